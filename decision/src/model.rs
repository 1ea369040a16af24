//! The HMDP of one vehicle: action set, `clip`-pruned transitions and the hybrid
//! kinematic maps `f^sigma`. Shared by the ego's plans and the SVs' scenario tree.

use crate::config::{PlanOccupancy, PlannerConfig};
use crate::lanes::LaneSet;
use crate::types::{Action, Beta, Maneuver};

/// All actions; the first five change at most one component (the "only one-step
/// transitions" set), the last four change both.
const ACTIONS: [Action; 9] = [
    Action {
        lateral: 0,
        longitudinal: 0,
    },
    Action {
        lateral: -1,
        longitudinal: 0,
    },
    Action {
        lateral: 1,
        longitudinal: 0,
    },
    Action {
        lateral: 0,
        longitudinal: -1,
    },
    Action {
        lateral: 0,
        longitudinal: 1,
    },
    Action {
        lateral: -1,
        longitudinal: -1,
    },
    Action {
        lateral: -1,
        longitudinal: 1,
    },
    Action {
        lateral: 1,
        longitudinal: -1,
    },
    Action {
        lateral: 1,
        longitudinal: 1,
    },
];

/// The admissible actions, "keep" first.
pub fn action_set(combined: bool) -> &'static [Action] {
    if combined {
        &ACTIONS
    } else {
        &ACTIONS[..5]
    }
}

/// Maneuver transition with `clip`: `None` when the action leaves `1..=lanes` or `{-1,0,1}`
/// (the action is discarded, never saturated).
pub fn transition(m: Maneuver, d: Action, lanes: u8) -> Option<Maneuver> {
    let lane = i16::from(m.lane) + i16::from(d.lateral);
    let beta = m.beta + d.longitudinal;
    if lane < 1 || lane > i16::from(lanes) || !(-1..=1).contains(&beta) {
        return None;
    }
    Some(Maneuver { lane: lane as u8, beta })
}

/// Where a rollout starts: the ego's maneuver, position, speed and occupied lanes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EgoStart {
    pub maneuver: Maneuver,
    pub x: f64,
    pub v: f64,
    /// Lanes the ego occupies now (body and target lane).
    pub occupancy: LaneSet,
    /// Which lanes the plan occupies after a lane change.
    pub plan_occupancy: PlanOccupancy,
}

/// Longitudinal kinematics of the maps `f^sigma`.
#[derive(Debug, Clone, Copy)]
pub struct Kinematics {
    pub dt: f64,
    /// Acceleration for `beta = -1, 0, +1` of the discrete maps (and the SVs' branches).
    pub accel: [f64; 3],
    /// Range of the ego's kinematic input `u` for `beta = -1, 0, +1`; a single point per state
    /// without `ego.continuous_accel`.
    pub bounds: [(f64, f64); 3],
}

impl Kinematics {
    pub fn new(config: &PlannerConfig) -> Self {
        let e = &config.ego;
        let accel = [e.decel_mps2, 0.0, e.accel_mps2];
        let bounds = if e.continuous_accel {
            let band = e.cruise_band_mps2;
            [(e.max_decel_mps2, -band), (-band, band), (band, e.accel_mps2)]
        } else {
            accel.map(|a| (a, a))
        };
        Self {
            dt: config.timing.step_s,
            accel,
            bounds,
        }
    }

    pub fn accel_of(&self, beta: Beta) -> f64 {
        self.accel[(beta + 1) as usize]
    }

    /// Range of `u` in maneuver state `beta`.
    pub fn bounds_of(&self, beta: Beta) -> (f64, f64) {
        self.bounds[(beta + 1) as usize]
    }

    /// Whether some state leaves the MPC a choice of acceleration.
    pub fn is_continuous(&self) -> bool {
        self.bounds.iter().any(|(lo, hi)| lo < hi)
    }

    /// Smallest and largest acceleration of any state.
    pub fn extreme_accels(&self) -> (f64, f64) {
        (self.bounds[0].0, self.bounds[2].1)
    }

