//! A request and its answer as RViz markers, in the frame [`FRAME_ID`] (x along the road,
//! y to the left, lane `i` centred at `(lanes - i) * lane_width_m`, as in
//! `docs/protocol.md`).
//!
//! Every array starts with a `DELETEALL`, so markers of an earlier answer (an SV that has
//! gone, a longer plan) never linger. Namespaces and ids:
//!
//! | namespace | ids | marker |
//! |---|---|---|
//! | `ego_plan` | 0, 1 | the ego now and at the end of each plan step: `LINE_STRIP` (0, only with a plan), `SPHERE_LIST` (1) |
//! | `occupied_lanes` | step index | a `CUBE_LIST`, one cube per lane the ego occupies at the end of the step |
//! | `svs` | SV index | a `CUBE` of the SV's size (4.5 x 1.8 m when unknown) |
//! | `sv_ids` | SV index | `TEXT_VIEW_FACING`, the SV's id |
//! | `sv_predictions` | SV index | `LINE_STRIP`, the SV now and at the end of each plan step at its current speed, lane kept (only with a plan) |
//!
//! Ids are list indices, not SV ids: an SV id is a `u32`, a marker id an `i32`. SVs in
//! corrective (hysteresis) mode are orange, the others grey.

use protocol::PlanRequest;

use crate::msg::viz::{ColorRGBA, Header, Marker, MarkerArray, Point, Pose, Time, Vector3};
use crate::FRAME_ID;

pub const NS_EGO_PLAN: &str = "ego_plan";
pub const NS_OCCUPIED_LANES: &str = "occupied_lanes";
pub const NS_SVS: &str = "svs";
pub const NS_SV_IDS: &str = "sv_ids";
pub const NS_SV_PREDICTIONS: &str = "sv_predictions";

/// The length of one plan step, s (the planner decides every 0.4 s).
pub const STEP_S: f64 = 0.4;
/// An SV's length when the request says 0 (unknown), m.
pub const DEFAULT_SV_LENGTH_M: f64 = 4.5;
/// An SV's width when the request says 0 (unknown), m.
pub const DEFAULT_SV_WIDTH_M: f64 = 1.8;

const SV_HEIGHT_M: f64 = 1.5;
const EGO_LINE_WIDTH_M: f64 = 0.3;
const EGO_SPHERE_M: f64 = 1.0;
const PREDICTION_LINE_WIDTH_M: f64 = 0.15;
const OCCUPIED_CELL_LENGTH_M: f64 = 2.0;
const TEXT_HEIGHT_M: f64 = 1.2;

const GREEN: ColorRGBA = rgba(0.1, 0.8, 0.2, 1.0);
const BLUE: ColorRGBA = rgba(0.2, 0.4, 1.0, 0.35);
const GREY: ColorRGBA = rgba(0.6, 0.6, 0.6, 0.9);
const ORANGE: ColorRGBA = rgba(1.0, 0.55, 0.0, 0.9);
const WHITE: ColorRGBA = rgba(1.0, 1.0, 1.0, 1.0);
const RED: ColorRGBA = rgba(0.9, 0.2, 0.2, 0.8);

const fn rgba(r: f32, g: f32, b: f32, a: f32) -> ColorRGBA {
    ColorRGBA { r, g, b, a }
}

/// The centre of `lane` across the road, m.
pub fn lane_centre_y(road: &protocol::Road, lane: u8) -> f64 {
    (f64::from(road.lanes) - f64::from(lane)) * road.lane_width_m
}

fn point(x: f64, y: f64, z: f64) -> Point {
    Point { x, y, z }
}

fn marker(stamp: Time, ns: &str, id: usize, kind: i32, scale: Vector3, color: ColorRGBA) -> Marker {
    Marker {
        header: Header {
            stamp,
            frame_id: FRAME_ID.to_owned(),
        },
        ns: ns.to_owned(),
        id: i32::try_from(id).unwrap_or(i32::MAX),
        r#type: kind,
        action: Marker::ADD,
        pose: Pose::default(),
        scale,
        color,
        ..Marker::default()
    }
}

fn scale(x: f64, y: f64, z: f64) -> Vector3 {
    Vector3 { x, y, z }
}

/// A usable size: the given one, or the default when unknown (0) or not a positive number.
fn size_or(value: f64, default: f64) -> f64 {
    if value.is_finite() && value > 0.0 {
        value
    } else {
        default
    }
}

