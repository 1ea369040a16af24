//! Surrogate safety measures of the ego, step by step (after SUMO's SSM device); pure.
//!
//! The episode feeds a [`SafetyAccumulator`] the world's state after every low-level step.
//! The ego's neighbours are found with the simulator's own lane sets (a vehicle changing
//! lanes occupies every lane from origin to target): the *leader* is the nearest vehicle
//! ahead whose lane set meets the ego's, the *follower* the nearest one behind. Gaps are
//! bumper to bumper ([`traffic::VEHICLE_LENGTH`]).

use serde::{Deserialize, Serialize};
use traffic::{LaneSet, World, VEHICLE_LENGTH};

/// Time to collision below this counts as a critical encounter (s).
pub const TTC_THRESHOLD_S: f64 = 3.0;
/// Time headway below this counts as tailgating (s).
pub const HEADWAY_THRESHOLD_S: f64 = 1.0;
/// An ego acceleration at or below this is hard braking (m/s^2).
pub const HARD_BRAKING_MPS2: f64 = -2.5;

/// What the measures need of one vehicle at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Body {
    /// Vehicle id.
    pub id: u32,
    /// Longitudinal position of the centre (m).
    pub x: f64,
    /// Speed (m/s).
    pub v: f64,
    /// Acceleration realised during the last step (m/s^2).
    pub a: f64,
    /// Lanes the simulator considers it to occupy.
    pub lanes: LaneSet,
    /// Whether a lateral manoeuvre is under way.
    pub changing_lanes: bool,
}

impl Body {
    /// Every vehicle of the world, the ego first (the order of [`World::vehicles`]).
    pub fn all(world: &World) -> Vec<Body> {
        world
            .vehicles()
            .iter()
            .zip(world.lane_sets())
            .map(|(v, lanes)| Body {
                id: v.id,
                x: v.x,
                v: v.v,
                a: v.a,
                lanes,
                changing_lanes: v.is_changing_lanes(),
            })
            .collect()
    }

    /// Whether `self` is ahead of `other` (ties in x broken by id, as the simulator does).
    pub fn is_ahead_of(&self, other: &Body) -> bool {
        (self.x, self.id) > (other.x, other.id)
    }
}

/// Time to collision: `gap / closing speed` while closing (a negative gap counts as 0).
pub fn time_to_collision(gap_m: f64, closing_mps: f64) -> Option<f64> {
    (closing_mps > 0.0).then(|| gap_m.max(0.0) / closing_mps)
}

/// Deceleration rate to avoid a crash: `closing^2 / (2 gap)` while closing with a gap.
pub fn drac(gap_m: f64, closing_mps: f64) -> Option<f64> {
    (closing_mps > 0.0 && gap_m > 0.0).then(|| closing_mps * closing_mps / (2.0 * gap_m))
}

/// Time headway of a follower at `speed` behind a gap (`None` at standstill).
pub fn time_headway(gap_m: f64, speed_mps: f64) -> Option<f64> {
    (speed_mps > 0.0).then(|| gap_m.max(0.0) / speed_mps)
}

/// The nearest vehicle ahead of `bodies[i]` (or behind it) sharing a lane with it.
fn neighbour(bodies: &[Body], i: usize, ahead: bool) -> Option<&Body> {
    let me = &bodies[i];
    let candidates = bodies
        .iter()
        .enumerate()
        .filter(|&(j, b)| j != i && b.lanes.intersects(me.lanes))
        .map(|(_, b)| b)
        .filter(|b| if ahead { b.is_ahead_of(me) } else { me.is_ahead_of(b) });
    let key = |b: &&Body| (b.x, b.id);
    if ahead {
        candidates.min_by(|a, b| key(a).partial_cmp(&key(b)).expect("finite positions"))
    } else {
        candidates.max_by(|a, b| key(a).partial_cmp(&key(b)).expect("finite positions"))
    }
}

/// The ego's measures at one instant.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepMeasures {
    /// TTC to the leader (ego closing in on it).
    pub ttc_leader_s: Option<f64>,
    /// TTC of the follower (closing in on the ego).
    pub ttc_follower_s: Option<f64>,
    /// Time headway to the leader.
    pub headway_s: Option<f64>,
    /// DRAC of the ego behind its leader.
    pub drac_mps2: Option<f64>,
}

impl StepMeasures {
    /// The smaller of the two TTCs.
    pub fn ttc_s(&self) -> Option<f64> {
        match (self.ttc_leader_s, self.ttc_follower_s) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }
}