    /// One step at acceleration `a`.
    pub fn step_with(&self, x: f64, v: f64, a: f64) -> (f64, f64) {
        (x + v * self.dt + 0.5 * a * self.dt * self.dt, v + a * self.dt)
    }

    /// One step of `f^sigma`: the acceleration is that of the *next* maneuver state.
    pub fn step(&self, x: f64, v: f64, beta_next: Beta) -> (f64, f64) {
        self.step_with(x, v, self.accel_of(beta_next))
    }

    /// `d x_h / d u_j` for `j <= h` (0-based steps): position after step `h` is
    /// `x0 + (h + 1) v0 dt + sum_j position_gain(h, j) u_j`.
    pub fn position_gain(&self, h: usize, j: usize) -> f64 {
        self.dt * self.dt * ((h - j) as f64 + 0.5)
    }

    /// Position after step `h` at zero acceleration.
    pub fn coasting_position(&self, start: &EgoStart, h: usize) -> f64 {
        start.x + (h + 1) as f64 * self.dt * start.v
    }
}

/// One action sequence over the horizon, rolled out.
#[derive(Debug, Clone, PartialEq)]
pub struct Rollout {
    pub actions: Vec<Action>,
    /// Maneuver after each step (`m_1..m_H`).
    pub maneuvers: Vec<Maneuver>,
    /// Acceleration applied in each step.
    pub accel: Vec<f64>,
    /// Position and speed after each step.
    pub x: Vec<f64>,
    pub v: Vec<f64>,
    /// Lanes occupied after each step: the initial lanes plus every lane targeted so far,
    /// because a lane change (`T_lc` = 3 s) outlasts the horizon.
    pub occupancy: Vec<LaneSet>,
}

impl Rollout {
    /// The same maneuvers driven at other accelerations (one per step).
    pub fn with_accelerations(&self, kin: &Kinematics, start: &EgoStart, accel: &[f64]) -> Rollout {
        let mut out = self.clone();
        let (mut x, mut v) = (start.x, start.v);
        for (h, &a) in accel.iter().enumerate() {
            (x, v) = kin.step_with(x, v, a);
            out.accel[h] = a;
            out.x[h] = x;
            out.v[h] = v;
        }
        out
    }
}

/// Roll a given action sequence out at each state's representative acceleration; `None` if
/// `clip` discards one of its actions.
pub fn rollout(kin: &Kinematics, lanes: u8, start: &EgoStart, actions: &[Action]) -> Option<Rollout> {
    let h = actions.len();
    let mut out = Rollout {
        actions: actions.to_vec(),
        maneuvers: Vec::with_capacity(h),
        accel: Vec::with_capacity(h),
        x: Vec::with_capacity(h),
        v: Vec::with_capacity(h),
        occupancy: Vec::with_capacity(h),
    };
    // `seen`: every lane occupied now or targeted so far, whichever lanes the plan occupies.
    let (mut m, mut x, mut v, mut seen) = (start.maneuver, start.x, start.v, start.occupancy);
    let mut new_lanes = 0;
    for &d in actions {
        m = transition(m, d, lanes)?;
        if !seen.contains(m.lane) {
            new_lanes += 1;
        }
        if new_lanes > new_lanes_allowed(start.occupancy) {
            return None;
        }
        let a = kin.accel_of(m.beta);
        (x, v) = kin.step_with(x, v, a);
        seen = seen.with(m.lane);
        out.maneuvers.push(m);
        out.accel.push(a);
        out.x.push(x);
        out.v.push(v);
        out.occupancy.push(match start.plan_occupancy {
            PlanOccupancy::HeldThroughChange => seen,
            PlanOccupancy::TargetLane => LaneSet::single(m.lane),
        });
    }
    Some(out)
}

/// How many lanes the ego does not occupy now a plan may target: one from a lane centre,
/// none while a lane change is under way (its body spans two lanes). A lane change outlasts
/// the horizon, so a plan may change lanes once, or abort a change under way back into a lane
/// the ego still occupies, but never retarget a change to a further lane: sweeping across
/// lanes one decision after another put the ego beside traffic it had checked only for the
/// lane it was leaving.
pub fn new_lanes_allowed(occupancy: LaneSet) -> usize {
    usize::from(occupancy.iter().count() == 1)
}

