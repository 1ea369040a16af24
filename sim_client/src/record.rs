//! `sim_client ... --record FILE.mcap`: a trial's ground truth, the ego's decisions and a
//! Foxglove scene, written after the trial (simulated time as log time).

use std::path::{Path, PathBuf};

use recording::scene::{scene_update, scene_update_schema, PlannedStep, Role, SceneRoad, SceneVehicle};
use recording::{ChannelSpec, McapSink, Rotation};
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};
use traffic::{SimParams, World};

use crate::episode::{Episode, StepObserver};
use crate::error::Result;

/// Topic of the trial's settings (one message, first).
pub const TRIAL_TOPIC: &str = "/sim/trial";
/// Topic of the ground truth: every vehicle after every low-level step.
pub const VEHICLES_TOPIC: &str = "/sim/vehicles";
/// Topic of the ego's decisions.
pub const DECISION_TOPIC: &str = "/sim/decision";
/// Topic of the Foxglove 3D scene.
pub const SCENE_TOPIC: &str = "/sim/scene";

/// One vehicle's ground truth. Id 0 is the ego.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RecordedVehicle {
    /// Vehicle id (0 = ego).
    pub id: u32,
    /// Longitudinal position of the centre, m.
    pub x_m: f64,
    /// Lateral position of the centre, m (lane `i` centred at `(lanes - i) * lane_width`).
    pub y_m: f64,
    /// Speed, m/s.
    pub v_mps: f64,
    /// Acceleration, m/s^2.
    #[serde(default)]
    pub a_mps2: f64,
    /// Lateral velocity, m/s (positive to the left).
    #[serde(default)]
    pub vy_mps: f64,
    /// Nearest lane (0 = derive from `y_m`).
    #[serde(default)]
    pub lane: u8,
    /// Lane it heads to (0 = `lane`).
    #[serde(default)]
    pub target_lane: u8,
    /// Longitudinal mode (-1, 0, 1).
    #[serde(default)]
    pub beta: i8,
}

/// Every vehicle after one low-level step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VehicleStates {
    /// Low-level step index (0 = the initial state).
    pub step: u64,
    /// Simulation time, s.
    pub time_s: f64,
    /// The vehicles, the ego (id 0) among them.
    pub vehicles: Vec<RecordedVehicle>,
}

/// The trial's road and settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrialInfo {
    /// What was run, e.g. `case1`.
    pub label: String,
    /// Seed of the simulator's random stream.
    #[serde(default)]
    pub seed: u64,
    /// Number of lanes; lane 1 is the leftmost.
    pub lanes: u8,
    /// Lane width, m.
    pub lane_width_m: f64,
    /// Speed limit, m/s.
    pub speed_limit_mps: f64,
    /// The ego's desired speed, m/s.
    pub ego_desired_speed_mps: f64,
    /// Low-level step, s (the period of `/sim/vehicles`).
    pub low_level_step_s: f64,
    /// At most this many SVs were sent to the planner (0 = the planner's default).
    #[serde(default)]
    pub max_svs: usize,
    /// The simulator's parameters (absent in a foreign recording: defaults with
    /// `low_level_step_s`).
    #[serde(default)]
    pub params: Option<SimParams>,
}

/// One decision of the ego, with its plan.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimDecision<'a> {
    /// The decision's record (layer, commanded lane and beta, ego state, ...).
    #[serde(flatten)]
    pub record: &'a crate::episode::DecisionRecord,
    /// The planned maneuvers (empty for the IDM + MOBIL ego).
    pub plan: Vec<protocol::PlanStep>,
}

impl<'a> SimDecision<'a> {
    /// The message of `record`.
    pub fn of(record: &'a crate::episode::DecisionRecord) -> Self {
        Self {
            record,
            plan: record.plan.iter().map(|&s| s.into()).collect(),
        }
    }
}

fn vehicle_states_schema() -> Value {
    let n = json!({ "type": "number" });
    let i = json!({ "type": "integer" });
    json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "hmdp.VehicleStates",
        "type": "object",
        "properties": {
            "step": i, "time_s": n,
            "vehicles": { "type": "array", "items": { "type": "object", "properties": {
                "id": i, "x_m": n, "y_m": n, "v_mps": n, "a_mps2": n, "vy_mps": n,
                "lane": i, "target_lane": i, "beta": i,
            }, "required": ["id", "x_m", "y_m", "v_mps"] } },
        },
        "required": ["step", "time_s", "vehicles"],
    })
}

fn trial_info_schema() -> Value {
    let n = json!({ "type": "number" });
    let i = json!({ "type": "integer" });
    json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "hmdp.TrialInfo",
        "type": "object",
        "properties": {
            "label": { "type": "string" }, "seed": i, "lanes": i, "lane_width_m": n,
            "speed_limit_mps": n, "ego_desired_speed_mps": n, "low_level_step_s": n,
            "max_svs": i, "params": { "type": ["object", "null"] },
        },
        "required": ["label", "lanes", "lane_width_m", "speed_limit_mps", "ego_desired_speed_mps", "low_level_step_s"],
    })
}