/// Measures of the ego, `bodies[0]`, against its leader and follower.
pub fn measure(bodies: &[Body]) -> StepMeasures {
    let Some(ego) = bodies.first() else {
        return StepMeasures::default();
    };
    let mut m = StepMeasures::default();
    if let Some(l) = neighbour(bodies, 0, true) {
        let gap = l.x - ego.x - VEHICLE_LENGTH;
        let closing = ego.v - l.v;
        m.ttc_leader_s = time_to_collision(gap, closing);
        m.headway_s = time_headway(gap, ego.v);
        m.drac_mps2 = drac(gap, closing);
    }
    if let Some(f) = neighbour(bodies, 0, false) {
        m.ttc_follower_s = time_to_collision(ego.x - f.x - VEHICLE_LENGTH, f.v - ego.v);
    }
    m
}

/// Who caused the ego's collision.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EgoCollisionKind {
    /// The ego rear-ended a vehicle ahead in its lane, or changed lanes into a vehicle.
    EgoAtFault,
    /// The ego kept its lane and was hit from behind or cut into.
    EgoHitInLane,
}

/// Classifies an ego contact from both vehicles' states at that step.
pub fn classify_ego_collision(ego: &Body, other: &Body) -> EgoCollisionKind {
    if ego.changing_lanes || (other.is_ahead_of(ego) && !other.changing_lanes) {
        EgoCollisionKind::EgoAtFault
    } else {
        EgoCollisionKind::EgoHitInLane
    }
}

/// The safety figures of one episode.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SafetySummary {
    /// Low-level steps measured.
    pub steps: u64,
    /// Smallest TTC (leader or follower) of the episode; `None`: never closing.
    pub min_ttc_s: Option<f64>,
    /// Steps with TTC below [`TTC_THRESHOLD_S`].
    pub ttc_below_3s_steps: u64,
    /// Steps with a headway below [`HEADWAY_THRESHOLD_S`].
    pub headway_below_1s_steps: u64,
    /// Share of steps with TTC below 3 s.
    pub ttc_below_3s_share: f64,
    /// Share of steps with a headway below 1 s.
    pub headway_below_1s_share: f64,
    /// Largest DRAC of the ego behind its leader (m/s^2; 0 when never closing).
    pub max_drac_mps2: f64,
    /// Maximal runs of steps with the ego's acceleration at or below [`HARD_BRAKING_MPS2`].
    pub hard_braking_events: u32,
    /// RMS of the ego's jerk over the steps (m/s^3).
    pub jerk_rms_mps3: f64,
    /// Largest |jerk| (m/s^3).
    pub jerk_max_abs_mps3: f64,
    /// Lowest ego speed after a step (m/s).
    pub min_speed_mps: f64,
}

/// Feeds on the world's state step by step and sums up the episode.
#[derive(Debug, Clone, PartialEq)]
pub struct SafetyAccumulator {
    dt: f64,
    steps: u64,
    ttc_below: u64,
    headway_below: u64,
    min_ttc: Option<f64>,
    max_drac: f64,
    hard_braking_events: u32,
    braking: bool,
    previous_accel: f64,
    jerk_square_sum: f64,
    jerk_max_abs: f64,
    min_speed: f64,
}

impl SafetyAccumulator {
    /// An accumulator for steps of `dt` seconds; `initial_accel` is the ego's acceleration
    /// before the first step (the reference of the first jerk sample).
    pub fn new(dt: f64, initial_accel: f64) -> Self {
        SafetyAccumulator {
            dt,
            steps: 0,
            ttc_below: 0,
            headway_below: 0,
            min_ttc: None,
            max_drac: 0.0,
            hard_braking_events: 0,
            braking: false,
            previous_accel: initial_accel,
            jerk_square_sum: 0.0,
            jerk_max_abs: 0.0,
            min_speed: f64::INFINITY,
        }
    }

    /// An accumulator for `world` before its first step.
    pub fn for_world(world: &World) -> Self {
        Self::new(world.params().dt, world.ego().a)
    }

    /// The world after one step.
    pub fn observe_world(&mut self, world: &World) {
        self.observe(&Body::all(world));
    }

    /// The vehicles after one step, the ego first.
    pub fn observe(&mut self, bodies: &[Body]) {
        let Some(ego) = bodies.first() else { return };
        let m = measure(bodies);
        self.steps += 1;
        if let Some(t) = m.ttc_s() {
            self.min_ttc = Some(self.min_ttc.map_or(t, |m| m.min(t)));
            self.ttc_below += u64::from(t < TTC_THRESHOLD_S);
        }
        self.headway_below += u64::from(m.headway_s.is_some_and(|h| h < HEADWAY_THRESHOLD_S));
        self.max_drac = self.max_drac.max(m.drac_mps2.unwrap_or(0.0));
        let braking = ego.a <= HARD_BRAKING_MPS2;
        self.hard_braking_events += u32::from(braking && !self.braking);
        self.braking = braking;
        let jerk = (ego.a - self.previous_accel) / self.dt;
        self.previous_accel = ego.a;
        self.jerk_square_sum += jerk * jerk;
        self.jerk_max_abs = self.jerk_max_abs.max(jerk.abs());
        self.min_speed = self.min_speed.min(ego.v);
    }

