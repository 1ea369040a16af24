//! Bad input gets a typed error, never a panic; good input always gets a decision.

use decision::corpus::{paper_classes, SituationGenerator};
use decision::{Action, CorrectiveEntry, DecisionError, InputError, Planner, PlannerConfig, Situation};
use proptest::prelude::*;

fn base(seed: u64, class: usize) -> Situation {
    let classes = paper_classes();
    SituationGenerator::new(seed).situation(&PlannerConfig::default(), &classes[class % classes.len()])
}

fn input_error(planner: &mut Planner, s: &Situation) -> InputError {
    match planner.decide(s) {
        Err(DecisionError::Input(e)) => e,
        other => panic!("expected an input error, got {other:?}"),
    }
}

fn bad_number() -> impl Strategy<Value = f64> {
    prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY)]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    #[test]
    fn non_finite_numbers_are_rejected(seed in 0u64..1000, class in 0usize..18, field in 0usize..9, value in bad_number()) {
        let mut s = base(seed, class);
        match field {
            0 => s.ego.x_m = value,
            1 => s.ego.y_m = value,
            2 => s.ego.v_mps = value,
            3 => s.ego.desired_speed_mps = value,
            4 => s.road.speed_limit_mps = value,
            5 => s.road.lane_width_m = value,
            6 => s.svs[0].x_m = value,
            7 => s.svs[0].v_mps = value,
            _ => s.svs[0].a_mps2 = value,
        }
        let mut p = Planner::new(PlannerConfig::default()).unwrap();
        let e = input_error(&mut p, &s);
        prop_assert!(matches!(e, InputError::NonFinite { .. }), "{e:?}");
    }

    #[test]
    fn negative_speeds_are_rejected(seed in 0u64..1000, v in -1e6f64..-1e-9, which in 0usize..3) {
        let mut s = base(seed, 4);
        match which {
            0 => s.ego.v_mps = v,
            1 => s.ego.desired_speed_mps = v,
            _ => s.svs[0].v_mps = v,
        }
        let mut p = Planner::new(PlannerConfig::default()).unwrap();
        let e = input_error(&mut p, &s);
        prop_assert!(matches!(e, InputError::NegativeSpeed { .. }), "{:?}", e);
    }

    #[test]
    fn lanes_off_the_road_are_rejected(seed in 0u64..1000, class in 0usize..18, lane in prop_oneof![Just(0u8), 5u8..=255], y_beyond_edge in 0.01f64..1e5) {
        let mut s = base(seed, class);
        let lanes = s.road.lanes;
        let mut p = Planner::new(PlannerConfig::default()).unwrap();
        let mut ego_lane = s.clone();
        ego_lane.ego.maneuver.lane = if lane == 0 { 0 } else { lanes + lane % (255 - lanes) + 1 };
        let e = input_error(&mut p, &ego_lane);
        prop_assert!(matches!(e, InputError::LaneOutOfRange { .. }), "{:?}", e);
        // An SV beyond the road edge (half a lane beyond the outermost lane centre) by more
        // than the tolerance of a measurement.
        let y_off = s.road.lane_width_m / 2.0 + decision::ROAD_EDGE_TOLERANCE_M + y_beyond_edge;
        s.svs[0].y_m = if seed % 2 == 0 { -y_off } else { f64::from(lanes - 1) * s.road.lane_width_m + y_off };
        let e = input_error(&mut p, &s);
        prop_assert!(matches!(e, InputError::LaneOutOfRange { .. }), "{:?}", e);
    }

    #[test]
    fn duplicate_ids_and_too_many_svs_are_rejected(seed in 0u64..1000, extra in 1usize..40) {
        let mut s = base(seed, 17);
        let mut p = Planner::new(PlannerConfig::default()).unwrap();
        let mut dup = s.clone();
        dup.svs[1].id = dup.svs[0].id;
        prop_assert_eq!(input_error(&mut p, &dup), InputError::DuplicateSvId { id: s.svs[0].id });
        let template = s.svs[0];
        for k in 0..(decision::MAX_INPUT_SVS - s.svs.len() + extra) {
            let mut sv = template;
            sv.id = 10_000 + k as u32;
            sv.x_m += 1000.0 + 10.0 * k as f64;
            s.svs.push(sv);
        }
        let count = s.svs.len();
        prop_assert_eq!(input_error(&mut p, &s), InputError::TooManyVehicles { count, capacity: decision::MAX_INPUT_SVS });
    }

    #[test]
    fn any_numbers_never_panic(seed in 0u64..1000, class in 0usize..18, values in proptest::collection::vec(any::<f64>(), 8), beta in any::<i8>()) {
        let mut s = base(seed, class);
        s.ego.x_m = values[0];
        s.ego.v_mps = values[1];
        s.svs[0].x_m = values[2];
        s.svs[0].y_m = values[3];
        s.svs[0].a_mps2 = values[4];
        s.road.lane_width_m = values[5];
        s.ego.maneuver.beta = beta;
        s.memory.corrective.push(CorrectiveEntry { sv_id: s.svs[0].id, release_m: values[6], trigger_m: values[7] });
        s.memory.previous_plan = vec![Action { lateral: beta, longitudinal: 0 }];
        let mut p = Planner::new(PlannerConfig::default()).unwrap();
        let _ = p.decide(&s);
    }

    #[test]
    fn valid_situations_always_get_a_decision(seed in 0u64..100_000, class in 0usize..18) {
        let s = base(seed, class);
        let mut p = Planner::new(PlannerConfig::default()).unwrap();
        let d = p.decide(&s).unwrap();
        prop_assert_eq!(d.plan.len(), 3);
        prop_assert_eq!(d.plan[0].maneuver, d.next_maneuver);
        prop_assert!(d.next_maneuver.lane >= 1 && d.next_maneuver.lane <= s.road.lanes);
    }
}

#[test]
fn memory_with_release_below_trigger_is_rejected() {
    let mut s = base(1, 3);
    s.memory.corrective.push(CorrectiveEntry {
        sv_id: s.svs[0].id,
        release_m: 10.0,
        trigger_m: 20.0,
    });
    let mut p = Planner::new(PlannerConfig::default()).unwrap();
    assert!(matches!(input_error(&mut p, &s), InputError::InvalidMemory { .. }));
}

#[test]
fn beta_out_of_range_is_rejected() {
    let mut s = base(2, 3);
    s.ego.maneuver.beta = 2;
    let mut p = Planner::new(PlannerConfig::default()).unwrap();
    assert_eq!(
        input_error(&mut p, &s),
        InputError::BetaOutOfRange {
            field: "ego.maneuver.beta",
            beta: 2
        }
    );
}
