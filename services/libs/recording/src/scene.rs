//! The `foxglove.SceneUpdate` 3D scene: vehicles as boxes, lane boundaries as lines, the ego's
//! planned maneuvers as a strip of boxes. Pure: JSON values only.
//!
//! One builder for every scene of the project: the simulator's (`sim_client ... --record`,
//! `--foxglove`: every vehicle of the world after every step) and the planner's
//! (`planner serve --foxglove`: the ego and the SVs of a request with the plan of its answer,
//! [`plan_scene`]).
//!
//! Frame [`FRAME_ID`]: x along the road, y lateral (positive to the left, lane `i` centred at
//! `(lanes - i) * lane_width`), z up. Entities: `road` (the lane boundaries), `ego`,
//! `vehicle/{id}` per SV and `plan`; every update replaces the previous one.

use protocol::{PlanRequest, PlanResponse};
use serde_json::{json, Value};

/// The scene's frame: set it as the display frame of Foxglove's 3D panel.
pub const FRAME_ID: &str = "road";
/// The schema name Foxglove recognises the scene by.
pub const SCENE_SCHEMA_NAME: &str = "foxglove.SceneUpdate";
/// A vehicle's length when unknown (a request's SV with `length_m` 0, the ego of a request), m.
pub const DEFAULT_LENGTH_M: f64 = 4.5;
/// A vehicle's width when unknown, m.
pub const DEFAULT_WIDTH_M: f64 = 1.8;

/// A step's planned maneuver: where the ego will be and in which lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlannedStep {
    /// Predicted position at the end of the step, m.
    pub x_m: f64,
    /// Target lane after the step.
    pub lane: u8,
}

impl From<&protocol::PlanStep> for PlannedStep {
    fn from(step: &protocol::PlanStep) -> Self {
        Self {
            x_m: step.x_m,
            lane: step.maneuver.lane,
        }
    }
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

/// How a vehicle is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// The ego (blue, entity `ego`).
    Ego,
    /// An SV (grey, entity `vehicle/{id}`).
    Sv,
    /// An SV the planner holds in corrective (hysteresis) mode (orange).
    CorrectiveSv,
}

/// One vehicle of the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneVehicle {
    /// Its id (shown for an SV).
    pub id: u32,
    pub role: Role,
    /// Centre, m.
    pub x_m: f64,
    pub y_m: f64,
    /// Speed, m/s (shown).
    pub v_mps: f64,
    /// Box size, m.
    pub length_m: f64,
    pub width_m: f64,
}

/// Lane boundaries drawn this far behind and ahead of the ego, m.
const ROAD_BEHIND_M: f64 = 100.0;
const ROAD_AHEAD_M: f64 = 200.0;
const BOX_HEIGHT_M: f64 = 1.5;
/// `foxglove.SceneEntityDeletion.type`: every entity.
const DELETE_ALL: u8 = 1;

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
        "frame_id": FRAME_ID,
        "id": id,
        "lifetime": { "sec": 0, "nsec": 0 },
        "frame_locked": false,
        "metadata": [],
        "arrows": [], "cubes": cubes, "spheres": [], "cylinders": [], "lines": lines,
        "triangles": [], "texts": texts, "models": [],
    })
}

fn vehicle_entity(v: &SceneVehicle, stamp: &Value) -> Value {
    let (c, id, label) = match v.role {
        Role::Ego => (color(0.1, 0.4, 1.0, 1.0), "ego".to_owned(), "ego".to_owned()),
        Role::Sv => (
            color(0.6, 0.6, 0.6, 1.0),
            format!("vehicle/{}", v.id),
            format!("SV {}", v.id),
        ),
        Role::CorrectiveSv => (
            color(1.0, 0.55, 0.0, 1.0),
            format!("vehicle/{}", v.id),
            format!("SV {}", v.id),
        ),
    };
    let cube = json!({
        "pose": pose(v.x_m, v.y_m, BOX_HEIGHT_M / 2.0),
        "size": { "x": v.length_m, "y": v.width_m, "z": BOX_HEIGHT_M },
        "color": c,
    });
    let text = json!({
        "pose": pose(v.x_m, v.y_m, BOX_HEIGHT_M + 0.8), "billboard": true, "font_size": 14.0,
        "scale_invariant": true, "color": color(1.0, 1.0, 1.0, 1.0),
        "text": format!("{label} {:.1} m/s", v.v_mps),
    });
    entity(&id, stamp, vec![cube], Vec::new(), vec![text])
}

