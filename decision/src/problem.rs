//! Algorithm 1, steps 1-5: from a validated situation to the decision problem both backends
//! solve — perception window, IDM margins, hysteresis refresh, SV scenario trees, and the
//! safety data of every SV.

use crate::braking_end::BrakingEnds;
use crate::config::{CostWeights, LateralDeparture, PlannerConfig};
use crate::evidence;
use crate::hysteresis;
use crate::idm::{ego_as_follower, hard_margin, idm_distance, linearised_margins, sv_idm_distance, thresholds};
use crate::lanes::{lanes_at, LaneSet};
use crate::model::{rollout, EgoStart, Kinematics, Rollout};
use crate::scenario::{beta_from_accel, longitudinal_variances, predict_branches_from, Branch};
use crate::types::{Action, CorrectiveEntry, Maneuver, PlannerMemory, Road, Situation, SvObservation};

/// Safety data of one SV inside the perception window.
///
/// The hard row of branch `b` at step `h` (0-based) reads
/// `gap_b(h) >= margin[b][h] + slope * (v_h - v_0) - allowance[h]`, together with the floor
/// `gap_b(h) >= floor[h] - floor_allowance[h]`; `gap` is the signed bumper-to-bumper distance and
/// `v_h` the ego's speed after step `h`.
#[derive(Debug, Clone)]
pub struct SvConstraint {
    pub id: u32,
    /// `s = +1`: the SV is ahead of the ego (the ego follows it); `-1`: behind.
    pub ahead: bool,
    /// IDM distance at the measured speeds.
    pub d_idm: f64,
    /// `d_hc(h)` at the measured speeds for `h = 1..=H` (the hysteresis thresholds use it).
    pub hard: Vec<f64>,
    /// Hard margin per branch and step at the ego's current speed, `[b][h]`.
    pub margin: Vec<Vec<f64>>,
    /// Jam-distance floor per step, `d0 + z sqrt(Sigma(h))`.
    pub floor: Vec<f64>,
    /// Sensitivity of the margin to the ego's speed (0 without `idm.speed_dependent`).
    pub slope: f64,
    /// How far the margin rows may still be violated per step when the SV is inside its
    /// margin now.
    pub allowance: Vec<f64>,
    /// The same for the floor rows (only when the SV is inside the floor now): the floor
    /// keeps the fast decay, whatever the margin's allowance.
    pub floor_allowance: Vec<f64>,
    /// No rows in the lanes the ego occupies now (a follower there keeps its own gap).
    pub exempt_in_own_lanes: bool,
    /// Thresholds in force while in corrective mode (only for SVs ahead).
    pub corrective: Option<CorrectiveEntry>,
    /// Layer A bound on the global slack, `gamma * d_idm`.
    pub relax_bound: f64,
    /// Mean prediction (probability-weighted over the kept branches) of the SV's position per
    /// step, and the lanes of its most probable branch: the hysteresis works on the mean gap
    /// `mu_Delta` as in the paper, while the hard rows hold for every branch.
    pub mean_x: Vec<f64>,
    /// Mean predicted speed per step (the band row's anticipation uses it).
    pub mean_v: Vec<f64>,
    pub mean_occupancy: Vec<LaneSet>,
    /// Bound on the hysteresis slack (0 unless corrective): `d_HS`, or with
    /// `hysteresis.soft_band` at least down to the hard rows' weakest demand.
    pub slack_max: f64,
    /// `hysteresis.anticipation_s` of the band row (0 unless corrective).
    pub anticipation_s: f64,
    pub branches: Vec<Branch>,
}

impl SvConstraint {
    /// Signed bumper-to-bumper gap to a branch position: positive when the SV keeps its side.
    pub fn gap(&self, sv_x: f64, ego_x: f64, length: f64) -> f64 {
        self.sign() * (sv_x - ego_x) - length
    }

    /// `+1` ahead, `-1` behind.
    pub fn sign(&self) -> f64 {
        if self.ahead {
            1.0
        } else {
            -1.0
        }
    }

    /// The band row's demand on the ego's gap at step `h` beyond the release distance: the
    /// anticipated change of the gap over `anticipation_s` at the SV's mean speed against
    /// the ego's measured one (the ego's own speed change enters the row as a term).
    pub fn band_anticipation(&self, h: usize, ego_v0: f64) -> f64 {
        self.anticipation_s * self.sign() * (self.mean_v[h] - ego_v0)
    }

