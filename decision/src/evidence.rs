//! Evidence in the SV scenario tree (paper III-B with observed evidence): the first step of an
//! SV's HMDP gets transition probabilities from what the SV shows, the later steps keep the
//! background ones, and the tree is pruned as before. So a branch survives where it matters —
//! an SV drifting towards a lane, held up behind a slower one, closing in on its leader — and
//! the prediction stays a single branch in quiet traffic.
//!
//! * Lateral: Bayes on the measured lateral velocity `vy`. Keeping the lane, `vy` is Gaussian
//!   around 0 (`keep_lateral_sigma_mps`); changing towards a side, its component that way is
//!   uniform on `[0, change_lateral_speed_max_mps]`. The prior of a side is the background
//!   `(1 - p_keep_lat) / 2`, raised towards `incentive_lane_change` when the SV is held up by
//!   a slower leader and that side's lane is freer (MOBIL's incentive).
//! * Longitudinal: an SV closing in on its own leader (another SV or the ego) with a time to
//!   collision below `brake_ttc_s` brakes in the next step with a probability growing to
//!   `brake_max`.
//!
//! A lane-changing branch leaves the lane it starts in once its body has left it at the
//! departure share of its lateral speed ([`depart`]), so an SV moving out of the ego's lane
//! stops constraining it in time.

use crate::config::PlannerConfig;
use crate::lanes::{lanes_at, nearest_lane, LaneSet};
use crate::scenario::Branch;
use crate::types::{EgoState, Road, SvObservation};

/// Probabilities of the first step's actions of one SV, from its evidence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FirstStep {
    /// A change to the left (`lateral = -1`, towards higher `y`).
    pub left: f64,
    /// A change to the right.
    pub right: f64,
    /// Braking (`longitudinal = -1`).
    pub brake: f64,
}

/// Where an SV is heading sideways: the lane of its maneuver state (the HMDP's `alpha`) and,
/// for a lane change already under way (the SV between two lane centres, moving towards one),
/// the lane it is leaving.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Heading {
    pub lane: u8,
    pub leaving: Option<u8>,
}

/// The SV's [`Heading`]: between two lane centres and moving towards one (faster than
/// `keep_lateral_sigma_mps`), it is changing into that one; otherwise its nearest lane.
pub fn heading(config: &PlannerConfig, road: &Road, sv: &SvObservation) -> Heading {
    let tol = config.vehicle.lane_centre_tolerance_m;
    let nearest = nearest_lane(road, sv.y_m).unwrap_or(1);
    let still = Heading {
        lane: nearest,
        leaving: None,
    };
    let moving =
        config.prediction.evidence.enabled && sv.vy_mps.abs() > config.prediction.evidence.keep_lateral_sigma_mps;
    let Ok(body) = lanes_at(road, sv.y_m, tol) else {
        return still;
    };
    let lanes: Vec<u8> = body.iter().collect();
    match (moving, lanes.as_slice()) {
        // Lane `a` has the higher y: moving up (vy > 0) heads into `a`.
        (true, &[a, b]) if sv.vy_mps > 0.0 => Heading {
            lane: a,
            leaving: Some(b),
        },
        (true, &[a, b]) => Heading {
            lane: b,
            leaving: Some(a),
        },
        _ => still,
    }
}

/// A vehicle in the scene as the evidence sees it (the ego is one for the SVs).
#[derive(Debug, Clone, Copy)]
struct Body {
    x: f64,
    v: f64,
    lane: u8,
}

