//! Where an SV's braking ends. An SV braking behind a slower vehicle in its lane brakes to
//! take that vehicle's speed, not to a standstill: the braking the ego needs to stay behind it
//! (`needed_decel`, the floor of the violation allowance's reference braking and of the
//! fallback's) is reckoned with the SV braking down to that speed, less
//! `prediction.braking_end_margin_mps` for the gap the SV may still open (the IDM undershoots
//! a leader's speed when it closed in too far), and hedged against it braking on to a stop
//! after all. Braking that nothing visible explains (no slower vehicle ahead) is taken to go
//! on to a standstill, as a leader braking for an obstacle would. The predicted branches keep
//! braking to a standstill: against them, the allowance's reference holds the ego to
//! `needed_decel`.
//!
//! Without this, every leader braking hard for a slower car in front of it was followed as
//! if it were stopping: at the start of a random scene, where SVs placed close behind slower
//! ones brake at up to 9 m/s^2 for a second, the ego braked beyond 2.5 m/s^2 for a car
//! that would settle 10 m/s faster than a standstill (docs/braking-leader.md).

use crate::config::PlannerConfig;
use crate::lanes::{lanes_at, LaneSet};
use crate::stopping::{escalating_decel, stopping_decel};
use crate::types::{Situation, SvObservation};

/// The speed each braking SV of a situation is explained to brake down to (m/s; 0: a
/// standstill, for every SV whose braking nothing explains).
#[derive(Debug, Clone, Default)]
pub struct BrakingEnds {
    /// `(id, end speed)`, by id, of the SVs whose braking is explained.
    ends: Vec<(u32, f64)>,
}

/// A vehicle as the explanation sees it.
struct Body {
    id: Option<u32>,
    x: f64,
    lanes: LaneSet,
    v: f64,
    /// The speed it ends at: its own when it does not brake.
    end: f64,
}

impl BrakingEnds {
    /// The end speed of every SV in the perception window. Leaders first, so that an SV
    /// braking for one that brakes itself ends where that one ends, less the margin.
    pub fn new(config: &PlannerConfig, s: &Situation) -> Self {
        let p = &config.prediction;
        // Most situations have no SV braking: nothing to explain, nothing to allocate.
        if !p.braking_ends_at_leader || s.svs.iter().all(|sv| sv.a_mps2 >= -p.accel_dead_band_mps2) {
            return BrakingEnds::default();
        }
        let tol = config.vehicle.lane_centre_tolerance_m;
        let ego = &s.ego;
        let window = &config.perception;
        let mut bodies: Vec<(Body, f64)> = s
            .svs
            .iter()
            .filter(|sv| {
                let dx = sv.x_m - ego.x_m;
                dx <= window.range_ahead_m && dx >= -window.range_behind_m
            })
            .filter_map(|sv| {
                let lanes = lanes_at(&s.road, sv.y_m, tol).ok()?;
                let body = Body {
                    id: Some(sv.id),
                    x: sv.x_m,
                    lanes,
                    v: sv.v_mps,
                    end: sv.v_mps,
                };
                Some((body, sv.a_mps2))
            })
            .collect();
        // The ego is a vehicle an SV may brake for (it does not brake on a prediction).
        if let Ok(lanes) = lanes_at(&s.road, ego.y_m, tol) {
            let body = Body {
                id: None,
                x: ego.x_m,
                lanes,
                v: ego.v_mps,
                end: ego.v_mps,
            };
            bodies.push((body, 0.0));
        }
        bodies.sort_by(|a, b| b.0.x.total_cmp(&a.0.x));
        let mut done: Vec<Body> = Vec::with_capacity(bodies.len());
        let mut ends = Vec::new();
        for (mut body, accel) in bodies {
            if accel < -p.accel_dead_band_mps2 {
                // `done` is in falling x: the last one ahead sharing a lane is the nearest.
                let leader = done
                    .iter()
                    .rev()
                    .find(|o| o.x > body.x && o.lanes.intersects(body.lanes));
                body.end = leader.map_or(0.0, |l| explained_end(config, &body, l));
                if let (Some(id), true) = (body.id, body.end > 0.0) {
                    ends.push((id, body.end));
                }
            }
            done.push(body);
        }
        ends.sort_by_key(|e| e.0);
        BrakingEnds { ends }
    }

    /// The speed SV `id`'s braking is explained to end at; 0 (a standstill) for any other SV
    /// (one whose braking nothing explains, one braking within the dead band, one not in the
    /// window).
    pub fn of(&self, id: u32) -> f64 {
        self.ends
            .binary_search_by_key(&id, |e| e.0)
            .map_or(0.0, |i| self.ends[i].1)
    }

