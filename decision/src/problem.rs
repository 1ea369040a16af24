//! Algorithm 1, steps 1-5: from a validated situation to the decision problem both backends
//! solve — perception window, IDM margins, hysteresis refresh, SV scenario trees, and the
//! safety data of every SV.

use crate::config::{CostWeights, PlannerConfig};
use crate::hysteresis;
use crate::idm::{hard_margin, idm_distance, thresholds};
use crate::lanes::{lanes_at, nearest_lane, LaneSet};
use crate::model::{rollout, Kinematics};
use crate::scenario::{beta_from_accel, longitudinal_variances, predict_branches, Branch};
use crate::types::{Action, CorrectiveEntry, Maneuver, PlannerMemory, Situation, SvObservation};

/// Safety data of one SV inside the perception window.
#[derive(Debug, Clone)]
pub struct SvConstraint {
    pub id: u32,
    /// `s = +1`: the SV is ahead of the ego (the ego follows it); `-1`: behind.
    pub ahead: bool,
    pub d_idm: f64,
    /// `d_hc(h)` for `h = 1..=H`.
    pub hard: Vec<f64>,
    /// Frozen thresholds while in corrective mode (only for SVs ahead).
    pub corrective: Option<CorrectiveEntry>,
    /// Layer A bound on the global slack, `gamma * d_idm`.
    pub relax_bound: f64,
    pub branches: Vec<Branch>,
}

impl SvConstraint {
    /// Signed bumper-to-bumper gap to a branch position: positive when the SV keeps its side.
    pub fn gap(&self, sv_x: f64, ego_x: f64, length: f64) -> f64 {
        let sign = if self.ahead { 1.0 } else { -1.0 };
        sign * (sv_x - ego_x) - length
    }

    /// Hysteresis slack bound `d_HS`.
    pub fn slack_bound(&self) -> f64 {
        self.corrective.map_or(0.0, |c| c.release_m - c.trigger_m)
    }
}

/// The decision problem: ego start, model, and every SV's constraint data.
#[derive(Debug, Clone)]
pub struct Problem {
    pub lanes: u8,
    pub horizon: usize,
    pub combined_actions: bool,
    pub kin: Kinematics,
    pub start: Maneuver,
    pub x0: f64,
    pub v0: f64,
    /// Lanes the ego occupies now (body and target lane).
    pub occupancy0: LaneSet,
    pub desired_speed: f64,
    /// Upper speed bound: the speed limit, or the current speed if already above it, so that
    /// holding speed is always admissible.
    pub speed_cap: f64,
    pub length: f64,
    pub weights: CostWeights,
    pub svs: Vec<SvConstraint>,
    pub tolerance: f64,
}

/// A problem with the memory the refresh produced.
#[derive(Debug, Clone)]
pub struct Prepared {
    pub problem: Problem,
    pub memory: PlannerMemory,
}

/// Build the problem. The situation must have passed `validate`.
pub fn prepare(config: &PlannerConfig, s: &Situation) -> Prepared {
    let road = &s.road;
    let kin = Kinematics::new(config);
    let tol = config.vehicle.lane_centre_tolerance_m;
    let length = config.vehicle.length_m;
    let ego = &s.ego;
    let body = lanes_at(road, ego.y_m, tol).expect("validated");
    let occupancy0 = body.with(ego.maneuver.lane);
    let z = config.z_epsilon();
    let variances = longitudinal_variances(config);

    // Nominal ego rollout (keep lane and beta) for the hysteresis refresh.
    let keep = vec![Action::KEEP; config.timing.horizon];
    let nominal = rollout(&kin, road.lanes, ego.maneuver, ego.x_m, ego.v_mps, occupancy0, &keep)
        .expect("keeping is always admissible");

    let in_window = |sv: &SvObservation| {
        let dx = sv.x_m - ego.x_m;
        dx <= config.perception.range_ahead_m && dx >= -config.perception.range_behind_m
    };
    let mut visible: Vec<&SvObservation> = s.svs.iter().filter(|sv| in_window(sv)).collect();
    visible.sort_by_key(|sv| sv.id);

    let mut svs = Vec::with_capacity(visible.len());
    let mut corrective_entries = Vec::new();
    for sv in visible {
        let ahead = sv.x_m >= ego.x_m;
        let d_idm = if ahead {
            idm_distance(&config.idm, ego.v_mps, sv.v_mps)
        } else {
            idm_distance(&config.idm, sv.v_mps, ego.v_mps)
        };
        let hard: Vec<f64> = variances.iter().map(|&var| hard_margin(d_idm, z, var)).collect();
        let sv_occ = lanes_at(road, sv.y_m, tol).expect("validated");
        let start = Maneuver {
            lane: nearest_lane(road, sv.y_m).expect("validated"),
            beta: beta_from_accel(sv.a_mps2, config.prediction.accel_dead_band_mps2),
        };
        let branches = predict_branches(config, &kin, road.lanes, start, sv.x_m, sv.v_mps, sv_occ);
        let mut constraint = SvConstraint {
            id: sv.id,
            ahead,
            d_idm,
            hard,
            corrective: None,
            relax_bound: config.recovery.gamma * d_idm,
            branches,
        };
        if config.hysteresis.enabled && ahead {
            let min_gap = constraint
                .branches
                .iter()
                .flat_map(|b| {
                    (0..b.x.len())
                        .filter(|&h| b.occupancy[h].intersects(nominal.occupancy[h]))
                        .map(|h| constraint.gap(b.x[h], nominal.x[h], length))
                        .collect::<Vec<_>>()
                })
                .reduce(f64::min);
            let current = thresholds(&config.hysteresis, d_idm, constraint.hard[0]);
            let previous = s.memory.corrective.iter().find(|e| e.sv_id == sv.id).copied();
            constraint.corrective = hysteresis::refresh(sv.id, previous, min_gap, current);
        }
        if let Some(entry) = constraint.corrective {
            corrective_entries.push(entry);
        }
        svs.push(constraint);
    }

    let problem = Problem {
        lanes: road.lanes,
        horizon: config.timing.horizon,
        combined_actions: config.ego.combined_actions,
        kin,
        start: ego.maneuver,
        x0: ego.x_m,
        v0: ego.v_mps,
        occupancy0,
        desired_speed: ego.desired_speed_mps,
        speed_cap: road.speed_limit_mps.max(ego.v_mps),
        length,
        weights: config.cost.clone(),
        svs,
        tolerance: config.solver.feasibility_tolerance,
    };
    Prepared {
        problem,
        memory: PlannerMemory {
            corrective: corrective_entries,
            previous_plan: Vec::new(),
        },
    }
}
