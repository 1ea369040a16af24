//! Lane occupancy at the planner level: a lane change in progress makes the ego occupy both
//! lanes (with `ego.plan_occupancy = "held_through_change"`, the default), and an SV between
//! lane centres occupies both of its lanes. The paper's occupancy (`"target_lane"`) against it
//! on one decision.

use decision::{
    EgoState, Layer, Maneuver, PlanOccupancy, Planner, PlannerConfig, PlannerMemory, Road, Situation, SvObservation,
};

fn situation(ego_y: f64, target: u8, sv_y: f64) -> Situation {
    Situation {
        road: Road {
            lanes: 2,
            lane_width_m: 4.0,
            speed_limit_mps: 30.0,
        },
        ego: EgoState {
            x_m: 0.0,
            y_m: ego_y,
            v_mps: 20.0,
            desired_speed_mps: 20.0,
            maneuver: Maneuver { lane: target, beta: 0 },
        },
        // 15 m ahead at the same speed: far inside the IDM distance (~32 m).
        svs: vec![SvObservation::new(1, 20.0, sv_y, 20.0, 0.0)],
        memory: PlannerMemory::default(),
    }
}

fn decide(s: &Situation) -> decision::Decision {
    Planner::new(PlannerConfig::default()).unwrap().decide(s).unwrap()
}

#[test]
fn an_sv_in_the_other_lane_does_not_constrain_a_lane_keeping_ego() {
    // Ego in lane 2 (y = 0), SV in lane 1 (y = 4): nothing to do, cruise at the desired speed.
    let d = decide(&situation(0.0, 2, 4.0));
    assert_eq!(d.layer, Layer::Nominal);
    assert_eq!(d.next_maneuver, Maneuver { lane: 2, beta: 0 });
    assert!(d.stats.cost.unwrap().abs() < 1e-9, "{:?}", d.stats.cost);
}

#[test]
fn a_lane_change_under_way_makes_the_other_lane_binding() {
    // Same SV, but the ego is half-way to lane 1: it occupies both lanes and is far too close.
    let d = decide(&situation(2.0, 1, 4.0));
    assert_eq!(d.next_maneuver.beta, -1, "the ego must back off: {d:?}");
    assert!(d.setpoint.accel_mps2 < -0.3, "{d:?}");
}

#[test]
fn an_sv_between_lanes_occupies_both() {
    // The SV drifts half-way into the ego's lane (y = 2): it shares lane 2 with the ego.
    let d = decide(&situation(0.0, 2, 2.0));
    assert_eq!(d.next_maneuver.beta, -1, "{d:?}");
    assert!(d.setpoint.accel_mps2 < -0.3, "{d:?}");
}

/// The paper-literal preset behind a leader deep in its hysteresis band (20 m/s, 65 m behind
/// one holding 15 m/s: beyond the IDM distance, inside the trigger distance), lane 1 empty.
fn deep_in_the_band(plan_occupancy: PlanOccupancy) -> decision::Decision {
    let mut config = PlannerConfig::from_toml_str(include_str!("../../deploy/paper.toml")).unwrap();
    config.ego.plan_occupancy = plan_occupancy;
    let mut s = situation(0.0, 2, 0.0);
    s.ego.desired_speed_mps = 25.0;
    s.svs = vec![SvObservation::new(1, 70.0, 0.0, 15.0, 0.0)];
    Planner::new(config).unwrap().decide(&s).unwrap()
}

#[test]
fn with_the_papers_alpha_a_lane_change_escapes_the_band_at_once() {
    // As formulation.md has it, the origin lane stays occupied to the horizon's end: the band
    // row (gap >= d_trig at every step) leaves no plan, whatever the lane.
    let held = deep_in_the_band(PlanOccupancy::HeldThroughChange);
    assert_eq!(held.layer, Layer::Fallback, "{held:?}");
    // The paper's alpha: one step after the change begins the ego is in lane 1 alone, so the
    // nominal MPC answers with the change (docs/paper-literal.md, "The lane a plan occupies").
    let target = deep_in_the_band(PlanOccupancy::TargetLane);
    assert_eq!(target.layer, Layer::Nominal, "{target:?}");
    assert_eq!(target.next_maneuver.lane, 1, "{target:?}");
}
