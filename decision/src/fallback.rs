//! Layer B: the deterministic fallback (paper eq. fallback_policy). It never fails.

use crate::braking_end::BrakingEnds;
use crate::config::PlannerConfig;
use crate::idm::{idm_distance, sv_idm_distance};
use crate::lanes::{lanes_at, LaneSet};
use crate::model::Kinematics;
use crate::stopping::stopping_decel;
use crate::types::{Beta, CorrectiveEntry, Situation, Threat};

/// The fallback's choice: the new `beta` and the threat that decided it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FallbackChoice {
    pub beta: Beta,
    pub threat: Threat,
    /// Id of the most critical SV, if any.
    pub sv_id: Option<u32>,
    /// Id of the front threat that needs the most braking, when another than `sv_id`.
    pub hardest_sv_id: Option<u32>,
    /// Its time to collision, s (infinite when not closing).
    pub ttc_s: f64,
    /// Braking the threat asks for, m/s^2: to keep the jam distance behind every `Front`
    /// threat, with room for it to slow down (`ego.lead_brake_room_mps2`; the threat that
    /// needs the most, which need not be `sv_id`), the comfortable braking for a `Band` one, 0
    /// otherwise.
    pub needed_decel_mps2: f64,
}

/// One SV sharing a lane with the ego, as the fallback sees it.
struct Candidate {
    id: u32,
    gap: f64,
    closing: f64,
    /// How far inside its IDM distance it is (negative: outside).
    deficit: f64,
    /// Braking that keeps the jam distance behind it (`BrakingEnds::needed_decel`; 0 behind the ego).
    stopping: f64,
    /// Braking that keeps it were it to brake at `ego.lead_brake_room_mps2` to a stop (0 behind
    /// the ego and for an SV ahead that is no threat).
    room: f64,
}

impl Candidate {
    fn ttc(&self) -> f64 {
        if self.gap <= 0.0 {
            0.0
        } else if self.closing > 0.0 {
            self.gap / self.closing
        } else {
            f64::INFINITY
        }
    }

    /// The braking it asks for: to keep the jam distance behind it, and the room for its braking.
    fn need(&self) -> f64 {
        self.stopping.max(self.room)
    }

    /// Most critical first: smallest TTC, then deepest inside its IDM distance, then id.
    fn more_critical(&self, other: &Candidate) -> bool {
        (self.ttc(), -self.deficit, self.id) < (other.ttc(), -other.deficit, other.id)
    }
}

