//! Inputs and outputs of the decision core.

use serde::{Deserialize, Serialize};

use crate::config::Backend;

/// Longitudinal maneuver state `beta`.
pub type Beta = i8;

/// The road as the planner sees it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Road {
    /// Number of lanes `n`; lane 1 is the leftmost, lane `i` has centre `(n - i) * lane_width`.
    pub lanes: u8,
    pub lane_width_m: f64,
    /// Upper speed bound `v_max`, m/s.
    pub speed_limit_mps: f64,
}

impl Road {
    pub fn lane_centre(&self, lane: u8) -> f64 {
        f64::from(self.lanes - lane) * self.lane_width_m
    }
}

/// Discrete maneuver state `m = (alpha, beta)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Maneuver {
    /// Target lane `alpha` in `1..=n`.
    pub lane: u8,
    /// `-1` decelerating, `0` cruising, `1` accelerating.
    pub beta: Beta,
}

/// Action `d = (d_lat, d_long)`; `d_lat = -1` is a change to the left.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Action {
    pub lateral: i8,
    pub longitudinal: i8,
}

impl Action {
    pub const KEEP: Action = Action {
        lateral: 0,
        longitudinal: 0,
    };
}

/// The ego's kinematic state, current maneuver and goal.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EgoState {
    pub x_m: f64,
    pub y_m: f64,
    pub v_mps: f64,
    pub desired_speed_mps: f64,
    pub maneuver: Maneuver,
}

/// One perceived surrounding vehicle. Positions are of the vehicle's centre.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SvObservation {
    pub id: u32,
    pub x_m: f64,
    pub y_m: f64,
    pub v_mps: f64,
    pub a_mps2: f64,
    /// Lateral velocity, m/s (positive = towards the left, increasing `y`). Lets the
    /// prediction see a lane change before the SV has left its lane centre.
    #[serde(default)]
    pub vy_mps: f64,
    /// Body length and width, m; `None`: the configured vehicle size.
    #[serde(default)]
    pub length_m: Option<f64>,
    #[serde(default)]
    pub width_m: Option<f64>,
}

impl SvObservation {
    /// An SV of the configured size driving straight along its lane.
    pub fn new(id: u32, x_m: f64, y_m: f64, v_mps: f64, a_mps2: f64) -> Self {
        Self {
            id,
            x_m,
            y_m,
            v_mps,
            a_mps2,
            vy_mps: 0.0,
            length_m: None,
            width_m: None,
        }
    }
}

/// Hysteresis state of one SV in corrective mode: the thresholds frozen when it triggered.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CorrectiveEntry {
    pub sv_id: u32,
    /// Frozen release distance `d_rel(k_trig)`, m.
    pub release_m: f64,
    /// Frozen trigger distance `d_trig(k_trig)`, m; `release_m - trigger_m` bounds the slack.
    pub trigger_m: f64,
}

/// What the planner remembers between decisions. It travels with the decision so that the
/// caller (or a network message) can hand it back: the planner itself keeps no state.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PlannerMemory {
    /// SVs in corrective mode, sorted by id.
    pub corrective: Vec<CorrectiveEntry>,
    /// The actions planned last time (warm start).
    pub previous_plan: Vec<Action>,
}

impl PlannerMemory {
    pub fn is_corrective(&self, sv_id: u32) -> bool {
        self.corrective.iter().any(|e| e.sv_id == sv_id)
    }
}

/// Everything one decision needs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Situation {
    pub road: Road,
    pub ego: EgoState,
    pub svs: Vec<SvObservation>,
    pub memory: PlannerMemory,
}

/// Which part of the recovery scheme produced a decision.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Layer {
    /// The nominal MPC.
    Nominal,
    /// Layer A: bounded global relaxation.
    GlobalRelaxation,
    /// Layer B: the deterministic fallback.
    Fallback,
}

impl Layer {
    pub fn name(self) -> &'static str {
        match self {
            Layer::Nominal => "nominal",
            Layer::GlobalRelaxation => "global_relaxation",
            Layer::Fallback => "fallback",
        }
    }
}

/// One step of the planned sequence.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PlanStep {
    pub action: Action,
    /// Maneuver after the action.
    pub maneuver: Maneuver,
    pub x_m: f64,
    pub v_mps: f64,
    /// Bit `l - 1` set when the ego occupies lane `l` at the end of the step.
    pub occupied_lanes: u16,
}

/// How the fallback chose its maneuver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Threat {
    Front,
    Rear,
    /// An SV ahead closer than its frozen trigger distance (beyond its IDM distance).
    Band,
    Lateral,
    None,
}

/// Statistics of one decision.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SolveStats {
    pub backend: Backend,
    /// Wall time of the whole decision, microseconds.
    pub total_us: u64,
    /// Wall time spent in the backend (MILP build and HiGHS, or enumeration), microseconds.
    pub solve_us: u64,
    /// SVs inside the perception window.
    pub svs_considered: usize,
    /// Scenario-tree branches kept over all SVs.
    pub branches: usize,
    /// SVs in corrective mode after the hysteresis refresh.
    pub corrective_svs: usize,
    /// Exact cost of the chosen plan (`None` for the fallback).
    pub cost: Option<f64>,
    /// Objective HiGHS reported for the chosen plan, if it solved one.
    pub solver_objective: Option<f64>,
    /// MILP size of the last solve: rows, columns, binaries.
    pub rows: usize,
    pub columns: usize,
    pub binaries: usize,
    /// Branch-and-bound nodes of the last HiGHS solve.
    pub nodes: u64,
    /// Action sequences evaluated by the enumeration backend.
    pub sequences: usize,
    /// A warm start was offered to HiGHS.
    pub warm_start: bool,
    /// The solve stopped at its time limit or an interrupt.
    pub interrupted: bool,
    /// Threat the fallback reacted to (`None` unless the fallback answered).
    pub fallback_threat: Option<Threat>,
    /// The MPC was not asked: an SV ahead needed braking beyond its range, and the fallback
    /// braked at once (docs/emergency-braking.md).
    pub emergency: bool,
}

impl SolveStats {
    /// Statistics of a decision that has not solved anything yet.
    pub fn new(backend: Backend) -> Self {
        Self {
            backend,
            total_us: 0,
            solve_us: 0,
            svs_considered: 0,
            branches: 0,
            corrective_svs: 0,
            cost: None,
            solver_objective: None,
            rows: 0,
            columns: 0,
            binaries: 0,
            nodes: 0,
            sequences: 0,
            warm_start: false,
            interrupted: false,
            fallback_threat: None,
            emergency: false,
        }
    }
}

/// What to command now: the first step's longitudinal acceleration and the speed it reaches
/// at the end of the first step. A vehicle that cannot take an acceleration tracks the speed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SetPoint {
    pub accel_mps2: f64,
    pub target_speed_mps: f64,
}

/// The answer of one decision.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Decision {
    /// First action of the plan.
    pub action: Action,
    /// Maneuver to command now `(alpha, beta)`.
    pub next_maneuver: Maneuver,
    /// Longitudinal set-point of the first step.
    pub setpoint: SetPoint,
    /// The planned sequence over the horizon.
    pub plan: Vec<PlanStep>,
    pub layer: Layer,
    pub stats: SolveStats,
    /// Memory to hand back with the next situation.
    pub memory: PlannerMemory,
}