/// The scene at `time_ns`: every vehicle, the lanes around the ego, and the ego's plan (empty
/// for none). The update first deletes every entity (a deletion of type ALL), so that a
/// vehicle that is gone (out of a request's perception window, another vehicle's request) does
/// not linger.
pub fn scene_update(time_ns: u64, road: SceneRoad, vehicles: &[SceneVehicle], plan: &[PlannedStep]) -> Value {
    let stamp = time(time_ns);
    let ego = vehicles.iter().find(|v| v.role == Role::Ego);
    let ego_x = ego.map_or(0.0, |v| v.x_m);
    let ego_length = ego.map_or(DEFAULT_LENGTH_M, |v| v.length_m);
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
    entities.extend(vehicles.iter().map(|v| vehicle_entity(v, &stamp)));
    let strip: Vec<Value> = plan
        .iter()
        .map(|s| {
            json!({
                "pose": pose(s.x_m, road.lane_centre(s.lane), 0.05),
                "size": { "x": ego_length, "y": road.lane_width_m * 0.8, "z": 0.1 },
                "color": color(0.1, 0.9, 0.3, 0.35),
            })
        })
        .collect();
    entities.push(entity("plan", &stamp, strip, Vec::new(), Vec::new()));
    json!({ "deletions": [{ "timestamp": stamp, "type": DELETE_ALL, "id": "" }], "entities": entities })
}

/// A usable size: the given one, or the default when unknown (0) or not a positive number.
fn size_or(value: f64, default: f64) -> f64 {
    if value.is_finite() && value > 0.0 {
        value
    } else {
        default
    }
}

/// The planner's scene of one answer at `time_ns`: the ego and the SVs of `request` (SVs in
/// corrective mode after the answer orange, sizes as sent or the defaults), the plan of
/// `response` (none for a rejection).
pub fn plan_scene(request: &PlanRequest, response: &PlanResponse, time_ns: u64) -> Value {
    let decided = response.outcome.as_decided();
    let corrective: &[protocol::CorrectiveEntry] = decided.map_or(&[], |d| &d.memory.corrective);
    let ego = SceneVehicle {
        id: 0,
        role: Role::Ego,
        x_m: request.ego.x_m,
        y_m: request.ego.y_m,
        v_mps: request.ego.v_mps,
        length_m: DEFAULT_LENGTH_M,
        width_m: DEFAULT_WIDTH_M,
    };
    let svs = request.svs.iter().map(|sv| SceneVehicle {
        id: sv.id,
        role: if corrective.iter().any(|c| c.sv_id == sv.id) {
            Role::CorrectiveSv
        } else {
            Role::Sv
        },
        x_m: sv.x_m,
        y_m: sv.y_m,
        v_mps: sv.v_mps,
        length_m: size_or(sv.length_m, DEFAULT_LENGTH_M),
        width_m: size_or(sv.width_m, DEFAULT_WIDTH_M),
    });
    let vehicles: Vec<SceneVehicle> = std::iter::once(ego).chain(svs).collect();
    let plan: Vec<PlannedStep> = decided.map_or(Vec::new(), |d| d.plan.iter().map(PlannedStep::from).collect());
    let road = SceneRoad {
        lanes: request.road.lanes,
        lane_width_m: request.road.lane_width_m,
    };
    scene_update(time_ns, road, &vehicles, &plan)
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
        "title": SCENE_SCHEMA_NAME,
        "type": "object",
        "properties": {
            "deletions": { "type": "array", "items": { "type": "object", "properties": {
                "timestamp": time, "type": {"type": "integer"}, "id": {"type": "string"},
            } } },
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

#[cfg(test)]
mod tests;