fn sim_decision_schema() -> Value {
    let n = json!({ "type": "number" });
    let i = json!({ "type": "integer" });
    json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "hmdp.SimDecision",
        "type": "object",
        "properties": {
            "index": i, "time_s": n, "layer": { "type": ["string", "null"] }, "target_lane": i, "beta": i,
            "corrective_svs": i, "corrective_sv_ids": { "type": "string" }, "svs_sent": i,
            "ego_x_m": n, "ego_y_m": n, "ego_speed_mps": n,
            "plan": { "type": "array", "items": { "type": "object" } },
        },
        "required": ["index", "time_s", "target_lane", "beta", "ego_x_m", "ego_y_m", "ego_speed_mps", "plan"],
    })
}

/// The channels of a simulator recording.
pub fn channels() -> Vec<ChannelSpec> {
    vec![
        ChannelSpec {
            topic: TRIAL_TOPIC,
            schema_name: "hmdp.TrialInfo",
            schema: trial_info_schema,
        },
        ChannelSpec {
            topic: VEHICLES_TOPIC,
            schema_name: "hmdp.VehicleStates",
            schema: vehicle_states_schema,
        },
        ChannelSpec {
            topic: DECISION_TOPIC,
            schema_name: "hmdp.SimDecision",
            schema: sim_decision_schema,
        },
        ChannelSpec {
            topic: SCENE_TOPIC,
            schema_name: recording::scene::SCENE_SCHEMA_NAME,
            schema: scene_update_schema,
        },
    ]
}

/// The road of a trial's scene.
pub fn scene_road(info: &TrialInfo) -> SceneRoad {
    SceneRoad {
        lanes: info.lanes,
        lane_width_m: info.lane_width_m,
    }
}

/// The scene of one step at `time_ns`: every vehicle (id 0 is the ego; the SVs in
/// `corrective` orange) and the ego's last plan.
pub fn step_scene(
    time_ns: u64,
    road: SceneRoad,
    vehicles: &[RecordedVehicle],
    plan: &[PlannedStep],
    corrective: &[u32],
) -> Value {
    let vehicles: Vec<SceneVehicle> = vehicles
        .iter()
        .map(|v| SceneVehicle {
            id: v.id,
            role: match v.id {
                traffic::EGO_ID => Role::Ego,
                id if corrective.contains(&id) => Role::CorrectiveSv,
                _ => Role::Sv,
            },
            x_m: v.x_m,
            y_m: v.y_m,
            v_mps: v.v_mps,
            length_m: traffic::VEHICLE_LENGTH,
            width_m: traffic::VEHICLE_WIDTH,
        })
        .collect();
    scene_update(time_ns, road, &vehicles, plan)
}

/// The plan of a decision, as the scene draws it.
pub fn planned_steps(decision: &crate::episode::DecisionRecord) -> Vec<PlannedStep> {
    decision
        .plan
        .iter()
        .map(|s| PlannedStep {
            x_m: s.x_m,
            lane: s.maneuver.lane,
        })
        .collect()
}

/// A world's vehicles as recorded.
pub fn vehicle_states(world: &World) -> VehicleStates {
    VehicleStates {
        step: world.step_index(),
        time_s: crate::metrics::clean(world.time()),
        vehicles: world
            .vehicles()
            .iter()
            .map(|v| RecordedVehicle {
                id: v.id,
                x_m: v.x,
                y_m: v.y,
                v_mps: v.v,
                a_mps2: v.a,
                vy_mps: v.vy,
                lane: v.lane,
                target_lane: v.target_lane,
                beta: v.beta,
            })
            .collect(),
    }
}

/// Collects the ground truth of every step (as a [`StepObserver`]).
#[derive(Debug, Default)]
pub struct GroundTruth {
    /// One entry per step, the initial state first.
    pub steps: Vec<VehicleStates>,
}

impl StepObserver for GroundTruth {
    fn after_step(&mut self, world: &mut World) -> Result<()> {
        self.steps.push(vehicle_states(world));
        Ok(())
    }
}

/// Simulated seconds as nanoseconds (negative as 0).
pub fn nanos(time_s: f64) -> u64 {
    (time_s.max(0.0) * 1e9).round() as u64
}

/// Writes the trial to `path`: its settings, the ground truth of every step, every decision
/// and a scene per step, in time order. Returns the files written.
pub fn write_trial(path: &Path, info: &TrialInfo, truth: &[VehicleStates], episode: &Episode) -> Result<Vec<PathBuf>> {
    let mut sink = McapSink::create(path, channels(), Rotation::default())?;
    sink.write_json(0, 0, info)?;
    let road = scene_road(info);
    let mut decisions = episode.decisions.iter().peekable();
    let mut last: Option<&crate::episode::DecisionRecord> = None;
    let mut plan: Vec<PlannedStep> = Vec::new();
    for states in truth {
        while let Some(d) = decisions.next_if(|d| d.time_s <= states.time_s + 1e-9) {
            sink.write_json(2, nanos(d.time_s), &SimDecision::of(d))?;
            plan = planned_steps(d);
            last = Some(d);
        }
        let at = nanos(states.time_s);
        sink.write_json(1, at, states)?;
        let corrective = last.map_or(&[][..], |d| &d.corrective_sv_ids);
        let scene = step_scene(at, road, &states.vehicles, &plan, corrective);
        sink.write_json(3, at, &scene)?;
    }
    Ok(sink.finish()?)
}