/// The markers of `request` and its `response`, stamped `stamp`. A rejection has no plan:
/// the ego's position and the SVs only.
pub fn plan_markers(request: &PlanRequest, response: &protocol::PlanResponse, stamp: Time) -> MarkerArray {
    let plan: &[protocol::PlanStep] = response.outcome.as_decided().map_or(&[], |d| &d.plan);
    let corrective: &[protocol::CorrectiveEntry] = response.outcome.as_decided().map_or(&[], |d| &d.memory.corrective);
    let mut markers = Vec::with_capacity(4 + plan.len() + 3 * request.svs.len());
    markers.push(Marker {
        header: Header {
            stamp,
            frame_id: FRAME_ID.to_owned(),
        },
        action: Marker::DELETEALL,
        ..Marker::default()
    });
    ego_markers(&mut markers, request, plan, stamp);
    occupied_markers(&mut markers, request, plan, stamp);
    sv_markers(&mut markers, request, plan.len(), corrective, stamp);
    MarkerArray { markers }
}

/// The ego's positions now and at the end of every step (x from the plan, y the centre of
/// the step's target lane).
pub fn ego_positions(request: &PlanRequest, plan: &[protocol::PlanStep]) -> Vec<Point> {
    std::iter::once(point(request.ego.x_m, request.ego.y_m, 0.0))
        .chain(
            plan.iter()
                .map(|step| point(step.x_m, lane_centre_y(&request.road, step.maneuver.lane), 0.0)),
        )
        .collect()
}

fn ego_markers(out: &mut Vec<Marker>, request: &PlanRequest, plan: &[protocol::PlanStep], stamp: Time) {
    let points = ego_positions(request, plan);
    if points.len() >= 2 {
        let mut line = marker(
            stamp,
            NS_EGO_PLAN,
            0,
            Marker::LINE_STRIP,
            scale(EGO_LINE_WIDTH_M, 0.0, 0.0),
            GREEN,
        );
        line.points = points.clone();
        out.push(line);
    }
    let mut spheres = marker(
        stamp,
        NS_EGO_PLAN,
        1,
        Marker::SPHERE_LIST,
        scale(EGO_SPHERE_M, EGO_SPHERE_M, EGO_SPHERE_M),
        GREEN,
    );
    spheres.points = points;
    out.push(spheres);
}

/// The lanes (1-based) whose bit is set in `occupied_lanes`.
pub fn occupied_lanes(bits: u16) -> impl Iterator<Item = u8> {
    (1..=16u8).filter(move |lane| bits & (1 << (lane - 1)) != 0)
}

fn occupied_markers(out: &mut Vec<Marker>, request: &PlanRequest, plan: &[protocol::PlanStep], stamp: Time) {
    let road = &request.road;
    for (k, step) in plan.iter().enumerate() {
        let mut cells = marker(
            stamp,
            NS_OCCUPIED_LANES,
            k,
            Marker::CUBE_LIST,
            scale(OCCUPIED_CELL_LENGTH_M, road.lane_width_m, 0.05),
            BLUE,
        );
        cells.points = occupied_lanes(step.occupied_lanes)
            .map(|lane| point(step.x_m, lane_centre_y(road, lane), 0.0))
            .collect();
        out.push(cells);
    }
}

/// An SV's predicted positions now and at the end of each of `steps` steps: constant
/// speed, lane kept.
pub fn sv_prediction(sv: &protocol::SvObservation, steps: usize) -> Vec<Point> {
    (0..=steps)
        .map(|k| point(sv.x_m + sv.v_mps * STEP_S * k as f64, sv.y_m, 0.0))
        .collect()
}

fn sv_markers(
    out: &mut Vec<Marker>,
    request: &PlanRequest,
    steps: usize,
    corrective: &[protocol::CorrectiveEntry],
    stamp: Time,
) {
    for (i, sv) in request.svs.iter().enumerate() {
        let length = size_or(sv.length_m, DEFAULT_SV_LENGTH_M);
        let width = size_or(sv.width_m, DEFAULT_SV_WIDTH_M);
        let colour = if corrective.iter().any(|c| c.sv_id == sv.id) {
            ORANGE
        } else {
            GREY
        };
        let mut body = marker(
            stamp,
            NS_SVS,
            i,
            Marker::CUBE,
            scale(length, width, SV_HEIGHT_M),
            colour,
        );
        body.pose.position = point(sv.x_m, sv.y_m, SV_HEIGHT_M / 2.0);
        out.push(body);

        let mut label = marker(
            stamp,
            NS_SV_IDS,
            i,
            Marker::TEXT_VIEW_FACING,
            scale(0.0, 0.0, TEXT_HEIGHT_M),
            WHITE,
        );
        label.pose.position = point(sv.x_m, sv.y_m, SV_HEIGHT_M + TEXT_HEIGHT_M);
        label.text = sv.id.to_string();
        out.push(label);

        if steps > 0 {
            let mut line = marker(
                stamp,
                NS_SV_PREDICTIONS,
                i,
                Marker::LINE_STRIP,
                scale(PREDICTION_LINE_WIDTH_M, 0.0, 0.0),
                RED,
            );
            line.points = sv_prediction(sv, steps);
            out.push(line);
        }
    }
}

#[cfg(test)]
mod tests;