/// The first step of `sv`'s tree, or `None` when the evidence is off (every step then has the
/// background probabilities).
pub fn first_step(
    config: &PlannerConfig,
    road: &Road,
    ego: &EgoState,
    svs: &[SvObservation],
    sv: &SvObservation,
) -> Option<FirstStep> {
    let e = &config.prediction.evidence;
    if !e.enabled {
        return None;
    }
    let heading = heading(config, road, sv);
    let lane = heading.lane;
    let others: Vec<Body> = svs
        .iter()
        .filter(|o| o.id != sv.id)
        .filter_map(|o| {
            Some(Body {
                x: o.x_m,
                v: o.v_mps,
                lane: nearest_lane(road, o.y_m).ok()?,
            })
        })
        .chain(nearest_lane(road, ego.y_m).ok().map(|lane| Body {
            x: ego.x_m,
            v: ego.v_mps,
            lane,
        }))
        .collect();
    let me = Body {
        x: sv.x_m,
        v: sv.v_mps,
        lane,
    };
    let leader = |lane: u8| {
        others
            .iter()
            .filter(|o| o.lane == lane && o.x > me.x && o.x - me.x <= e.incentive_range_m)
            .min_by(|a, b| a.x.total_cmp(&b.x))
    };
    let own = leader(lane);
    // Held up: how much faster than its leader, scaled to [0, 1].
    let held_up = own.map_or(0.0, |l| {
        ((me.v - l.v - 1.0) / (e.incentive_speed_gap_mps - 1.0)).clamp(0.0, 1.0)
    });
    let background = (1.0 - config.prediction.p_keep_lat) / 2.0;
    // Left is the lane with the smaller index (higher y).
    let sides = [
        (lane.checked_sub(1).filter(|&l| l >= 1), 1.0),
        (lane.checked_add(1).filter(|&l| l <= road.lanes), -1.0),
    ];
    let mut prior = [0.0; 2];
    let mut likelihood = [0.0; 2];
    // A lane change under way is the maneuver state the tree starts in: its lateral velocity
    // says nothing about a further change, which has the background probability. So too for
    // one ending: still moving towards its lane's centre and reaching it within a decision
    // step, an SV shows the change it finishes, not one into the lane beyond (read as a start,
    // it had the ego beside it brake at 6 m/s^2 for a cut-in that never came). A change that
    // starts from just off the centre on the far side is seen a step later, once past it.
    let offset = sv.y_m - road.lane_centre(lane);
    let arriving = offset * sv.vy_mps < 0.0 && offset.abs() <= sv.vy_mps.abs() * config.timing.step_s;
    let under_way = heading.leaving.is_some() || arriving;
    for (k, (target, sign)) in sides.iter().enumerate() {
        let Some(target) = *target else { continue };
        if under_way {
            prior[k] = background;
            likelihood[k] = 1.0;
            continue;
        }
        let freer = leader(target).is_none_or(|t| own.is_none_or(|o| t.v > o.v + 1.0));
        let incentive = if freer { held_up } else { 0.0 };
        prior[k] = background + (e.incentive_lane_change - background).max(0.0) * incentive;
        let towards = sign * sv.vy_mps;
        likelihood[k] = if (0.0..=e.change_lateral_speed_max_mps).contains(&towards) {
            1.0 / e.change_lateral_speed_max_mps
        } else {
            0.0
        };
    }
    let sigma = e.keep_lateral_sigma_mps;
    let keep_likelihood = if under_way {
        1.0
    } else {
        (-0.5 * (sv.vy_mps / sigma).powi(2)).exp() / (sigma * (2.0 * std::f64::consts::PI).sqrt())
    };
    let keep = (1.0 - prior[0] - prior[1]) * keep_likelihood;
    let changes = [prior[0] * likelihood[0], prior[1] * likelihood[1]];
    let total = keep + changes[0] + changes[1];
    let (left, right) = if total > 0.0 {
        (changes[0] / total, changes[1] / total)
    } else {
        // No hypothesis explains the motion (faster than any lane change): it changes lanes,
        // if it has a lane to change to.
        let towards = |k: usize, moving: bool| f64::from(moving && sides[k].0.is_some());
        (towards(0, sv.vy_mps > 0.0), towards(1, sv.vy_mps < 0.0))
    };
    let brake_background = (1.0 - config.prediction.p_keep_long) / 2.0;
    let ttc = own.filter(|l| me.v > l.v).map_or(f64::INFINITY, |l| {
        (l.x - me.x - config.vehicle.length_m).max(0.0) / (me.v - l.v)
    });
    let urgency = ((e.brake_ttc_s - ttc) / e.brake_ttc_s).clamp(0.0, 1.0);
    let brake = brake_background + (e.brake_max - brake_background).max(0.0) * urgency;
    Some(FirstStep { left, right, brake })
}