    /// The figures so far.
    pub fn summary(&self) -> SafetySummary {
        let share = |n: u64| {
            if self.steps == 0 {
                0.0
            } else {
                n as f64 / self.steps as f64
            }
        };
        SafetySummary {
            steps: self.steps,
            min_ttc_s: self.min_ttc,
            ttc_below_3s_steps: self.ttc_below,
            headway_below_1s_steps: self.headway_below,
            ttc_below_3s_share: share(self.ttc_below),
            headway_below_1s_share: share(self.headway_below),
            max_drac_mps2: self.max_drac,
            hard_braking_events: self.hard_braking_events,
            jerk_rms_mps3: if self.steps == 0 {
                0.0
            } else {
                (self.jerk_square_sum / self.steps as f64).sqrt()
            },
            jerk_max_abs_mps3: self.jerk_max_abs,
            min_speed_mps: if self.steps == 0 { 0.0 } else { self.min_speed },
        }
    }
}

/// Nearest-rank percentile of minimum TTCs, `None` standing for "never closing" (infinite).
pub fn ttc_percentile(values: &[Option<f64>], p: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mut v: Vec<f64> = values.iter().map(|t| t.unwrap_or(f64::INFINITY)).collect();
    v.sort_by(f64::total_cmp);
    let rank = ((p * v.len() as f64).ceil() as usize).clamp(1, v.len());
    Some(v[rank - 1]).filter(|t| t.is_finite())
}

/// The safety figures of a set of episodes.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GroupSafety {
    /// Smallest per-episode minimum TTC (s); `None`: no episode ever closed in.
    pub min_ttc_min_s: Option<f64>,
    /// 5th percentile of the per-episode minimum TTC (nearest rank; `None`: infinite).
    pub min_ttc_p5_s: Option<f64>,
    /// Median of the per-episode minimum TTC.
    pub min_ttc_p50_s: Option<f64>,
    /// Share of all steps with TTC below 3 s.
    pub ttc_below_3s_share: f64,
    /// Share of all steps with a headway below 1 s.
    pub headway_below_1s_share: f64,
    /// Largest DRAC (m/s^2).
    pub max_drac_mps2: f64,
    /// Hard-braking events in all episodes.
    pub hard_braking_events: u64,
    /// Hard-braking events per simulated hour.
    pub hard_braking_per_hour: f64,
    /// RMS jerk over all steps (m/s^3).
    pub jerk_rms_mps3: f64,
    /// Largest |jerk| (m/s^3).
    pub jerk_max_abs_mps3: f64,
    /// Lowest ego speed of all episodes (m/s).
    pub min_speed_mps: f64,
}

impl GroupSafety {
    /// Aggregates episodes; `dt` converts steps to time.
    pub fn from_episodes<'a>(episodes: impl Iterator<Item = &'a SafetySummary>, dt: f64) -> Self {
        let mut min_ttcs = Vec::new();
        let (mut steps, mut ttc_below, mut headway_below, mut events) = (0u64, 0u64, 0u64, 0u64);
        let (mut drac, mut jerk_sq, mut jerk_max, mut min_speed) = (0.0f64, 0.0, 0.0f64, f64::INFINITY);
        for s in episodes {
            min_ttcs.push(s.min_ttc_s);
            steps += s.steps;
            ttc_below += s.ttc_below_3s_steps;
            headway_below += s.headway_below_1s_steps;
            events += u64::from(s.hard_braking_events);
            drac = drac.max(s.max_drac_mps2);
            jerk_sq += s.jerk_rms_mps3 * s.jerk_rms_mps3 * s.steps as f64;
            jerk_max = jerk_max.max(s.jerk_max_abs_mps3);
            if s.steps > 0 {
                min_speed = min_speed.min(s.min_speed_mps);
            }
        }
        let share = |n: u64| if steps == 0 { 0.0 } else { n as f64 / steps as f64 };
        let hours = steps as f64 * dt / 3600.0;
        GroupSafety {
            min_ttc_min_s: ttc_percentile(&min_ttcs, 0.0),
            min_ttc_p5_s: ttc_percentile(&min_ttcs, 0.05),
            min_ttc_p50_s: ttc_percentile(&min_ttcs, 0.5),
            ttc_below_3s_share: share(ttc_below),
            headway_below_1s_share: share(headway_below),
            max_drac_mps2: drac,
            hard_braking_events: events,
            hard_braking_per_hour: if hours > 0.0 { events as f64 / hours } else { 0.0 },
            jerk_rms_mps3: if steps == 0 {
                0.0
            } else {
                (jerk_sq / steps as f64).sqrt()
            },
            jerk_max_abs_mps3: jerk_max,
            min_speed_mps: if min_speed.is_finite() { min_speed } else { 0.0 },
        }
    }
}

#[cfg(test)]
#[path = "safety_tests.rs"]
mod tests;
