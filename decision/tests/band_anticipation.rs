//! The hysteresis band with anticipation (`hysteresis.anticipation_s`): the band row asks for
//! the release distance at today's relative speed a few seconds ahead, so an ego closing in on
//! its leader brakes early and gently, and one already falling back is not pushed to brake.

use decision::{
    CorrectiveEntry, EgoState, Layer, Maneuver, Planner, PlannerConfig, PlannerMemory, Road, Situation, SvObservation,
};

/// One lane, the ego at `v_ego` with a leader at 22 m/s `gap_m` ahead (bumper to bumper), in
/// corrective mode with the release distance frozen at `release_m`.
fn following(v_ego: f64, gap_m: f64, release_m: f64) -> Situation {
    let length = PlannerConfig::default().vehicle.length_m;
    Situation {
        road: Road {
            lanes: 1,
            lane_width_m: 3.5,
            speed_limit_mps: 33.0,
        },
        ego: EgoState {
            x_m: 0.0,
            y_m: 0.0,
            v_mps: v_ego,
            desired_speed_mps: 30.0,
            maneuver: Maneuver { lane: 1, beta: 0 },
        },
        svs: vec![SvObservation::new(1, gap_m + length, 0.0, 22.0, 0.0)],
        memory: PlannerMemory {
            corrective: vec![CorrectiveEntry {
                sv_id: 1,
                release_m,
                trigger_m: release_m - 6.0,
            }],
            previous_plan: Vec::new(),
        },
    }
}

/// The distances below are worked out for `T = 1.5` s (formulation.md's).
fn first_accel(anticipation_s: f64, s: &Situation) -> f64 {
    let mut config = PlannerConfig::default();
    config.idm.time_headway_s = 1.5;
    config.hysteresis.anticipation_s = anticipation_s;
    let d = Planner::new(config).unwrap().decide(s).unwrap();
    assert_eq!(d.layer, Layer::Nominal, "{d:?}");
    assert!(d.memory.is_corrective(1), "still following the leader: {d:?}");
    d.setpoint.accel_mps2
}

#[test]
fn an_ego_closing_in_brakes_earlier_with_anticipation() {
    // 2 m/s faster than the leader, 2 m beyond the release distance of 70 m and well beyond
    // its IDM distance (about 52 m): the plain band is met for most of the 1.2 s horizon, the
    // anticipated one (4 m of closing) is not.
    let s = following(24.0, 72.0, 70.0);
    let plain = first_accel(0.0, &s);
    let anticipated = first_accel(2.0, &s);
    assert!(anticipated < plain - 0.1, "anticipated {anticipated}, plain {plain}");
    assert!(anticipated < -0.3, "brakes now: {anticipated}");
    assert!(
        anticipated >= PlannerConfig::default().ego.comfort_decel_mps2 - 1e-9,
        "gently: {anticipated}"
    );
}

#[test]
fn an_ego_falling_back_is_not_pushed_to_brake() {
    // 2 m/s slower than the leader, 2 m inside the release distance: the gap opens by 4 m
    // within the anticipation time, so the band asks for nothing more.
    let s = following(20.0, 38.0, 40.0);
    let anticipated = first_accel(2.0, &s);
    assert!(anticipated > -0.3, "no braking: {anticipated}");
}