    /// Hysteresis slack bound.
    pub fn slack_bound(&self) -> f64 {
        self.slack_max
    }

    /// Lanes in which this SV's rows apply at a step where the ego occupies `ego`, given the
    /// lanes `ego_now` it occupies at the decision.
    pub fn binding_lanes(&self, ego: LaneSet, ego_now: LaneSet) -> LaneSet {
        if self.exempt_in_own_lanes {
            LaneSet(ego.0 & !ego_now.0)
        } else {
            ego
        }
    }

    /// Whether the floor row can bind (it is implied when the margin never falls below it).
    pub fn floor_matters(&self) -> bool {
        self.slope != 0.0
            || self
                .margin
                .iter()
                .any(|m| m.iter().zip(&self.floor).any(|(m, f)| m < f))
    }
}

/// The decision problem: ego start, model, and every SV's constraint data.
#[derive(Debug, Clone)]
pub struct Problem {
    pub lanes: u8,
    pub horizon: usize,
    pub combined_actions: bool,
    pub kin: Kinematics,
    pub ego: EgoStart,
    pub desired_speed: f64,
    /// Upper speed bound: the speed limit, or the current speed if already above it, so that
    /// holding speed is always admissible.
    pub speed_cap: f64,
    pub length: f64,
    /// Braking beyond this is priced by `w_hard_brake`, m/s^2.
    pub comfort_decel: f64,
    /// Braking beyond this is priced by `w_firm_brake`, m/s^2.
    pub firm_decel: f64,
    /// Braking beyond this is priced by `w_peak_brake`, m/s^2.
    pub peak_decel: f64,
    pub weights: CostWeights,
    /// Terminal cost of ending the horizon in lane `l` (index `l - 1`).
    pub lane_value: Vec<f64>,
    pub svs: Vec<SvConstraint>,
    pub tolerance: f64,
    /// Solver of the exact evaluation's LP.
    pub evaluation_lp: crate::config::LpSolver,
}

impl Problem {
    /// Every action sequence the ego may take over the horizon (the oracle's search space).
    pub fn admissible_sequences(&self) -> Vec<Vec<Action>> {
        crate::model::admissible_sequences(self.ego.maneuver, self.lanes, self.horizon, self.combined_actions)
    }
}

/// A problem with the memory the refresh produced.
#[derive(Debug, Clone)]
pub struct Prepared {
    pub problem: Problem,
    pub memory: PlannerMemory,
}

/// The ego's rollout when it resumes accelerating: `beta` steps up by one each step until it
/// reaches +1, in its target lane.
fn resuming_rollout(kin: &Kinematics, lanes: u8, start: &EgoStart, horizon: usize) -> Rollout {
    let mut beta = start.maneuver.beta;
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
    rollout(kin, lanes, start, &actions).expect("stepping beta up to +1 is admissible")
}

/// An SV slower than the ego's desired speed by more than this holds the ego back, m/s.
const FOLLOWING_MARGIN_MPS: f64 = 0.5;

/// Everything the prepared problem needs to know about the ego and the model.
struct Context<'a> {
    config: &'a PlannerConfig,
    road: &'a Road,
    /// The whole scene, for the SVs' evidence.
    situation: &'a Situation,
    kin: Kinematics,
    start: EgoStart,
    desired_speed: f64,
    /// `z_eps sqrt(Sigma_Delta(h))` and `Sigma_Delta(h)` per step.
    sigmas: Vec<f64>,
    variances: Vec<f64>,
    z: f64,
    nominal: Rollout,
    release_rollout: Rollout,
    braking_ends: BrakingEnds,
}

