//! Inputs found by the protocol fuzzer (`protocol/fuzz`, target `decide_valid`), minimised:
//! the decision core must refuse them with a typed error, never panic, and its decisions must
//! fit the protocol.

use decision::{
    fallback_only, Backend, DecisionError, EgoState, InputError, Maneuver, Planner, PlannerConfig, Road, ValidSituation,
};
use decision::{PlannerMemory, Situation};

fn situation(lane_width_m: f64, ego_y_m: f64) -> Situation {
    Situation {
        road: Road {
            lanes: 3,
            lane_width_m,
            speed_limit_mps: 30.0,
        },
        ego: EgoState {
            x_m: 0.0,
            y_m: ego_y_m,
            v_mps: 25.0,
            desired_speed_mps: 28.0,
            maneuver: Maneuver { lane: 2, beta: 0 },
        },
        svs: Vec::new(),
        memory: PlannerMemory::default(),
    }
}

fn enumeration() -> Planner {
    let mut config = PlannerConfig::default();
    config.solver.backend = Backend::Enumeration;
    Planner::new(config).unwrap()
}

/// The fallback of a situation the input checks accept.
fn valid_fallback(s: &decision::Situation) -> Result<decision::Decision, DecisionError> {
    let config = PlannerConfig::default();
    Ok(fallback_only(&config, &ValidSituation::new(&config, s)?))
}

/// A lane width just above zero used to pass the range check, and a lateral position a
/// little below zero was then more than 2^63 lanes off the road: `nearest_lane` rounded it to
/// `i64::MAX` and added 1, which overflowed. Such widths are now refused, and a position
/// far off a normal road is a typed error (lane arithmetic also saturates now).
#[test]
fn lateral_position_far_off_a_very_narrow_road_is_a_typed_error() {
    for (width, y) in [(1.0e-300, -1.0), (f64::MIN_POSITIVE, -1.0e-290), (1.0e-19, -1.0)] {
        let s = situation(width, y);
        let refused = |r: &Result<decision::Decision, DecisionError>| matches!(r, Err(DecisionError::Input(e)) if e.to_string().contains("road.lane_width_m"));
        let decided = enumeration().decide(&s);
        assert!(refused(&decided), "width {width}: {decided:?}");
        let fallback = valid_fallback(&s);
        assert!(refused(&fallback), "width {width}: {fallback:?}");
    }
    for (width, y) in [(1.0, -9.0e6), (1.0, 9.9e6), (20.0, -9.9e6)] {
        let s = situation(width, y);
        let expected = |r: &Result<decision::Decision, DecisionError>| {
            matches!(
                r,
                Err(DecisionError::Input(InputError::LaneOutOfRange {
                    field: "ego.y_m",
                    ..
                }))
            )
        };
        let decided = enumeration().decide(&s);
        assert!(expected(&decided), "width {width}, y {y}: {decided:?}");
        let fallback = valid_fallback(&s);
        assert!(expected(&fallback), "width {width}, y {y}: {fallback:?}");
    }
}

/// The fallback's first action is `choice.beta - start.beta` (`planner::fallback_decision`):
/// from accelerating (`beta = 1`) straight to braking for a front threat it is -2, outside the
/// action set `-1..=1` — the protocol's `PlanResponse::validate` then refuses the response the
/// planner (and the service's watchdog) sends. Found as a planner decision of layer Fallback.
#[test]
fn fallback_from_accelerating_to_braking_is_a_valid_action() {
    // Minimised from the fuzzer: accelerating in lane 2, a stopped SV 15 m ahead.
    let mut s = situation(3.5, 3.5);
    s.ego.v_mps = 15.0;
    s.ego.desired_speed_mps = 15.0;
    s.ego.maneuver.beta = 1;
    s.svs.push(decision::SvObservation::new(3, 15.0, 3.5, 0.0, 0.0));
    let d = valid_fallback(&s).unwrap();
    assert_eq!(d.next_maneuver.beta, -1, "the fallback brakes: {d:?}");
    let unit = |a: decision::Action| (-1..=1).contains(&a.lateral) && (-1..=1).contains(&a.longitudinal);
    assert!(unit(d.action), "{d:?}");
    assert!(d.plan.iter().all(|step| unit(step.action)), "{d:?}");
}
