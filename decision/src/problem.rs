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
    /// Mean prediction (probability-weighted over the kept branches) of the SV's position per
    /// step, and the lanes of its most probable branch: the hysteresis works on the mean gap
    /// `mu_Delta` as in the paper, while the hard rows hold for every branch.
    pub mean_x: Vec<f64>,
    pub mean_occupancy: Vec<LaneSet>,
    /// Bound on the hysteresis slack (0 unless corrective): `d_HS`, or with
    /// `hysteresis.soft_band` at least down to the hard margin.
    pub slack_max: f64,
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
        self.slack_max
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
    /// Terminal cost of ending the horizon in lane `l` (index `l - 1`).
    pub lane_value: Vec<f64>,
    pub svs: Vec<SvConstraint>,
    pub tolerance: f64,
}

/// A problem with the memory the refresh produced.
#[derive(Debug, Clone)]
pub struct Prepared {
    pub problem: Problem,
    pub memory: PlannerMemory,
}

/// The ego's rollout when it resumes accelerating: `beta` steps up by one each step until it
/// reaches +1, in its target lane.
fn resuming_rollout(
    kin: &Kinematics,
    lanes: u8,
    start: Maneuver,
    x0: f64,
    v0: f64,
    occupancy0: LaneSet,
    horizon: usize,
) -> crate::model::Rollout {
    let mut beta = start.beta;
    let actions: Vec<Action> = (0..horizon)
        .map(|_| {
            let up = i8::from(beta < 1);
            beta += up;
            Action {
                lateral: 0,
                longitudinal: up,
            }
        })
        .collect();
    rollout(kin, lanes, start, x0, v0, occupancy0, &actions).expect("stepping beta up to +1 is admissible")
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

    // Nominal ego rollout (keep lane and beta) for the hysteresis trigger, and the resuming
    // rollout (beta stepping up to accelerating) for its release.
    let keep = vec![Action::KEEP; config.timing.horizon];
    let nominal = rollout(&kin, road.lanes, ego.maneuver, ego.x_m, ego.v_mps, occupancy0, &keep)
        .expect("keeping is always admissible");
    let resuming = resuming_rollout(
        &kin,
        road.lanes,
        ego.maneuver,
        ego.x_m,
        ego.v_mps,
        occupancy0,
        config.timing.horizon,
    );

    let in_window = |sv: &SvObservation| {
        let dx = sv.x_m - ego.x_m;
        dx <= config.perception.range_ahead_m && dx >= -config.perception.range_behind_m
    };
    let mut visible: Vec<&SvObservation> = s.svs.iter().filter(|sv| in_window(sv)).collect();
    // The nearest `max_svs` are the relevant ones (ties by id, so the choice is deterministic).
    visible.sort_by(|a, b| {
        let (da, db) = ((a.x_m - ego.x_m).abs(), (b.x_m - ego.x_m).abs());
        da.total_cmp(&db).then(a.id.cmp(&b.id))
    });
    visible.truncate(config.perception.max_svs);
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
        let mean_x: Vec<f64> = (0..config.timing.horizon)
            .map(|h| branches.iter().map(|b| b.probability * b.x[h]).sum())
            .collect();
        let mean_occupancy = branches[0].occupancy.clone();
        let mut constraint = SvConstraint {
            id: sv.id,
            ahead,
            d_idm,
            hard,
            corrective: None,
            relax_bound: config.recovery.gamma * d_idm,
            slack_max: 0.0,
            mean_x,
            mean_occupancy,
            branches,
        };
        // Hysteresis concerns the SV the ego follows: ahead and in a lane the ego occupies now.
        if config.hysteresis.enabled && ahead && sv_occ.intersects(occupancy0) {
            let min_gap_on = |ego_x: &[f64]| {
                (0..constraint.mean_x.len())
                    .filter(|&h| constraint.mean_occupancy[h].intersects(nominal.occupancy[h]))
                    .map(|h| constraint.gap(constraint.mean_x[h], ego_x[h], length))
                    .reduce(f64::min)
            };
            let current = thresholds(&config.hysteresis, d_idm, constraint.hard[0]);
            let previous = s.memory.corrective.iter().find(|e| e.sv_id == sv.id).copied();
            constraint.corrective = hysteresis::refresh(
                sv.id,
                previous,
                min_gap_on(&nominal.x),
                min_gap_on(&resuming.x),
                current,
            );
        }
        if let Some(entry) = constraint.corrective {
            let band = entry.release_m - entry.trigger_m;
            let to_hard = entry.release_m - constraint.hard.iter().copied().fold(f64::MIN, f64::max);
            constraint.slack_max = if config.hysteresis.soft_band {
                band.max(to_hard)
            } else {
                band
            };
            corrective_entries.push(entry);
        }
        svs.push(constraint);
    }

    // Speed the ego could hold in each lane beyond the horizon: its desired speed, or less when
    // an SV ahead in that lane (within the lookahead) is slower.
    let achievable: Vec<f64> = (1..=road.lanes)
        .map(|lane| {
            s.svs
                .iter()
                .filter(|sv| sv.x_m > ego.x_m && sv.x_m - ego.x_m <= config.cost.lane_lookahead_m)
                .filter(|sv| lanes_at(road, sv.y_m, tol).is_ok_and(|occ| occ.contains(lane)))
                .map(|sv| sv.v_mps)
                .fold(ego.desired_speed_mps, f64::min)
        })
        .collect();
    let lane_value: Vec<f64> = achievable
        .iter()
        .map(|v| config.cost.w_lane_speed * (ego.desired_speed_mps - v).max(0.0))
        .collect();

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
        lane_value,
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