/// The paper's three cases, and the band's, in this priority:
///
/// 1. **Front vehicle braking / too close**: an SV ahead in a lane the ego occupies
///    (`occupancy0`) that is inside its IDM distance (the distance includes the closing-speed
///    term, so a fast approach counts), or that brakes so that staying behind it takes more
///    than `ego.comfort_decel_mps2` (`BrakingEnds::needed_decel`): decelerate, at least that hard,
///    and at least as hard as keeps it behind should it brake at `ego.lead_brake_room_mps2`
///    to a stop (every front threat's, the most any needs). The most critical by time to
///    collision decides. While any front SV is inside its IDM
///    distance the fallback never accelerates.
/// 2. **Rear vehicle closing**: otherwise, an SV behind in the ego's lanes that closes in or is
///    inside its IDM distance: accelerate.
/// 3. **Front vehicle inside its band**: otherwise, with the band's slack bounded by `d_HS`
///    (`hysteresis.soft_band = false`, the paper's bound), an SV ahead in corrective mode closer
///    than its frozen trigger distance, deeper than that slack reaches: decelerate, at
///    `ego.comfort_decel_mps2` within the state's range (one fixed deceleration per state:
///    that one). Without this the fallback would hold the ego just outside the IDM distance,
///    where the nominal problem stays infeasible for as long as the SV stays ahead; braking
///    opens the gap the nominal rows ask for. With the soft band the band is no hard row, and
///    following inside the trigger distance is ordinary: not a threat.
/// 4. **Lateral risk**: otherwise, an SV alongside in an adjacent lane: hold speed.
///
/// With nothing at all, hold speed. `corrective` are the SVs in corrective mode after this
/// decision's hysteresis refresh.
pub fn choose(
    config: &PlannerConfig,
    s: &Situation,
    occupancy0: LaneSet,
    corrective: &[CorrectiveEntry],
) -> FallbackChoice {
    let ego = &s.ego;
    let length = config.vehicle.length_m;
    let tol = config.vehicle.lane_centre_tolerance_m;
    let braking_ends = BrakingEnds::new(config, s);
    let mut front: Option<Candidate> = None;
    // The braking the hardest front threat needs: during a lane change the SV with the
    // smallest TTC (which decides) need not be the one that takes the most braking.
    let mut hardest_need = 0.0_f64;
    let mut hardest_id = None;
    let mut rear: Option<Candidate> = None;
    let mut band: Option<Candidate> = None;
    let mut lateral: Option<u32> = None;
    for sv in &s.svs {
        let dx = sv.x_m - ego.x_m;
        if dx > config.perception.range_ahead_m || dx < -config.perception.range_behind_m {
            continue;
        }
        let Ok(lanes) = lanes_at(&s.road, sv.y_m, tol) else {
            continue;
        };
        if lanes.intersects(occupancy0) {
            if dx >= 0.0 {
                let mut c = Candidate {
                    id: sv.id,
                    gap: dx - length,
                    closing: ego.v_mps - sv.v_mps,
                    deficit: idm_distance(&config.idm, ego.v_mps, sv.v_mps) - (dx - length),
                    stopping: braking_ends.needed_decel(config, sv, dx - length, ego.v_mps),
                    room: 0.0,
                };
                // Inside its IDM distance, or braking so that staying behind it takes more
                // than the ego's comfortable braking: the paper's "front vehicle braking".
                let threat = c.deficit > 0.0 || c.stopping > -config.ego.comfort_decel_mps2;
                // The room only adds to a threat's braking: this runs every decision, so the
                // bisection runs only for threats.
                if threat {
                    c.room = lead_brake_room(config, c.gap, ego.v_mps, sv.v_mps);
                }
                let inside_band =
                    !config.hysteresis.soft_band && corrective.iter().any(|e| e.sv_id == sv.id && c.gap < e.trigger_m);
                if threat && c.need() > hardest_need {
                    (hardest_need, hardest_id) = (c.need(), Some(c.id));
                }
                if threat && front.as_ref().is_none_or(|f| c.more_critical(f)) {
                    front = Some(c);
                } else if !threat && inside_band && band.as_ref().is_none_or(|b| c.more_critical(b)) {
                    band = Some(c);
                }
            } else {
                let c = Candidate {
                    id: sv.id,
                    gap: -dx - length,
                    closing: sv.v_mps - ego.v_mps,
                    deficit: sv_idm_distance(&config.idm, ego.v_mps, sv.v_mps, false) - (-dx - length),
                    stopping: 0.0,
                    room: 0.0,
                };
                let threat = c.closing > 0.0 || c.deficit > 0.0;
                if threat && rear.as_ref().is_none_or(|r| c.more_critical(r)) {
                    rear = Some(c);
                }
            }
        } else {
            let adjacent = lanes
                .iter()
                .any(|l| occupancy0.iter().any(|e| (i16::from(l) - i16::from(e)).abs() == 1));
            if adjacent && dx.abs() < length && lateral.is_none_or(|id| sv.id < id) {
                lateral = Some(sv.id);
            }
        }
    }
    if let Some(f) = front {
        // Behind every front threat, the most any needs: to keep the jam distance behind it,
        // and room for it to slow down.
        let needed = -hardest_need.max(f.need());
        return FallbackChoice {
            beta: -1,
            threat: Threat::Front,
            sv_id: Some(f.id),
            hardest_sv_id: hardest_id.filter(|&id| id != f.id && hardest_need > f.need()),
            ttc_s: f.ttc(),
            needed_decel_mps2: needed,
        };
    }
    if let Some(r) = rear {
        return FallbackChoice {
            beta: 1,
            threat: Threat::Rear,
            sv_id: Some(r.id),
            hardest_sv_id: None,
            ttc_s: r.ttc(),
            needed_decel_mps2: 0.0,
        };
    }
    if let Some(b) = band {
        return FallbackChoice {
            beta: -1,
            threat: Threat::Band,
            sv_id: Some(b.id),
            hardest_sv_id: None,
            ttc_s: b.ttc(),
            needed_decel_mps2: config.ego.comfort_decel_mps2,
        };
    }
    FallbackChoice {
        beta: 0,
        threat: if lateral.is_some() {
            Threat::Lateral
        } else {
            Threat::None
        },
        sv_id: lateral,
        hardest_sv_id: None,
        ttc_s: f64::INFINITY,
        needed_decel_mps2: 0.0,
    }
}

