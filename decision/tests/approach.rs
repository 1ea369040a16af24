//! Closing in on a slower leader from far (`idm.comfort_decel_mps2`, the IDM's `b`): the
//! dynamic term `v dv / (2 sqrt(a b))` of the IDM distance budgets the braking that matches
//! the leader's speed. With formulation.md's `b = 2` the ego at 33 m/s starts braking for a
//! 25 m/s leader 105-120 m back (bumpers), where matching its speed at the gap it follows at
//! needs about 0.5 m/s^2; with the shipped `b = 3` (the ego's decelerating state) it brakes
//! 9-46 m later, still comfortably, and never closer than the least time headway.

use decision::{EgoState, Maneuver, Planner, PlannerConfig, PlannerMemory, Road, Situation, SvObservation};

const LENGTH_M: f64 = 5.0;

/// What a closed loop gives: where the ego first brakes (the bumper gap then; `None`: it never
/// brakes), its strongest braking, the least bumper gap, the distance it covered, and its final
/// gap and speed.
#[derive(Debug)]
struct Approach {
    first_braking_gap: Option<f64>,
    strongest_braking: f64,
    least_gap: f64,
    distance: f64,
    final_gap: f64,
    final_speed: f64,
}

/// One lane: the ego at 33 m/s, a leader `gap0` m ahead (bumpers) at 25 m/s; from
/// `leader_accel_from_s` on (if any) the leader speeds up at 1 m/s^2 to 31 m/s. The ego applies
/// each answer's set-point for 0.4 s; all is integrated at 50 ms for 30 s.
fn approach(config: &PlannerConfig, gap0: f64, leader_accel_from_s: Option<f64>) -> Approach {
    let mut planner = Planner::new(config.clone()).unwrap();
    let dt = 0.05;
    let (mut x_ego, mut v_ego) = (0.0, 33.0);
    let (mut x_lead, mut v_lead, mut a_lead) = (gap0 + LENGTH_M, 25.0, 0.0);
    let (mut memory, mut beta, mut accel) = (PlannerMemory::default(), 0, 0.0);
    let mut out = Approach {
        first_braking_gap: None,
        strongest_braking: 0.0,
        least_gap: f64::INFINITY,
        distance: 0.0,
        final_gap: 0.0,
        final_speed: 0.0,
    };
    for step in 0..600 {
        if step % 8 == 0 {
            let s = Situation {
                road: Road {
                    lanes: 1,
                    lane_width_m: 3.5,
                    speed_limit_mps: 33.33,
                },
                ego: EgoState {
                    x_m: x_ego,
                    y_m: 0.0,
                    v_mps: v_ego,
                    desired_speed_mps: 33.0,
                    maneuver: Maneuver { lane: 1, beta },
                },
                svs: vec![SvObservation::new(1, x_lead, 0.0, v_lead, a_lead)],
                memory: memory.clone(),
            };
            let d = planner.decide(&s).unwrap();
            (memory, beta, accel) = (d.memory, d.next_maneuver.beta, d.setpoint.accel_mps2);
            if accel < -config.ego.cruise_band_mps2 && out.first_braking_gap.is_none() {
                out.first_braking_gap = Some(x_lead - x_ego - LENGTH_M);
            }
            out.strongest_braking = out.strongest_braking.min(accel);
        }
        let t = f64::from(step) * dt;
        a_lead = match leader_accel_from_s {
            Some(from) if t >= from && v_lead < 31.0 => 1.0,
            _ => 0.0,
        };
        v_lead = (v_lead + a_lead * dt).min(31.0);
        x_lead += v_lead * dt;
        v_ego = (v_ego + accel * dt).max(0.0);
        x_ego += v_ego * dt;
        out.least_gap = out.least_gap.min(x_lead - x_ego - LENGTH_M);
    }
    out.distance = x_ego;
    out.final_gap = x_lead - x_ego - LENGTH_M;
    out.final_speed = v_ego;
    out
}

fn with_b(b: f64) -> PlannerConfig {
    let mut c = PlannerConfig::default();
    c.idm.comfort_decel_mps2 = b;
    c
}

#[test]
fn a_slower_leader_far_ahead_is_approached_later_and_still_comfortably() {
    let config = PlannerConfig::default();
    assert_eq!(config.idm.comfort_decel_mps2, 3.0, "the shipped b");
    let floor = |v: f64| config.idm.jam_distance_m + v * config.idm.min_time_headway_s;
    for (gap0, leader_accel_from_s) in [
        (120.0, None),
        (160.0, None),
        (200.0, None),
        (120.0, Some(4.0)),
        (160.0, Some(4.0)),
    ] {
        let shipped = approach(&config, gap0, leader_accel_from_s);
        let wide = approach(&with_b(2.0), gap0, leader_accel_from_s);
        let case = format!(
            "gap {gap0} m, leader speeding up from t = {leader_accel_from_s:?} s: {shipped:?} against b = 2: {wide:?}"
        );
        // Comfortable and safe either way: no braking beyond the comfort level, never
        // inside the least time headway.
        for a in [&shipped, &wide] {
            assert!(a.strongest_braking >= config.ego.comfort_decel_mps2 - 1e-6, "{case}");
            assert!(a.least_gap >= floor(33.0), "{case}");
        }
        // The shipped b brakes closer to the leader (or not at all, where the leader speeds
        // up in time) and so covers more road; where the leader stays slower, it ends
        // following it at its speed all the same.
        let first_wide = wide.first_braking_gap.expect("b = 2 brakes for the leader");
        assert!(
            shipped.first_braking_gap.is_none_or(|first| first < first_wide - 5.0),
            "{case}"
        );
        assert!(shipped.distance > wide.distance + 1.0, "{case}");
        if leader_accel_from_s.is_none() {
            assert!((shipped.final_speed - 25.0).abs() < 1.0, "{case}");
            assert!(shipped.final_gap >= floor(25.0), "{case}");
        }
    }
}