/// Build the problem. The situation must have passed `validate`.
pub fn prepare(config: &PlannerConfig, s: &Situation) -> Prepared {
    let road = &s.road;
    let kin = Kinematics::new(config);
    let tol = config.vehicle.lane_centre_tolerance_m;
    let horizon = config.timing.horizon;
    let ego = &s.ego;
    let body = lanes_at(road, ego.y_m, tol).expect("validated");
    let start = EgoStart {
        maneuver: ego.maneuver,
        x: ego.x_m,
        v: ego.v_mps,
        occupancy: body.with(ego.maneuver.lane),
        plan_occupancy: config.ego.plan_occupancy,
    };
    let z = config.z_epsilon();
    let variances = longitudinal_variances(config);
    // Nominal ego rollout (keep lane and beta) for the hysteresis trigger, and the rollout
    // its release is checked on.
    let keep = vec![Action::KEEP; horizon];
    let nominal = rollout(&kin, road.lanes, &start, &keep).expect("keeping is always admissible");
    let release_rollout = if config.hysteresis.release_on_resuming {
        resuming_rollout(&kin, road.lanes, &start, horizon)
    } else {
        nominal.clone()
    };
    let ctx = Context {
        config,
        road,
        situation: s,
        kin,
        start,
        desired_speed: ego.desired_speed_mps,
        sigmas: variances.iter().map(|&var| z * var.sqrt()).collect(),
        variances,
        z,
        nominal,
        release_rollout,
        braking_ends: BrakingEnds::new(config, s),
    };

    let mut svs = Vec::new();
    let mut corrective_entries = Vec::new();
    for sv in relevant_svs(config, s) {
        let constraint = sv_constraint(&ctx, sv, &s.memory);
        if let Some(entry) = constraint.corrective {
            corrective_entries.push(entry);
        }
        svs.push(constraint);
    }

    let problem = Problem {
        lanes: road.lanes,
        horizon,
        combined_actions: config.ego.combined_actions,
        kin,
        ego: start,
        desired_speed: ego.desired_speed_mps,
        speed_cap: road.speed_limit_mps.max(ego.v_mps),
        length: config.vehicle.length_m,
        comfort_decel: config.ego.comfort_decel_mps2,
        firm_decel: config.ego.firm_decel_mps2,
        peak_decel: config.ego.peak_decel_mps2,
        weights: config.cost.clone(),
        lane_value: lane_values(config, s),
        svs,
        tolerance: config.solver.feasibility_tolerance,
        evaluation_lp: config.solver.evaluation_lp,
    };
    Prepared {
        problem,
        memory: PlannerMemory {
            corrective: corrective_entries,
            previous_plan: Vec::new(),
        },
    }
}

/// How far the margin rows of an SV ahead in the ego's path (`ahead_in_path`: in a lane the ego
/// occupies now, or predicted into one) may be violated after each step: the larger of the
/// geometric decay of today's `violation` (`idm.violation_decay` per step) and the violation
/// that remains on a reference rollout where the ego brakes at `idm.violation_recovery_mps2`
/// as soon as its maneuver state allows (one state change per step: from `+1` it first
/// cruises), against each predicted branch.
///
/// The decay alone asks a deep violation (a cut-in 20 m ahead inside a 120 m margin) to
/// shrink by a fifth of it per step, which only the strongest braking achieves, and none at
/// all from an accelerating state: the problem is infeasible and the fallback answers.
/// Recovering at a comfortable deceleration is what a driver does. The same holds for a
/// violation only predicted (a leader slowing a little raises its IDM distance by the
/// closing-speed term): held strictly, it asked the strongest braking for a leader 1.3 s
/// ahead slowing at 2.3 m/s^2. The reference never brakes less than staying behind a braking
/// leader takes (`BrakingEnds::needed_decel`): an allowance must not let the
/// ego follow a leader's emergency braking comfortably into its bumper. The reference rollout
/// meets these rows by construction (with one fixed acceleration per state, braking at that
/// harder one meets them too, as the margin falls and the gap grows with braking); the floor
/// rows keep the decay alone.
fn violation_allowance(
    ctx: &Context,
    margin: &[Vec<f64>],
    slope: f64,
    branches: &[Branch],
    violation: f64,
    needed_decel: f64,
    ahead_in_path: bool,
) -> Vec<f64> {
    let config = ctx.config;
    let horizon = config.timing.horizon;
    let decay = config.idm.violation_decay;
    let by_decay = (1..=horizon as i32).map(|h| violation * decay.powi(h));
    let recovery = config.idm.violation_recovery_mps2;
    if !(ahead_in_path && decay > 0.0 && recovery > 0.0) {
        return by_decay.collect();
    }
    let kin = &ctx.kin;
    let start = &ctx.start;
    let length = config.vehicle.length_m;
    let (mut x, mut v) = (start.x, start.v);
    let mut beta = start.maneuver.beta;
    let mut reference = Vec::with_capacity(horizon);
    for h in 0..horizon {
        beta = (beta - 1).max(-1);
        let lowest = kin.bounds[(beta + 1) as usize].0;
        let u = (-recovery.max(needed_decel)).max(lowest).max(-v / kin.dt);
        (x, v) = kin.step_with(x, v, u);
        let worst = branches
            .iter()
            .zip(margin)
            .map(|(b, m)| m[h] + slope * (v - start.v) - (b.x[h] - x - length))
            .fold(0.0, f64::max);
        reference.push(worst);
    }
    by_decay.zip(reference).map(|(d, r)| d.max(r)).collect()
}