    /// The least deceleration that keeps the ego at `v_ego` the jam distance behind `sv`,
    /// `gap_m` (bumpers) ahead: braking on to its end speed (`stopping::stopping_decel`).
    /// An end above a standstill is only what the vehicle ahead of it explains, so the answer
    /// must also leave room for the SV braking on to a stop after all: from the moment it
    /// passes the speed that explained it, a decision step later, the ego's strongest braking
    /// must still keep the jam distance (`stopping::escalating_decel`).
    pub fn needed_decel(&self, config: &PlannerConfig, sv: &SvObservation, gap_m: f64, v_ego: f64) -> f64 {
        let jam = config.idm.jam_distance_m;
        let end = self.of(sv.id);
        let to_end = stopping_decel(gap_m, jam, v_ego, sv.v_mps, sv.a_mps2, end);
        if end <= 0.0 {
            return to_end;
        }
        let disproved_below = end + config.prediction.braking_end_margin_mps;
        let braking = (-sv.a_mps2).max(1e-6);
        let hold_s = (sv.v_mps - disproved_below).max(0.0) / braking + config.timing.step_s;
        let escalation = -config.ego.max_decel_mps2;
        to_end.max(escalating_decel(
            gap_m, jam, v_ego, sv.v_mps, sv.a_mps2, hold_s, escalation,
        ))
    }
}

/// The end speed of `body`'s braking behind `leader`: the speed the leader ends at, less the
/// margin, when that explains it (the leader ends slower than `body` is now); a standstill
/// otherwise. An SV still braking at or below that speed is not taken at its word: the ego
/// counts on the explanation only while it has not been disproved.
fn explained_end(config: &PlannerConfig, body: &Body, leader: &Body) -> f64 {
    if leader.end < body.v {
        (leader.end - config.prediction.braking_end_margin_mps).max(0.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::{EgoState, Maneuver, PlannerMemory, Road, SvObservation};

    const ROAD: Road = Road {
        lanes: 3,
        lane_width_m: 3.5,
        speed_limit_mps: 40.0,
    };

    fn situation(svs: Vec<SvObservation>) -> Situation {
        let ego = EgoState {
            x_m: 0.0,
            y_m: ROAD.lane_centre(2),
            v_mps: 30.0,
            maneuver: Maneuver { lane: 2, beta: 0 },
            desired_speed_mps: 33.0,
        };
        Situation {
            road: ROAD,
            ego,
            svs,
            memory: PlannerMemory::default(),
        }
    }

    fn sv(id: u32, x: f64, lane: u8, v: f64, a: f64) -> SvObservation {
        SvObservation::new(id, x, ROAD.lane_centre(lane), v, a)
    }

    #[test]
    fn braking_for_a_slower_leader_ends_below_its_speed() {
        let config = PlannerConfig::default();
        let margin = config.prediction.braking_end_margin_mps;
        let s = situation(vec![sv(1, 40.0, 2, 30.0, -9.0), sv(2, 70.0, 2, 20.0, 0.0)]);
        let ends = BrakingEnds::new(&config, &s);
        assert_eq!(ends.of(1), 20.0 - margin);
        // Not braking (or within the dead band): nothing explained, a standstill as before.
        assert_eq!(ends.of(2), 0.0);
        let s = situation(vec![sv(1, 40.0, 2, 30.0, -0.29), sv(2, 70.0, 2, 20.0, 0.0)]);
        assert_eq!(BrakingEnds::new(&config, &s).of(1), 0.0);
    }

    #[test]
    fn unexplained_braking_goes_on_to_a_standstill() {
        let config = PlannerConfig::default();
        // Nothing ahead; a faster leader far ahead; a slower one in another lane.
        for others in [
            vec![],
            vec![sv(2, 190.0, 2, 35.0, 0.0)],
            vec![sv(2, 60.0, 1, 15.0, 0.0)],
        ] {
            let mut svs = vec![sv(1, 40.0, 2, 30.0, -4.0)];
            svs.extend(others);
            assert_eq!(BrakingEnds::new(&config, &situation(svs)).of(1), 0.0);
        }
        let mut off = PlannerConfig::default();
        off.prediction.braking_ends_at_leader = false;
        let s = situation(vec![sv(1, 40.0, 2, 30.0, -9.0), sv(2, 70.0, 2, 20.0, 0.0)]);
        assert_eq!(BrakingEnds::new(&off, &s).of(1), 0.0);
    }

    #[test]
    fn a_chain_ends_where_its_head_ends() {
        let config = PlannerConfig::default();
        let margin = config.prediction.braking_end_margin_mps;
        // 3 brakes for 4 (slower), 1 for 3; and 5 for 6, which stops for nothing visible.
        let s = situation(vec![
            sv(1, 30.0, 2, 30.0, -3.0),
            sv(3, 60.0, 2, 27.0, -5.0),
            sv(4, 90.0, 2, 18.0, 0.1),
            sv(5, 30.0, 3, 30.0, -3.0),
            sv(6, 60.0, 3, 25.0, -5.0),
        ]);
        let ends = BrakingEnds::new(&config, &s);
        assert_eq!(ends.of(3), 18.0 - margin);
        assert_eq!(ends.of(1), 18.0 - 2.0 * margin);
        assert_eq!(ends.of(6), 0.0);
        assert_eq!(ends.of(5), 0.0);
    }

    #[test]
    fn braking_on_at_or_below_the_leaders_speed_is_not_explained() {
        let config = PlannerConfig::default();
        // Already slower than its leader and still braking: the explanation no longer holds.
        let s = situation(vec![sv(1, 40.0, 2, 19.0, -2.0), sv(2, 53.0, 2, 20.0, 0.0)]);
        assert_eq!(BrakingEnds::new(&config, &s).of(1), 0.0);
    }
}
