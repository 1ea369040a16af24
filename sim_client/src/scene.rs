//! The `foxglove.SceneUpdate` of one simulator step: vehicles as boxes, lane boundaries as
//! lines, the ego's planned maneuvers as a strip of boxes. Pure: JSON values only.
//!
//! Frame `road`: x along the road, y lateral (positive to the left, lane `i` centred at
//! `(lanes - i) * lane_width`), z up.

use serde_json::{json, Value};

use crate::record::RecordedVehicle;

/// A step's planned maneuver: where the ego will be and in which lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlannedStep {
    /// Predicted position at the end of the step, m.
    pub x_m: f64,
    /// Target lane after the step.
    pub lane: u8,
}

/// The road the scene is drawn on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneRoad {
    /// Number of lanes.
    pub lanes: u8,
    /// Lane width, m.
    pub lane_width_m: f64,
}

impl SceneRoad {
    /// Lateral position of lane `lane`'s centre.
    pub fn lane_centre(&self, lane: u8) -> f64 {
        f64::from(self.lanes.saturating_sub(lane)) * self.lane_width_m
    }
}

/// Lane boundaries drawn this far behind and ahead of the ego, m.
const ROAD_BEHIND_M: f64 = 100.0;
const ROAD_AHEAD_M: f64 = 200.0;
const BOX_HEIGHT_M: f64 = 1.5;

fn time(ns: u64) -> Value {
    json!({ "sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000 })
}

fn pose(x: f64, y: f64, z: f64) -> Value {
    json!({ "position": { "x": x, "y": y, "z": z }, "orientation": { "x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0 } })
}

fn color(r: f64, g: f64, b: f64, a: f64) -> Value {
    json!({ "r": r, "g": g, "b": b, "a": a })
}

fn entity(id: &str, stamp: &Value, cubes: Vec<Value>, lines: Vec<Value>, texts: Vec<Value>) -> Value {
    json!({
        "timestamp": stamp,
        "frame_id": "road",
        "id": id,
        "lifetime": { "sec": 0, "nsec": 0 },
        "frame_locked": false,
        "metadata": [],
        "arrows": [], "cubes": cubes, "spheres": [], "cylinders": [], "lines": lines,
        "triangles": [], "texts": texts, "models": [],
    })
}

/// The scene at `time_ns`: every vehicle (id 0 is the ego), the lanes around the ego, and
/// the ego's last plan (empty for none). Each update replaces the previous one (fixed ids;
/// vehicles that left are deleted by the update's `deletions`).
pub fn scene_update(
    time_ns: u64,
    road: SceneRoad,
    vehicles: &[RecordedVehicle],
    plan: &[PlannedStep],
    length_m: f64,
    width_m: f64,
) -> Value {
    let stamp = time(time_ns);
    let ego_x = vehicles.iter().find(|v| v.id == 0).map_or(0.0, |v| v.x_m);
    let (x0, x1) = (ego_x - ROAD_BEHIND_M, ego_x + ROAD_AHEAD_M);
    let half = road.lane_width_m / 2.0;
    let mut points = Vec::new();
    for k in 0..=road.lanes {
        let y = f64::from(k) * road.lane_width_m - half;
        points.push(json!({ "x": x0, "y": y, "z": 0.0 }));
        points.push(json!({ "x": x1, "y": y, "z": 0.0 }));
    }
    let lanes = json!({
        "type": 2, "pose": pose(0.0, 0.0, 0.0), "thickness": 0.15, "scale_invariant": false,
        "points": points, "color": color(0.8, 0.8, 0.8, 1.0), "colors": [], "indices": [],
    });
    let mut entities = vec![entity("road", &stamp, Vec::new(), vec![lanes], Vec::new())];
    for v in vehicles {
        let (c, label) = if v.id == 0 {
            (color(0.1, 0.4, 1.0, 1.0), "ego".to_owned())
        } else {
            (color(0.6, 0.6, 0.6, 1.0), format!("SV {}", v.id))
        };
        let cube = json!({
            "pose": pose(v.x_m, v.y_m, BOX_HEIGHT_M / 2.0),
            "size": { "x": length_m, "y": width_m, "z": BOX_HEIGHT_M },
            "color": c,
        });
        let text = json!({
            "pose": pose(v.x_m, v.y_m, BOX_HEIGHT_M + 0.8), "billboard": true, "font_size": 14.0,
            "scale_invariant": true, "color": color(1.0, 1.0, 1.0, 1.0),
            "text": format!("{label} {:.1} m/s", v.v_mps),
        });
        entities.push(entity(
            &format!("vehicle/{}", v.id),
            &stamp,
            vec![cube],
            Vec::new(),
            vec![text],
        ));
    }
    let strip: Vec<Value> = plan
        .iter()
        .map(|s| {
            json!({
                "pose": pose(s.x_m, road.lane_centre(s.lane), 0.05),
                "size": { "x": length_m, "y": road.lane_width_m * 0.8, "z": 0.1 },
                "color": color(0.1, 0.9, 0.3, 0.35),
            })
        })
        .collect();
    entities.push(entity("plan", &stamp, strip, Vec::new(), Vec::new()));
    json!({ "deletions": [], "entities": entities })
}

/// A JSON Schema of the parts of `foxglove.SceneUpdate` the scene uses; Foxglove knows the
/// type by its name.
pub fn scene_update_schema() -> Value {
    let vec3 = json!({ "type": "object", "properties": { "x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"} } });
    let color = json!({ "type": "object", "properties": { "r": {"type": "number"}, "g": {"type": "number"}, "b": {"type": "number"}, "a": {"type": "number"} } });
    let pose = json!({ "type": "object", "properties": { "position": vec3, "orientation": { "type": "object" } } });
    let time = json!({ "type": "object", "properties": { "sec": {"type": "integer"}, "nsec": {"type": "integer"} } });
    let cube = json!({ "type": "object", "properties": { "pose": pose, "size": vec3, "color": color } });
    let line = json!({ "type": "object", "properties": {
        "type": {"type": "integer"}, "pose": pose, "thickness": {"type": "number"},
        "scale_invariant": {"type": "boolean"}, "points": {"type": "array", "items": vec3}, "color": color } });
    let text = json!({ "type": "object", "properties": {
        "pose": pose, "billboard": {"type": "boolean"}, "font_size": {"type": "number"},
        "scale_invariant": {"type": "boolean"}, "color": color, "text": {"type": "string"} } });
    json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "foxglove.SceneUpdate",
        "type": "object",
        "properties": {
            "deletions": { "type": "array", "items": { "type": "object" } },
            "entities": { "type": "array", "items": { "type": "object", "properties": {
                "timestamp": time, "frame_id": {"type": "string"}, "id": {"type": "string"},
                "lifetime": time, "frame_locked": {"type": "boolean"},
                "cubes": {"type": "array", "items": cube}, "lines": {"type": "array", "items": line},
                "texts": {"type": "array", "items": text},
            } } },
        },
        "required": ["deletions", "entities"],
    })
}