/// Least braking (m/s^2, >= 0) that keeps the ego `jam_distance_m` behind an SV `gap_m` ahead
/// should it brake at `ego.lead_brake_room_mps2` to a standstill from now. An SV braking
/// already is `stopping`'s (`BrakingEnds::needed_decel`, with the end its braking explains).
fn lead_brake_room(config: &PlannerConfig, gap_m: f64, v_ego: f64, v_sv: f64) -> f64 {
    let room = config.ego.lead_brake_room_mps2;
    if room <= 0.0 {
        return 0.0;
    }
    stopping_decel(gap_m, config.idm.jam_distance_m, v_ego, v_sv, -room, 0.0)
}

/// The fallback's acceleration: the state's representative one, braking harder when the front
/// threat needs it (beyond the range of `beta = -1`, down to `emergency_decel_mps2`: staying
/// behind an SV ahead is what the vehicle's brakes are for, and stopping short at the planned
/// range would be a collision chosen), and as hard as the choice says (within that range) for
/// an SV inside its band.
pub fn acceleration(kin: &Kinematics, choice: &FallbackChoice, emergency_decel_mps2: f64) -> f64 {
    let (lo, hi) = kin.bounds_of(choice.beta);
    let nominal = kin.accel_of(choice.beta).clamp(lo, hi);
    match choice.threat {
        Threat::Front => nominal
            .min(choice.needed_decel_mps2)
            .clamp(emergency_decel_mps2.min(lo), hi),
        Threat::Band => choice.needed_decel_mps2.clamp(lo, hi),
        _ => nominal,
    }
}

/// Whether `choice` is an SV ahead that only braking beyond the MPC's range (`beta = -1`'s)
/// keeps the ego behind, with the vehicle able to brake harder (`emergency_decel_mps2`).
pub fn needs_emergency_braking(config: &PlannerConfig, kin: &Kinematics, choice: &FallbackChoice) -> bool {
    let planned = kin.bounds_of(-1).0;
    choice.threat == Threat::Front && choice.needed_decel_mps2 < planned && config.ego.emergency_decel_mps2 < planned
}