/// Lets every branch of `sv` that changes lanes leave the lane it starts from once its body
/// has left it, moving sideways at `departure_speed_share` of its lateral speed (the measured
/// one when it moves that way, else a lane width per `ego.lane_change_s`): a branch that
/// changes lanes in the tree leaves its start lane, and with a change already under way
/// ([`Heading::leaving`]) every branch leaves the lane the SV is leaving.
pub fn depart(config: &PlannerConfig, road: &Road, sv: &SvObservation, heading: Heading, branches: &mut [Branch]) {
    let tol = config.vehicle.lane_centre_tolerance_m;
    let (lo, hi) = (road.lane_centre(road.lanes), road.lane_centre(1));
    let nominal = road.lane_width_m / config.ego.lane_change_s;
    let share = config.prediction.departure_speed_share;
    for b in branches.iter_mut() {
        let (onset, start_lane, target) = match heading.leaving {
            Some(leaving) => (0, leaving, heading.lane),
            None => match b.maneuvers.iter().position(|m| m.lane != heading.lane) {
                Some(onset) => (onset, heading.lane, b.maneuvers[onset].lane),
                None => continue,
            },
        };
        // Towards higher y for a smaller lane index.
        let sign = if target < start_lane { 1.0 } else { -1.0 };
        let speed = (sign * sv.vy_mps).max(nominal);
        let origin = LaneSet::single(start_lane);
        for h in onset..b.occupancy.len() {
            // Moving since the step before the change took effect at the latest.
            let moving = config.timing.step_s * (h + 1) as f64;
            let y = (sv.y_m + sign * share * speed * moving).clamp(lo, hi);
            let body = lanes_at(road, y, tol).unwrap_or(origin);
            if !body.intersects(origin) {
                b.occupancy[h] = b.occupancy[h].without(start_lane);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::Maneuver;

    fn road() -> Road {
        Road {
            lanes: 3,
            lane_width_m: 4.0,
            speed_limit_mps: 40.0,
        }
    }

    fn ego() -> EgoState {
        EgoState {
            x_m: 0.0,
            y_m: 4.0,
            v_mps: 25.0,
            desired_speed_mps: 30.0,
            maneuver: Maneuver { lane: 2, beta: 0 },
        }
    }

    fn sv(id: u32, x: f64, y: f64, v: f64, vy: f64) -> SvObservation {
        SvObservation {
            vy_mps: vy,
            ..SvObservation::new(id, x, y, v, 0.0)
        }
    }

    #[test]
    fn quiet_traffic_has_the_background_probabilities() {
        let config = PlannerConfig::default();
        let alone = sv(1, 30.0, 8.0, 25.0, 0.0);
        let f = first_step(&config, &road(), &ego(), &[alone], &alone).unwrap();
        // Lane 1 is the leftmost: no change to the left; to the right the background prior,
        // divided by the keep likelihood's peak (vy = 0 favours keeping).
        assert_eq!(f.left, 0.0);
        assert!(f.right < 0.01, "{f:?}");
        assert!((f.brake - 0.1).abs() < 1e-12, "{f:?}");
    }

    #[test]
    fn a_drifting_sv_held_up_by_a_slower_one_is_likely_to_change_lanes() {
        let config = PlannerConfig::default();
        let cutting = sv(1, 30.0, 7.95, 25.0, -0.15);
        let slow = sv(2, 55.0, 8.0, 18.0, 0.0);
        let f = first_step(&config, &road(), &ego(), &[cutting, slow], &cutting).unwrap();
        assert!(f.right > 0.3 && f.right < 0.7, "{f:?}");
        assert_eq!(f.left, 0.0);
        // Closing in on the slower one at 7 m/s from 20.5 m: a time to collision of 2.9 s.
        assert!(f.brake > 0.4, "{f:?}");
        // Without the slower leader the same drift is far less telling.
        let f = first_step(&config, &road(), &ego(), &[cutting], &cutting).unwrap();
        assert!(f.right < 0.3, "{f:?}");
        // Moving fast sideways at its lane centre, the change is near certain whatever the
        // surroundings.
        let fast = sv(1, 30.0, 7.95, 25.0, -0.6);
        let f = first_step(&config, &road(), &ego(), &[fast], &fast).unwrap();
        assert!(f.right > 0.99, "{f:?}");
    }

    #[test]
    fn a_change_under_way_is_the_state_the_tree_starts_in() {
        let config = PlannerConfig::default();
        // Half a metre out of lane 1's centre, moving towards lane 2: changing into lane 2.
        let changing = sv(1, 30.0, 7.5, 25.0, -0.6);
        assert_eq!(
            heading(&config, &road(), &changing),
            Heading {
                lane: 2,
                leaving: Some(1)
            }
        );
        // A further change has the background probability only.
        let f = first_step(&config, &road(), &ego(), &[changing], &changing).unwrap();
        assert!((f.left - 0.05).abs() < 1e-12 && (f.right - 0.05).abs() < 1e-12, "{f:?}");
        // Off-centre but not moving: it stays in its nearest lane.
        let straddling = sv(1, 30.0, 7.5, 25.0, 0.0);
        assert_eq!(
            heading(&config, &road(), &straddling),
            Heading { lane: 1, leaving: None }
        );
    }

    #[test]
    fn a_change_ending_is_no_evidence_of_the_next() {
        let config = PlannerConfig::default();
        // 1 cm short of lane 2's centre, still moving up into it at 0.24 m/s: the end of a
        // change from lane 3, not the start of one into lane 1.
        let arriving = sv(1, 3.0, 3.99, 28.0, 0.24);
        let f = first_step(&config, &road(), &ego(), &[arriving], &arriving).unwrap();
        assert!((f.left - 0.05).abs() < 1e-12 && (f.right - 0.05).abs() < 1e-12, "{f:?}");
        // The same speed 1 cm past the centre, moving away from it: a change starting.
        let leaving = sv(1, 3.0, 4.01, 28.0, 0.24);
        let f = first_step(&config, &road(), &ego(), &[leaving], &leaving).unwrap();
        assert!(f.left > 0.99, "{f:?}");
        // 8 cm short of the centre at 0.18 m/s: not there within a step (0.4 s), so read as a
        // change starting from just off the centre (as likely as that speed makes it).
        let slow = sv(1, 3.0, 3.92, 28.0, 0.18);
        let f = first_step(&config, &road(), &ego(), &[slow], &slow).unwrap();
        assert!(f.left > 0.5, "{f:?}");
    }

    #[test]
    fn off_means_the_background_tree() {
        let mut config = PlannerConfig::default();
        config.prediction.evidence.enabled = false;
        let s = sv(1, 30.0, 7.5, 25.0, -0.6);
        assert_eq!(first_step(&config, &road(), &ego(), &[s], &s), None);
    }
}