/// SVs inside the perception window, the nearest `max_svs` of them (ties by id, so the
/// choice is deterministic), in id order.
fn relevant_svs<'a>(config: &PlannerConfig, s: &'a Situation) -> Vec<&'a SvObservation> {
    let ego = &s.ego;
    let p = &config.perception;
    let mut visible: Vec<&SvObservation> = s
        .svs
        .iter()
        .filter(|sv| {
            let dx = sv.x_m - ego.x_m;
            dx <= p.range_ahead_m && dx >= -p.range_behind_m
        })
        .collect();
    visible.sort_by(|a, b| {
        let (da, db) = ((a.x_m - ego.x_m).abs(), (b.x_m - ego.x_m).abs());
        da.total_cmp(&db).then(a.id.cmp(&b.id))
    });
    visible.truncate(p.max_svs);
    visible.sort_by_key(|sv| sv.id);
    visible
}

/// Prediction, margins and hysteresis state of one SV.
fn sv_constraint(ctx: &Context, sv: &SvObservation, memory: &PlannerMemory) -> SvConstraint {
    let config = ctx.config;
    let road = ctx.road;
    let tol = config.vehicle.lane_centre_tolerance_m;
    let length = config.vehicle.length_m;
    let horizon = config.timing.horizon;
    let (x0, v0) = (ctx.start.x, ctx.start.v);
    let occupancy0 = ctx.start.occupancy;
    let ahead = sv.x_m >= x0;
    let d_idm = sv_idm_distance(&config.idm, v0, sv.v_mps, ahead);
    let hard: Vec<f64> = ctx
        .variances
        .iter()
        .map(|&var| hard_margin(d_idm, ctx.z, var))
        .collect();
    let sv_occ = lanes_at(road, sv.y_m, tol).expect("validated");
    let heading = evidence::heading(config, road, sv);
    let sv_start = Maneuver {
        lane: heading.lane,
        beta: beta_from_accel(sv.a_mps2, config.prediction.accel_dead_band_mps2),
    };
    let measured = (
        sv.x_m,
        sv.v_mps,
        config.prediction.measured_accel_while_keeping.then_some(sv.a_mps2),
    );
    let first = evidence::first_step(config, road, &ctx.situation.ego, &ctx.situation.svs, sv);
    let mut branches = predict_branches_from(config, &ctx.kin, road.lanes, sv_start, measured, sv_occ, first);
    if first.is_some() && config.prediction.lateral_departure == LateralDeparture::Always {
        evidence::depart(config, road, sv, heading, &mut branches);
    }
    let departing = predict_lateral_motion(config, road, sv, sv_start.lane, &mut branches);
    let mean_x: Vec<f64> = (0..horizon)
        .map(|h| branches.iter().map(|b| b.probability * b.x[h]).sum())
        .collect();
    let mean_v: Vec<f64> = (0..horizon)
        .map(|h| branches.iter().map(|b| b.probability * b.v[h]).sum())
        .collect();
    // The occupancy the hysteresis follows; see `LateralDeparture`.
    let mean_occupancy = match departing {
        Some(d) if config.prediction.lateral_departure != LateralDeparture::Never => d,
        _ => branches[0].occupancy.clone(),
    };
    let (margin, slope) = if config.idm.speed_dependent {
        let speeds: Vec<Vec<f64>> = branches.iter().map(|b| b.v.clone()).collect();
        linearised_margins(
            &config.idm,
            ego_as_follower(&config.idm, ahead),
            v0,
            sv.v_mps,
            &speeds,
            &ctx.sigmas,
        )
    } else {
        (vec![hard.clone(); branches.len()], 0.0)
    };
    let floor: Vec<f64> = ctx.sigmas.iter().map(|&s| config.idm.jam_distance_m + s).collect();
    let exempt_in_own_lanes = !ahead && config.perception.rear_responsibility;
    let sign = if ahead { 1.0 } else { -1.0 };
    // Already inside the margin now, in a lane the ego occupies or predicted into one within
    // the horizon (a cut-in the lateral prediction sees): the rows may stay violated by a
    // shrinking share of today's violation. A cut-in two steps away is no more the ego's
    // doing than one a step away, and with no allowance its margin is infeasible at once.
    let shares_lane = sv_occ.intersects(occupancy0)
        || branches
            .iter()
            .any(|b| b.occupancy.iter().any(|o| o.intersects(occupancy0)));
    let gap_now = sign * (sv.x_m - x0) - length;
    let in_path = shares_lane && !exempt_in_own_lanes;
    let (violation_now, floor_violation_now) = if in_path {
        (
            (hard[0].max(floor[0]) - gap_now).max(0.0),
            (floor[0] - gap_now).max(0.0),
        )
    } else {
        (0.0, 0.0)
    };
    // Only the allowance of an SV ahead in the path uses it.
    let needed_decel = if ahead && in_path {
        ctx.braking_ends.needed_decel(config, sv, gap_now, v0)
    } else {
        0.0
    };
    let allowance = violation_allowance(
        ctx,
        &margin,
        slope,
        &branches,
        violation_now,
        needed_decel,
        ahead && in_path,
    );
    let decay = config.idm.violation_decay;
    let floor_allowance: Vec<f64> = (1..=horizon as i32)
        .map(|h| floor_violation_now * decay.powi(h))
        .collect();
    let mut c = SvConstraint {
        id: sv.id,
        ahead,
        d_idm,
        hard,
        margin,
        floor,
        slope,
        allowance,
        floor_allowance,
        exempt_in_own_lanes,
        corrective: None,
        relax_bound: config.recovery.gamma * d_idm,
        slack_max: 0.0,
        anticipation_s: 0.0,
        mean_x,
        mean_v,
        mean_occupancy,
        branches,
    };
    // Hysteresis concerns the SV the ego follows: ahead and in a lane the ego occupies now.
    if config.hysteresis.enabled && ahead && sv_occ.intersects(occupancy0) {
        let min_gap_on = |r: &Rollout| {
            (0..c.mean_x.len())
                .filter(|&h| c.mean_occupancy[h].intersects(r.occupancy[h]))
                .map(|h| c.gap(c.mean_x[h], r.x[h], length))
                .reduce(f64::min)
        };
        let current = thresholds(&config.hysteresis, d_idm, c.hard[0]);
        let mut previous = memory.corrective.iter().find(|e| e.sv_id == sv.id).copied();
        if config.hysteresis.resize_release {
            if let Some(frozen) = previous.as_mut() {
                // At the leader's speed: the distance that is genuinely safe once the ego no
                // longer closes in; never below today's own release distance.
                let matched_idm = idm_distance(&config.idm, sv.v_mps, sv.v_mps);
                let matched_hard = hard_margin(matched_idm, ctx.z, ctx.variances[0]);
                let matched = thresholds(&config.hysteresis, matched_idm, matched_hard);
                let release = frozen.release_m.min(current.release.max(matched.release));
                let band = frozen.release_m - frozen.trigger_m;
                frozen.release_m = release;
                frozen.trigger_m = release - band;
            }
        }
        c.corrective = hysteresis::refresh(
            sv.id,
            previous,
            min_gap_on(&ctx.nominal),
            min_gap_on(&ctx.release_rollout),
            current,
            config.hysteresis.hold_while_following && sv.v_mps < ctx.desired_speed - FOLLOWING_MARGIN_MPS,
        );
    }
    if let Some(entry) = c.corrective {
        c.anticipation_s = config.hysteresis.anticipation_s;
        let band = entry.release_m - entry.trigger_m;
        let weakest = (0..horizon)
            .map(|h| (c.floor[h] - c.floor_allowance[h]).min(c.hard[h] - c.allowance[h]))
            .fold(f64::INFINITY, f64::min);
        // The anticipated closing is priced, never forced: the bound covers it.
        let closing = (0..horizon).map(|h| c.band_anticipation(h, v0)).fold(0.0, f64::max);
        c.slack_max = closing
            + if config.hysteresis.soft_band {
                band.max(entry.release_m - weakest)
            } else {
                band
            };
    }
    c
}

