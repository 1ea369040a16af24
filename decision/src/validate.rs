//! Input checks: every number finite, speeds non-negative, lanes on the road, ids unique,
//! capacity respected. Runs before anything else so the core never sees bad data.

use crate::config::PlannerConfig;
use crate::error::InputError;
use crate::lanes::nearest_lane;
use crate::types::Situation;

/// Plausibility bounds: beyond them the numbers are not a road scene, and huge magnitudes
/// would only turn into overflow inside the solver.
const MAX_POSITION_M: f64 = 1.0e7;
const MAX_SPEED_MPS: f64 = 150.0;
const MAX_ACCEL_MPS2: f64 = 100.0;
/// Narrower lanes are not a road; the bound also keeps lane arithmetic far from overflow.
const MIN_LANE_WIDTH_M: f64 = 1.0;
const MAX_LANE_WIDTH_M: f64 = 20.0;
/// A speed this little below zero is measurement noise of a standing vehicle, not an error:
/// it is accepted and read as 0 (see [`normalised`]).
pub const NEGATIVE_SPEED_TOLERANCE_MPS: f64 = 0.5;
/// At most this many SVs in one request. The planner uses the `perception.max_svs` most
/// relevant of them (see `problem::relevant_svs`); a perception stack may send all it sees.
pub const MAX_INPUT_SVS: usize = 64;

fn within(field: &'static str, value: f64, min: f64, max: f64) -> Result<(), InputError> {
    if !value.is_finite() {
        return Err(InputError::NonFinite { field });
    }
    if value < min || value > max {
        return Err(InputError::OutOfRange { field, value, min, max });
    }
    Ok(())
}

fn finite(field: &'static str, value: f64) -> Result<(), InputError> {
    within(field, value, -MAX_POSITION_M, MAX_POSITION_M)
}

fn speed(field: &'static str, value: f64) -> Result<(), InputError> {
    if !value.is_finite() {
        return Err(InputError::NonFinite { field });
    }
    if value < -NEGATIVE_SPEED_TOLERANCE_MPS {
        return Err(InputError::NegativeSpeed { field, value });
    }
    within(field, value, -NEGATIVE_SPEED_TOLERANCE_MPS, MAX_SPEED_MPS)
}

/// A situation that passed [`validate`] against a configuration, with the measurement
/// tolerances applied ([`normalised`]): what the planner decides on. Built only by
/// [`ValidSituation::new`], so a holder never checks it again.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidSituation(Situation);

impl ValidSituation {
    /// Checks `situation` against `config` (the lane count and the horizon are the
    /// configuration's) and applies the tolerances.
    pub fn new(config: &PlannerConfig, situation: &Situation) -> Result<Self, InputError> {
        validate(config, situation)?;
        Ok(Self(normalised(situation)))
    }

    /// The situation, tolerances applied.
    pub fn get(&self) -> &Situation {
        &self.0
    }
}

/// Check a situation against the configuration.
fn validate(config: &PlannerConfig, s: &Situation) -> Result<(), InputError> {
    let road = &s.road;
    if road.lanes == 0 || road.lanes > config.perception.max_lanes {
        return Err(InputError::LaneCount {
            lanes: road.lanes,
            max: config.perception.max_lanes,
        });
    }
    within(
        "road.lane_width_m",
        road.lane_width_m,
        MIN_LANE_WIDTH_M,
        MAX_LANE_WIDTH_M,
    )?;
    speed("road.speed_limit_mps", road.speed_limit_mps)?;

    let ego = &s.ego;
    finite("ego.x_m", ego.x_m)?;
    finite("ego.y_m", ego.y_m)?;
    speed("ego.v_mps", ego.v_mps)?;
    speed("ego.desired_speed_mps", ego.desired_speed_mps)?;
    let lane = ego.maneuver.lane;
    if lane == 0 || lane > road.lanes {
        return Err(InputError::LaneOutOfRange {
            field: "ego.maneuver.lane",
            lane: i64::from(lane),
            lanes: road.lanes,
        });
    }
    if !(-1..=1).contains(&ego.maneuver.beta) {
        return Err(InputError::BetaOutOfRange {
            field: "ego.maneuver.beta",
            beta: ego.maneuver.beta,
        });
    }
    nearest_lane(road, ego.y_m).map_err(|lane| InputError::LaneOutOfRange {
        field: "ego.y_m",
        lane,
        lanes: road.lanes,
    })?;

    if s.svs.len() > MAX_INPUT_SVS {
        return Err(InputError::TooManyVehicles {
            count: s.svs.len(),
            capacity: MAX_INPUT_SVS,
        });
    }
    let mut ids: Vec<u32> = Vec::with_capacity(s.svs.len());
    for sv in &s.svs {
        finite("sv.x_m", sv.x_m)?;
        finite("sv.y_m", sv.y_m)?;
        within("sv.vy_mps", sv.vy_mps, -MAX_SPEED_MPS, MAX_SPEED_MPS)?;
        for (field, size) in [("sv.length_m", sv.length_m), ("sv.width_m", sv.width_m)] {
            if let Some(size) = size {
                within(field, size, 0.5, 30.0)?;
            }
        }
        speed("sv.v_mps", sv.v_mps)?;
        within("sv.a_mps2", sv.a_mps2, -MAX_ACCEL_MPS2, MAX_ACCEL_MPS2)?;
        nearest_lane(road, sv.y_m).map_err(|lane| InputError::LaneOutOfRange {
            field: "sv.y_m",
            lane,
            lanes: road.lanes,
        })?;
        ids.push(sv.id);
    }
    ids.sort_unstable();
    if let Some(w) = ids.windows(2).find(|w| w[0] == w[1]) {
        return Err(InputError::DuplicateSvId { id: w[0] });
    }

    let memory = &s.memory;
    if memory.corrective.len() > MAX_INPUT_SVS {
        return Err(InputError::InvalidMemory {
            field: "memory.corrective",
            why: "more corrective entries than SV capacity",
        });
    }
    for e in &memory.corrective {
        if !(e.release_m.abs() <= MAX_POSITION_M && e.trigger_m.abs() <= MAX_POSITION_M) {
            return Err(InputError::InvalidMemory {
                field: "memory.corrective",
                why: "threshold not a finite distance",
            });
        }
        if e.release_m < e.trigger_m {
            return Err(InputError::InvalidMemory {
                field: "memory.corrective",
                why: "release below trigger",
            });
        }
    }
    if memory.previous_plan.len() > config.timing.horizon {
        return Err(InputError::InvalidMemory {
            field: "memory.previous_plan",
            why: "previous plan longer than the horizon",
        });
    }
    if memory
        .previous_plan
        .iter()
        .any(|a| !(-1..=1).contains(&a.lateral) || !(-1..=1).contains(&a.longitudinal))
    {
        return Err(InputError::InvalidMemory {
            field: "memory.previous_plan",
            why: "previous plan action outside -1..=1",
        });
    }
    Ok(())
}

/// The situation with measurement tolerances applied: speeds within
/// [`NEGATIVE_SPEED_TOLERANCE_MPS`] below zero read as 0. Call after [`validate`].
fn normalised(s: &Situation) -> Situation {
    let mut out = s.clone();
    out.ego.v_mps = out.ego.v_mps.max(0.0);
    out.ego.desired_speed_mps = out.ego.desired_speed_mps.max(0.0);
    out.road.speed_limit_mps = out.road.speed_limit_mps.max(0.0);
    for sv in &mut out.svs {
        sv.v_mps = sv.v_mps.max(0.0);
    }
    out
}