/// Every `clip`-admissible action sequence of length `horizon`, in lexicographic order of
/// the action set (so "keep, keep, ..." is first).
pub fn admissible_sequences(start: Maneuver, lanes: u8, horizon: usize, combined: bool) -> Vec<Vec<Action>> {
    let set = action_set(combined);
    let mut out = Vec::new();
    let mut prefix = Vec::with_capacity(horizon);
    fn recurse(
        m: Maneuver,
        lanes: u8,
        left: usize,
        set: &[Action],
        prefix: &mut Vec<Action>,
        out: &mut Vec<Vec<Action>>,
    ) {
        if left == 0 {
            out.push(prefix.clone());
            return;
        }
        for &d in set {
            if let Some(next) = transition(m, d, lanes) {
                prefix.push(d);
                recurse(next, lanes, left - 1, set, prefix, out);
                prefix.pop();
            }
        }
    }
    recurse(start, lanes, horizon, set, &mut prefix, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(lane: u8, beta: Beta) -> Maneuver {
        Maneuver { lane, beta }
    }

    #[test]
    fn clip_discards_rather_than_saturates() {
        assert_eq!(
            transition(
                m(1, 0),
                Action {
                    lateral: -1,
                    longitudinal: 0
                },
                2
            ),
            None
        );
        assert_eq!(
            transition(
                m(2, 0),
                Action {
                    lateral: 1,
                    longitudinal: 0
                },
                2
            ),
            None
        );
        assert_eq!(
            transition(
                m(1, 1),
                Action {
                    lateral: 0,
                    longitudinal: 1
                },
                2
            ),
            None
        );
        assert_eq!(
            transition(
                m(2, 1),
                Action {
                    lateral: -1,
                    longitudinal: 0
                },
                2
            ),
            Some(m(1, 1))
        );
    }

    #[test]
    fn sequence_counts() {
        // Middle lane of 3, cruising: all 5 actions admissible at every step of 1.
        assert_eq!(admissible_sequences(m(2, 0), 3, 1, false).len(), 5);
        let all = admissible_sequences(m(2, 0), 5, 3, false);
        // In 5 lanes, starting from lane 3 cruising, only the beta bound prunes:
        // beta sequences with |beta| <= 1 at each step.
        let wide = admissible_sequences(m(3, 0), 5, 1, true);
        assert_eq!(wide.len(), 9);
        assert_eq!(all[0], vec![Action::KEEP; 3]);
    }

    #[test]
    fn exhaustive_count_matches_brute_force() {
        for lanes in 1..=4u8 {
            for lane in 1..=lanes {
                for beta in -1..=1 {
                    let start = m(lane, beta);
                    let mut brute = 0;
                    let one_step = action_set(false);
                    for &a in one_step {
                        for &b in one_step {
                            for &c in one_step {
                                let seq = [a, b, c];
                                let mut cur = Some(start);
                                for d in seq {
                                    cur = cur.and_then(|s| transition(s, d, lanes));
                                }
                                brute += usize::from(cur.is_some());
                            }
                        }
                    }
                    assert_eq!(admissible_sequences(start, lanes, 3, false).len(), brute);
                }
            }
        }
    }

    #[test]
    fn kinematic_map_uses_next_beta() {
        let kin = Kinematics {
            dt: 0.4,
            accel: [-3.0, 0.0, 1.5],
            bounds: [(-3.0, -3.0), (0.0, 0.0), (1.5, 1.5)],
        };
        let (x, v) = kin.step(100.0, 20.0, 1);
        assert!((x - (100.0 + 8.0 + 0.5 * 1.5 * 0.16)).abs() < 1e-12);
        assert!((v - 20.6).abs() < 1e-12);
        let (x, v) = kin.step(0.0, 10.0, -1);
        assert!((x - (4.0 - 0.24)).abs() < 1e-12);
        assert!((v - 8.8).abs() < 1e-12);
    }

    #[test]
    fn a_plan_changes_lanes_once_and_never_retargets_a_change_under_way() {
        let kin = Kinematics {
            dt: 0.4,
            accel: [-3.0, 0.0, 1.5],
            bounds: [(-3.0, -3.0), (0.0, 0.0), (1.5, 1.5)],
        };
        let (keep, left, right) = (ACTIONS[0], ACTIONS[1], ACTIONS[2]);
        assert_eq!((left.lateral, right.lateral, left.longitudinal), (-1, 1, 0));
        let at = |lane: u8, occupancy: LaneSet| EgoStart {
            maneuver: m(lane, 0),
            x: 0.0,
            v: 10.0,
            occupancy,
            plan_occupancy: PlanOccupancy::HeldThroughChange,
        };
        // From a lane centre: one change, and back, but not a second lane further.
        let centred = at(2, LaneSet::single(2));
        assert!(rollout(&kin, 4, &centred, &[left, keep, keep]).is_some());
        assert!(rollout(&kin, 4, &centred, &[left, right, keep]).is_some());
        assert!(rollout(&kin, 4, &centred, &[left, left, keep]).is_none());
        assert!(rollout(&kin, 4, &centred, &[left, right, right]).is_none());
        // A change from 2 to 3 under way: aborting back to 2 is allowed, going on to 4 is not.
        let changing = at(3, LaneSet::single(2).with(3));
        assert!(rollout(&kin, 4, &changing, &[keep, keep, keep]).is_some());
        assert!(rollout(&kin, 4, &changing, &[left, keep, keep]).is_some());
        assert!(rollout(&kin, 4, &changing, &[right, keep, keep]).is_none());
        assert!(rollout(&kin, 4, &changing, &[keep, keep, right]).is_none());
    }

    #[test]
    fn occupancy_keeps_the_origin_lane_after_a_change() {
        let kin = Kinematics {
            dt: 0.4,
            accel: [-3.0, 0.0, 1.5],
            bounds: [(-3.0, -3.0), (0.0, 0.0), (1.5, 1.5)],
        };
        let left = Action {
            lateral: -1,
            longitudinal: 0,
        };
        let start = EgoStart {
            maneuver: m(2, 0),
            x: 0.0,
            v: 10.0,
            occupancy: LaneSet::single(2),
            plan_occupancy: PlanOccupancy::HeldThroughChange,
        };
        let r = rollout(&kin, 3, &start, &[Action::KEEP, left, Action::KEEP]).unwrap();
        let slow = r.with_accelerations(&kin, &start, &[0.0, -1.0, -1.0]);
        assert!((slow.v[2] - 9.2).abs() < 1e-12);
        // x after 3 steps: 12 + sum_j gain(2, j) u_j = 12 - 0.16 * (1.5 + 0.5).
        assert!((slow.x[2] - (12.0 - 0.32)).abs() < 1e-12);
        assert!(
            (kin.coasting_position(&start, 2) - kin.position_gain(2, 1) - kin.position_gain(2, 2) - slow.x[2]).abs()
                < 1e-12
        );
        assert_eq!(r.occupancy[0], LaneSet::single(2));
        assert_eq!(r.occupancy[1], LaneSet::single(1).with(2));
        assert_eq!(r.occupancy[2], LaneSet::single(1).with(2));
        assert_eq!(r.maneuvers[2], m(1, 0));
        // The paper's alpha: the target lane alone from the step the change begins.
        let paper = EgoStart {
            plan_occupancy: PlanOccupancy::TargetLane,
            ..start
        };
        let r = rollout(&kin, 3, &paper, &[Action::KEEP, left, Action::KEEP]).unwrap();
        let lanes: Vec<LaneSet> = r.occupancy.clone();
        assert_eq!(lanes, vec![LaneSet::single(2), LaneSet::single(1), LaneSet::single(1)]);
        // The limit of one change per plan still counts the lanes left behind.
        let back_and_on = [left, Action { lateral: 1, ..left }, Action { lateral: 1, ..left }];
        assert!(rollout(&kin, 3, &paper, &back_and_on).is_none());
    }
}