/// Terminal lane values: the speed the ego could hold in each lane beyond the horizon is its
/// desired speed, or less when an SV ahead in that lane (within the lookahead) is slower. Such
/// an SV holds the lane at its speed only once the ego has closed in to the SV's IDM distance
/// at the desired speed, after `t_reach`; over `cost.lane_horizon_s` the lane lets the ego
/// average `v_sv + (v_des - v_sv) min(1, t_reach / lane_horizon_s)`, and the slowest SV's average
/// counts. A far slow SV thus weighs in gradually, not from a cut-off distance on.
fn lane_values(config: &PlannerConfig, s: &Situation) -> Vec<f64> {
    let (road, ego) = (&s.road, &s.ego);
    let tol = config.vehicle.lane_centre_tolerance_m;
    let v_des = ego.desired_speed_mps;
    let lane_speed = |sv: &SvObservation| {
        if sv.v_mps >= v_des {
            return v_des;
        }
        let gap = sv.x_m - ego.x_m - config.vehicle.length_m;
        let t_reach = (gap - idm_distance(&config.idm, sv.v_mps, sv.v_mps)).max(0.0) / (v_des - sv.v_mps);
        let share = if config.cost.lane_horizon_s > 0.0 {
            (t_reach / config.cost.lane_horizon_s).min(1.0)
        } else {
            0.0
        };
        sv.v_mps + (v_des - sv.v_mps) * share
    };
    (1..=road.lanes)
        .map(|lane| {
            let achievable = s
                .svs
                .iter()
                .filter(|sv| sv.x_m > ego.x_m && sv.x_m - ego.x_m <= config.cost.lane_lookahead_m)
                .filter(|sv| lanes_at(road, sv.y_m, tol).is_ok_and(|occ| occ.contains(lane)))
                .map(lane_speed)
                .fold(v_des, f64::min);
            config.cost.w_lane_speed * (v_des - achievable).max(0.0)
        })
        .collect()
}