/// The fallback's target lane: the current one (a lane change under way completes), unless
/// the threat (the most critical, or the front threat that needs the most braking) occupies
/// that target lane and the ego's body is still in a lane that threat does not occupy — then
/// the change is aborted back to that lane. Completing a change into the lane of the SV the
/// fallback is reacting to is how two vehicles merging into the same lane from both sides
/// collide.
pub fn lateral_target(config: &PlannerConfig, s: &Situation, choice: &FallbackChoice) -> u8 {
    let target = s.ego.maneuver.lane;
    let tol = config.vehicle.lane_centre_tolerance_m;
    // An SV inside its band is beyond its IDM distance: braking is enough, the change stays.
    if choice.threat == Threat::Band {
        return target;
    }
    let Ok(body) = lanes_at(&s.road, s.ego.y_m, tol) else {
        return target;
    };
    for id in [choice.sv_id, choice.hardest_sv_id].into_iter().flatten() {
        let Some(sv) = s.svs.iter().find(|sv| sv.id == id) else {
            continue;
        };
        let Ok(threat) = lanes_at(&s.road, sv.y_m, tol) else {
            continue;
        };
        if !threat.contains(target) {
            continue;
        }
        if let Some(back) = body.iter().find(|&l| l != target && !threat.contains(l)) {
            return back;
        }
    }
    target
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::{EgoState, Maneuver, PlannerMemory, Road, SvObservation};

    fn situation(svs: Vec<SvObservation>) -> Situation {
        Situation {
            road: Road {
                lanes: 3,
                lane_width_m: 4.0,
                speed_limit_mps: 40.0,
            },
            ego: EgoState {
                x_m: 100.0,
                y_m: 4.0,
                v_mps: 20.0,
                desired_speed_mps: 25.0,
                maneuver: Maneuver { lane: 2, beta: 0 },
            },
            svs,
            memory: PlannerMemory::default(),
        }
    }

    fn sv(id: u32, x: f64, y: f64, v: f64) -> SvObservation {
        SvObservation::new(id, x, y, v, 0.0)
    }

    #[test]
    fn front_closing_brakes() {
        let c = PlannerConfig::default();
        // Gap 15 m, closing 5 m/s: TTC 3 s. Rear SV: gap 25 m, closing 2 m/s: TTC 12.5 s.
        let s = situation(vec![sv(1, 120.0, 4.0, 15.0), sv(2, 70.0, 4.0, 22.0)]);
        // Needed: 25 / (2 * 13) = 0.96 m/s^2, below the representative -3.
        let f = choose(&c, &s, LaneSet::single(2), &[]);
        assert_eq!((f.beta, f.threat, f.sv_id), (-1, Threat::Front, Some(1)));
        assert!((f.ttc_s - 3.0).abs() < 1e-12);
    }

    #[test]
    fn a_front_sv_braking_hard_beyond_its_idm_distance_brakes_as_hard_as_staying_behind_takes() {
        let c = PlannerConfig::default();
        // Gap 55 m at equal speed (outside the IDM distance of about 22 m), the leader braking
        // at 6 m/s^2: stopping behind it within 53 m + its 33.3 m takes 400 / 172.7 = 2.32 m/s^2.
        let braking = SvObservation::new(1, 160.0, 4.0, 20.0, -6.0);
        let f = choose(&c, &situation(vec![braking]), LaneSet::single(2), &[]);
        assert_eq!((f.beta, f.threat, f.sv_id), (-1, Threat::Front, Some(1)));
        assert!(
            (f.needed_decel_mps2 + 400.0 / (2.0 * (53.0 + 400.0 / 12.0))).abs() < 1e-6,
            "{f:?}"
        );
        // Slowing gently is not a threat: staying behind takes less than comfortable braking.
        let gentle = SvObservation::new(1, 160.0, 4.0, 20.0, -0.5);
        let f = choose(&c, &situation(vec![gentle]), LaneSet::single(2), &[]);
        assert_eq!(f.threat, Threat::None, "{f:?}");
    }

    #[test]
    fn a_front_threat_beyond_the_planned_range_gets_the_emergency_braking_it_needs() {
        // The closing alone (the room for the SV's braking: the next test).
        let mut c = PlannerConfig::default();
        c.ego.lead_brake_room_mps2 = 0.0;
        let kin = Kinematics::new(&c);
        // Gap 24 m, the ego at 26 m/s and the SV at 8 m/s: keeping the 2 m jam distance takes
        // 18^2 / (2 * 22) = 7.36 m/s^2, beyond the planned -6.
        let s = |gap_m: f64, v_sv: f64| {
            let mut s = situation(vec![sv(1, 100.0 + gap_m + c.vehicle.length_m, 4.0, v_sv)]);
            s.ego.v_mps = 26.0;
            s
        };
        let f = choose(&c, &s(24.0, 8.0), LaneSet::single(2), &[]);
        assert_eq!(f.threat, Threat::Front);
        let needed = -(18.0_f64.powi(2)) / (2.0 * 22.0);
        assert!((f.needed_decel_mps2 - needed).abs() < 1e-9, "{f:?}");
        assert!((acceleration(&kin, &f, c.ego.emergency_decel_mps2) - needed).abs() < 1e-9);
        // Needing more than the vehicle has: all of it.
        let f = choose(&c, &s(8.0, 0.0), LaneSet::single(2), &[]);
        assert_eq!(
            acceleration(&kin, &f, c.ego.emergency_decel_mps2),
            c.ego.emergency_decel_mps2
        );
        // With the emergency braking at the planned range's end, no harder than the MPC may.
        assert_eq!(acceleration(&kin, &f, c.ego.max_decel_mps2), c.ego.max_decel_mps2);
        // Within the planned range it is what is needed, whatever the emergency braking: 18 m
        // behind an SV at 14 m/s, 12^2 / (2 * 16) = 4.5 m/s^2.
        let f = choose(&c, &s(18.0, 14.0), LaneSet::single(2), &[]);
        assert_eq!(f.threat, Threat::Front);
        assert!(!needs_emergency_braking(&c, &kin, &f));
        let a = acceleration(&kin, &f, c.ego.emergency_decel_mps2);
        assert!((a + 4.5).abs() < 1e-9, "{a} {f:?}");
    }

    #[test]
    fn the_room_for_an_sv_ahead_braking_is_the_stop_behind_its_stop() {
        let c = PlannerConfig::default();
        let room = c.ego.lead_brake_room_mps2;
        assert_eq!(room, 3.0);
        // The ego at 30 m/s 60 m behind an SV at 8 m/s: the SV would stop within 64 / 6 m, and
        // the ego, faster until it stops, within 58 m beyond that.
        let closed_form = 900.0 / (2.0 * (58.0 + 64.0 / 6.0));
        assert!((lead_brake_room(&c, 60.0, 30.0, 8.0) - closed_form).abs() < 1e-6);
        // Behind an SV at the ego's speed, never more than the room itself.
        for gap in [3.0, 10.0, 30.0, 60.0] {
            let d = lead_brake_room(&c, gap, 30.0, 30.0);
            assert!(d > 0.0 && d <= room + 1e-9, "{gap} m: {d}");
        }
        // Off: none; and as Layer B's need, 7 m/s^2 > 6 is an emergency.
        let mut off = c.clone();
        off.ego.lead_brake_room_mps2 = 0.0;
        assert_eq!(lead_brake_room(&off, 60.0, 30.0, 8.0), 0.0);
        let mut s = situation(vec![sv(1, 100.0 + 50.0 + c.vehicle.length_m, 4.0, 8.0)]);
        s.ego.v_mps = 30.0;
        let kin = Kinematics::new(&c);
        let f = choose(&c, &s, LaneSet::single(2), &[]);
        let need = 900.0 / (2.0 * (48.0 + 64.0 / 6.0));
        assert!((f.needed_decel_mps2 + need).abs() < 1e-6, "{f:?}");
        assert!(needs_emergency_braking(&c, &kin, &f));
        assert!(!needs_emergency_braking(
            &off,
            &kin,
            &choose(&off, &s, LaneSet::single(2), &[])
        ));
    }

    #[test]
    fn the_braking_is_for_the_front_threat_that_needs_the_most() {
        let mut c = PlannerConfig::default();
        c.ego.lead_brake_room_mps2 = 0.0;
        let kin = Kinematics::new(&c);
        // Changing from lane 3 into lane 2 (y = 0.05, both lanes occupied). In lane 3, 15 m
        // ahead and closing at 5 m/s: TTC 3 s, 25 / 26 = 0.96 m/s^2 keeps the jam distance.
        // In lane 2, 40 m ahead and closing at 13 m/s: TTC 3.1 s, 169 / 76 = 2.2 m/s^2.
        let mut s = situation(vec![
            sv(1, 100.0 + 15.0 + c.vehicle.length_m, 0.0, 15.0),
            sv(2, 100.0 + 40.0 + c.vehicle.length_m, 4.0, 7.0),
        ]);
        s.ego.y_m = 0.05;
        let f = choose(&c, &s, LaneSet::single(2).with(3), &[]);
        assert_eq!((f.threat, f.sv_id), (Threat::Front, Some(1)));
        assert!((f.needed_decel_mps2 + 169.0 / 76.0).abs() < 1e-9, "{f:?}");
        assert!((acceleration(&kin, &f, c.ego.emergency_decel_mps2) - kin.accel_of(-1)).abs() < 1e-12);
        assert_eq!(f.hardest_sv_id, Some(2));
        // The ego heads for lane 2, where the SV that needs the most braking is: the change is
        // aborted back to lane 3, although the most critical SV is in lane 3.
        s.ego.maneuver.lane = 2;
        assert_eq!(lateral_target(&c, &s, &f), 3);
        // 10 m closer, lane 2's SV needs 169 / 56 = 3.02 m/s^2, more than the state's 3.
        s.svs[1].x_m -= 10.0;
        let f = choose(&c, &s, LaneSet::single(2).with(3), &[]);
        assert!(
            (acceleration(&kin, &f, c.ego.emergency_decel_mps2) + 169.0 / 56.0).abs() < 1e-9,
            "{f:?}"
        );
    }

    #[test]
    fn the_room_can_make_another_sv_the_one_that_needs_the_most_and_abort_a_change() {
        let c = PlannerConfig::default();
        // Changing from lane 3 into lane 2 (both occupied). In lane 3, 20 m ahead at 19 m/s:
        // the most critical (TTC 20 s), inside its IDM distance, with almost nothing to brake
        // for. In lane 2, 5 m ahead at the ego's 20 m/s: never closing, inside its IDM
        // distance, and the one that leaves the least room should it brake at 3 m/s^2.
        let mut s = situation(vec![
            sv(1, 100.0 + 20.0 + c.vehicle.length_m, 0.0, 19.0),
            sv(2, 100.0 + 5.0 + c.vehicle.length_m, 4.0, 20.0),
        ]);
        s.ego.y_m = 0.05;
        s.ego.maneuver.lane = 2;
        let f = choose(&c, &s, LaneSet::single(2).with(3), &[]);
        assert_eq!(
            (f.threat, f.sv_id, f.hardest_sv_id),
            (Threat::Front, Some(1), Some(2)),
            "{f:?}"
        );
        // Both at 20 m/s, the ego braking at d < 3 stops last: 5 + 400 / 6 - 400 / (2 d) = 2.
        let room = 200.0 / (5.0 - 2.0 + 400.0 / 6.0);
        assert!((f.needed_decel_mps2 + room).abs() < 1e-6, "{f:?}");
        // Lane 2's SV decides: the change is aborted back to lane 3.
        assert_eq!(lateral_target(&c, &s, &f), 3);
        // Without the room lane 3's SV needs the most (a little, to keep its jam distance),
        // and the change into lane 2 goes on.
        let mut no_room = c.clone();
        no_room.ego.lead_brake_room_mps2 = 0.0;
        let f = choose(&no_room, &s, LaneSet::single(2).with(3), &[]);
        assert_eq!((f.sv_id, f.hardest_sv_id), (Some(1), None), "{f:?}");
        assert_eq!(lateral_target(&no_room, &s, &f), 2);
    }

    #[test]
    fn rear_closing_faster_accelerates() {
        let c = PlannerConfig::default();
        // Front: gap 45, closing 1 -> 45 s. Rear: gap 10, closing 10 -> 1 s.
        let s = situation(vec![sv(1, 150.0, 4.0, 19.0), sv(2, 85.0, 4.0, 30.0)]);
        let f = choose(&c, &s, LaneSet::single(2), &[]);
        assert_eq!((f.beta, f.threat, f.sv_id), (1, Threat::Rear, Some(2)));
        assert!((f.ttc_s - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_front_sv_inside_its_idm_distance_brakes_even_when_not_closing() {
        let c = PlannerConfig::default();
        // Gap 15 m at equal speed (20 m/s): IDM distance 32 m, no TTC.
        let s = situation(vec![sv(3, 120.0, 4.0, 20.0)]);
        let f = choose(&c, &s, LaneSet::single(2), &[]);
        assert_eq!((f.beta, f.threat, f.sv_id), (-1, Threat::Front, Some(3)));
        assert!(f.ttc_s.is_infinite());
        // Beyond its IDM distance it is no threat.
        let s = situation(vec![sv(3, 140.0, 4.0, 20.0)]);
        assert_eq!(choose(&c, &s, LaneSet::single(2), &[]).threat, Threat::None);
    }

    #[test]
    fn a_corrective_front_sv_inside_its_band_brakes_unless_a_rear_sv_closes_in() {
        // The paper's band: slack bounded by d_HS.
        let mut c = PlannerConfig::default();
        c.hysteresis.soft_band = false;
        // Gap 35 m at equal speed: beyond the IDM distance (about 22 m), inside a frozen
        // trigger distance of 40 m.
        let mut s = situation(vec![sv(3, 140.0, 4.0, 20.0)]);
        assert_eq!(choose(&c, &s, LaneSet::single(2), &[]).threat, Threat::None);
        let entry = |trigger_m| CorrectiveEntry {
            sv_id: 3,
            release_m: trigger_m + 8.0,
            trigger_m,
        };
        let f = choose(&c, &s, LaneSet::single(2), &[entry(40.0)]);
        assert_eq!((f.beta, f.threat, f.sv_id), (-1, Threat::Band, Some(3)));
        // Comfortable braking where the state allows it; the state's one deceleration where
        // it is fixed (the paper-literal preset).
        let kin = Kinematics::new(&c);
        assert_eq!(
            acceleration(&kin, &f, c.ego.emergency_decel_mps2),
            c.ego.comfort_decel_mps2
        );
        let mut fixed = c.clone();
        fixed.ego.continuous_accel = false;
        assert_eq!(
            acceleration(&Kinematics::new(&fixed), &f, fixed.ego.emergency_decel_mps2),
            fixed.ego.decel_mps2
        );
        // Beyond the trigger distance the band's slack reaches: no threat.
        assert_eq!(choose(&c, &s, LaneSet::single(2), &[entry(30.0)]).threat, Threat::None);
        // With the soft band, following inside the trigger distance is no threat at all (a
        // watchdog's fallback must not brake for it).
        let soft = PlannerConfig::default();
        assert_eq!(
            choose(&soft, &s, LaneSet::single(2), &[entry(40.0)]).threat,
            Threat::None
        );
        // A lane change under way is kept: the SV is beyond its IDM distance.
        let mut changing = s.clone();
        changing.ego.y_m = 0.05;
        let f = choose(&c, &changing, LaneSet::single(2).with(3), &[entry(40.0)]);
        assert_eq!((f.threat, lateral_target(&c, &changing, &f)), (Threat::Band, 2));
        // An SV closing in from behind outranks it: the band is no hard row.
        s.svs.push(sv(2, 85.0, 4.0, 30.0));
        let f = choose(&c, &s, LaneSet::single(2), &[entry(40.0)]);
        assert_eq!((f.beta, f.threat, f.sv_id), (1, Threat::Rear, Some(2)));
    }

    #[test]
    fn lateral_alongside_holds_speed() {
        let c = PlannerConfig::default();
        // Alongside in lane 1 (y = 8), nothing closing in lane 2.
        let s = situation(vec![sv(4, 102.0, 8.0, 20.0), sv(5, 160.0, 4.0, 25.0)]);
        let f = choose(&c, &s, LaneSet::single(2), &[]);
        assert_eq!((f.beta, f.threat, f.sv_id), (0, Threat::Lateral, Some(4)));
    }

    #[test]
    fn a_lane_change_into_the_threat_lane_is_aborted() {
        let c = PlannerConfig::default();
        // Ego still in lane 3 (y = 0.05) but heading for lane 2; an SV drifting from lane 1
        // into lane 2 (y = 4.6) just 2 m ahead: brake and go back to lane 3.
        let mut s = situation(vec![sv(8, 102.0, 4.6, 19.0)]);
        s.ego.y_m = 0.05;
        s.ego.maneuver.lane = 2;
        let f = choose(&c, &s, LaneSet::single(2).with(3), &[]);
        assert_eq!((f.beta, f.threat, f.sv_id), (-1, Threat::Front, Some(8)));
        assert_eq!(lateral_target(&c, &s, &f), 3);
        // Without the ego's change under way there is nothing to abort.
        let mut keep = s.clone();
        keep.ego.y_m = 4.0;
        assert_eq!(lateral_target(&c, &keep, &f), 2);
    }

    #[test]
    fn nothing_holds_speed() {
        let c = PlannerConfig::default();
        let f = choose(&c, &situation(vec![sv(1, 400.0, 4.0, 1.0)]), LaneSet::single(2), &[]);
        assert_eq!((f.beta, f.threat, f.sv_id), (0, Threat::None, None));
    }

    #[test]
    fn an_sv_between_lanes_counts_in_both() {
        let c = PlannerConfig::default();
        // y = 6 lies between lanes 1 and 2; it shares lane 2 with the ego and is closing.
        let s = situation(vec![sv(9, 115.0, 6.0, 10.0)]);
        let f = choose(&c, &s, LaneSet::single(2), &[]);
        assert_eq!((f.beta, f.threat), (-1, Threat::Front));
    }
}
