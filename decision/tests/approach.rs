//! Closing in on a slower leader from far (`idm.comfort_decel_mps2`, the IDM's `b`): the
//! dynamic term `v dv / (2 sqrt(a b))` of the IDM distance budgets the braking that matches
//! the leader's speed. With formulation.md's `b = 2` the ego at 33 m/s starts braking for a
//! 25 m/s leader 105-120 m back (bumpers), where matching its speed at the gap it follows at
//! needs about 0.5 m/s^2; with the shipped `b = 3` (the ego's decelerating state) it brakes
//! 9-46 m later, still comfortably, and never closer than the least time headway.

mod common;

use common::{ClosedLoop, Vehicle, LENGTH_M};
use decision::PlannerConfig;

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

/// One lane ([`ClosedLoop`], 30 s): the ego at 33 m/s, a leader `gap0` m ahead (bumpers) at
/// 25 m/s; from `leader_accel_from_s` on (if any) the leader speeds up at 1 m/s^2 to 31 m/s.
fn approach(config: &PlannerConfig, gap0: f64, leader_accel_from_s: Option<f64>) -> Approach {
    let leader = Vehicle {
        x_m: gap0 + LENGTH_M,
        v_mps: 25.0,
        accel: Box::new(move |t, v| match leader_accel_from_s {
            Some(from) if t >= from && v < 31.0 => 1.0,
            _ => 0.0,
        }),
        speed_bounds: (f64::NEG_INFINITY, 31.0),
    };
    let trace = ClosedLoop {
        config: config.clone(),
        lanes: 1,
        desired_speed_mps: 33.0,
        ego_v_mps: 33.0,
        vehicles: vec![leader],
        duration_s: 30.0,
    }
    .run();
    Approach {
        first_braking_gap: trace
            .decisions
            .iter()
            .find(|d| d.accel_mps2 < -config.ego.cruise_band_mps2)
            .map(|d| d.gap_m),
        strongest_braking: trace.strongest_braking(),
        least_gap: trace.least_gap_m,
        distance: trace.ego_x_m,
        final_gap: trace.final_gap_m,
        final_speed: trace.ego_v_mps,
    }
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