/// An SV moving sideways is predicted along its lateral velocity: each branch also occupies
/// the lanes of the linearly extrapolated position, so a drifting SV is in the ego's lane in
/// the prediction before it leaves its own lane centre. Returned: the most probable branch's
/// occupancy *departing*, i.e. the extrapolated position's lanes and those its own lateral
/// actions move it into, without the lanes it occupies now; it leaves a lane only once also
/// `prediction.departure_speed_share` of its lateral velocity has taken it out. With
/// `LateralDeparture::Always` every branch is departing too.
fn predict_lateral_motion(
    config: &PlannerConfig,
    road: &Road,
    sv: &SvObservation,
    start_lane: u8,
    branches: &mut [Branch],
) -> Option<Vec<LaneSet>> {
    let threshold = config.prediction.lateral_velocity_threshold_mps;
    if threshold <= 0.0 || sv.vy_mps.abs() < threshold {
        return None;
    }
    let tol = config.vehicle.lane_centre_tolerance_m;
    let (lo, hi) = (road.lane_centre(road.lanes), road.lane_centre(1));
    let mut departing_first = None;
    for b in branches.iter_mut() {
        let mut moved = LaneSet::EMPTY;
        let mut departing = Vec::with_capacity(b.occupancy.len());
        for h in 0..b.occupancy.len() {
            let lane = b.maneuvers[h].lane;
            if lane != start_lane {
                moved = moved.with(lane);
            }
            let t = config.timing.step_s * (h + 1) as f64;
            let at = |share: f64| {
                lanes_at(road, (sv.y_m + share * sv.vy_mps * t).clamp(lo, hi), tol).unwrap_or(LaneSet::EMPTY)
            };
            // Entering a lane at the full lateral velocity, leaving one at the slower share.
            let ahead = at(1.0);
            b.occupancy[h] = b.occupancy[h].union(ahead);
            departing.push(moved.union(ahead).union(at(config.prediction.departure_speed_share)));
        }
        if config.prediction.lateral_departure == LateralDeparture::Always {
            b.occupancy.clone_from(&departing);
        }
        departing_first.get_or_insert(departing);
    }
    departing_first
}
