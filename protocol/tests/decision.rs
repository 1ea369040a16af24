//! Conversions to and from the decision core (feature `decision`, always on for the tests
//! through the crate's dev-dependency on itself).
#![cfg(feature = "decision")]

mod common;

use std::collections::HashSet;

use common::*;
use decision::{InputError, PlannerConfig};
use proptest::prelude::*;
use protocol::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn situation_round_trips_through_the_request(req in request()) {
        let situation = req.to_situation();
        let back = PlanRequest::from_situation(req.vehicle_id, req.sequence, req.timestamp_ns, &situation).unwrap();
        prop_assert_eq!(back.to_situation(), situation.clone());
        // And through the bytes.
        let decoded: PlanRequest = decode_bincode(&encode_bincode(&back)).unwrap();
        prop_assert_eq!(decoded.to_situation(), situation);
        let mut with_deadline = back;
        with_deadline.deadline_us = req.deadline_us;
        with_deadline.sent_at_ns = req.sent_at_ns;
        prop_assert_eq!(with_deadline, req);
    }
}

#[test]
fn situations_beyond_capacity_do_not_convert() {
    let mut situation = example_request().to_situation();
    situation.svs = (0..=MAX_SVS as u32)
        .map(|id| decision::SvObservation::new(id, 10.0 * f64::from(id), 3.5, 20.0, 0.0))
        .collect();
    assert!(matches!(
        PlanRequest::from_situation(1, 1, 1, &situation),
        Err(WireError::CapacityExceeded(_))
    ));
    let mut situation = example_request().to_situation();
    situation.memory.previous_plan = vec![decision::Action::KEEP; 7];
    assert!(matches!(
        PlanRequest::from_situation(1, 1, 1, &situation),
        Err(WireError::CapacityExceeded(_))
    ));
}

fn every_input_error() -> Vec<InputError> {
    vec![
        InputError::NonFinite { field: "ego.x_m" },
        InputError::OutOfRange {
            field: "sv.a_mps2",
            value: 1e3,
            min: -100.0,
            max: 100.0,
        },
        InputError::NegativeSpeed {
            field: "ego.v_mps",
            value: -1.0,
        },
        InputError::LaneCount { lanes: 0, max: 8 },
        InputError::LaneOutOfRange {
            field: "ego.maneuver.lane",
            lane: 5,
            lanes: 3,
        },
        InputError::BetaOutOfRange {
            field: "ego.maneuver.beta",
            beta: 3,
        },
        InputError::DuplicateSvId { id: 4 },
        InputError::TooManyVehicles {
            count: 17,
            capacity: 16,
        },
        InputError::InvalidMemory {
            field: "memory.corrective",
            why: "release below trigger",
        },
    ]
}

#[test]
fn input_errors_get_distinct_reasons() {
    let errors = every_input_error();
    let mut codes = HashSet::new();
    for e in &errors {
        let rejected = Rejected::from(e);
        let reason = rejected.reason().unwrap();
        assert_eq!(RejectReason::from(e), reason);
        assert!((10..30).contains(&reason.code()), "{e:?} -> {reason:?}");
        assert!(!rejected.field().is_empty(), "{e:?}");
        assert!(codes.insert(reason.code()), "{e:?} shares code {}", reason.code());
    }
    assert_eq!(codes.len(), errors.len());
    let r = Rejected::from(&InputError::NegativeSpeed {
        field: "ego.v_mps",
        value: -1.0,
    });
    assert_eq!((r.reason(), r.field()), (Ok(RejectReason::NegativeSpeed), "ego.v_mps"));
    let r = Rejected::from(&InputError::LaneOutOfRange {
        field: "sv.y_m",
        lane: 9,
        lanes: 3,
    });
    assert_eq!(r.field(), "sv.y_m");
}

#[test]
fn the_planner_rejects_through_the_protocol() {
    let mut req = example_request();
    req.ego.v_mps = -3.0;
    assert_eq!(req.check_wire(), Ok(()));
    let mut planner = decision::Planner::new(PlannerConfig::default()).unwrap();
    let err = planner.decide(&req.to_situation()).unwrap_err();
    let resp = PlanResponse::rejected(req.vehicle_id, req.sequence, Rejected::from(&err), 0);
    // `validate` gives the same rejection, with the request's ids.
    let invalid = req.clone().validate(&PlannerConfig::default()).unwrap_err();
    assert_eq!(invalid.response(), resp);
    let decoded: PlanResponse = decode_json_str(&encode_json(&resp)).unwrap();
    let rejected = decoded.outcome.as_rejected().unwrap();
    assert_eq!(rejected.reason(), Ok(RejectReason::NegativeSpeed));
    assert_eq!(rejected.field(), "ego.v_mps");
}

#[test]
fn a_decision_travels_and_its_memory_comes_back() {
    let req = example_request();
    let situation = req.to_situation();
    let mut planner = decision::Planner::new(PlannerConfig::default()).unwrap();
    let decision = planner.decide(&situation).unwrap();
    let resp = PlanResponse::from_decision(&req, &decision, 17).unwrap();
    assert_eq!((resp.vehicle_id, resp.sequence, resp.queue_us), (7, 42, 17));
    assert_eq!(resp.validate(), Ok(()));

    let decoded: PlanResponse = decode_bincode(&encode_bincode(&resp)).unwrap();
    let decided = decoded.outcome.as_decided().unwrap();
    assert_eq!(decided.layer(), Ok(Layer::from(decision.layer)));
    assert_eq!(decision::Action::from(decided.action), decision.action);
    assert_eq!(decision::Maneuver::from(decided.next_maneuver), decision.next_maneuver);
    let plan: Vec<decision::PlanStep> = decided.plan.iter().map(|&s| s.into()).collect();
    assert_eq!(plan, decision.plan);
    assert_eq!(decision::PlannerMemory::from(&decided.memory), decision.memory);
    assert_eq!(decision::SetPoint::from(decided.setpoint), decision.setpoint);

    // The next request carries the memory back.
    let mut next = req.clone();
    next.sequence += 1;
    next.memory = decided.memory.clone();
    assert_eq!(next.to_situation().memory, decision.memory);
    // The fallback layer maps too.
    let config = PlannerConfig::default();
    let fallback = decision::fallback_only(&config, &decision::ValidSituation::new(&config, &situation).unwrap());
    let decided = Decided::try_from(&fallback).unwrap();
    assert_eq!(decided.layer(), Ok(Layer::Fallback));
}

#[test]
fn layers_map_one_to_one() {
    for (core, wire) in [
        (decision::Layer::Nominal, Layer::Nominal),
        (decision::Layer::GlobalRelaxation, Layer::GlobalRelaxation),
        (decision::Layer::Fallback, Layer::Fallback),
    ] {
        assert_eq!(Layer::from(core), wire);
        assert_eq!(wire.name(), core.name());
    }
}

#[test]
fn sv_size_zero_means_unknown() {
    let mut wire = SvObservation::new(3, 10.0, 3.5, 20.0, 0.5);
    wire.vy_mps = -0.4;
    wire.width_m = 1.9;
    let core = decision::SvObservation::from(wire);
    assert_eq!((core.length_m, core.width_m, core.vy_mps), (None, Some(1.9), -0.4));
    assert_eq!(SvObservation::from(core), wire);
}

#[test]
fn answer_validates_decides_and_echoes() {
    let config = PlannerConfig::default();
    let mut planner = decision::Planner::new(config.clone()).unwrap();
    let req = example_request();
    let valid = req.clone().validate(&config).expect("a valid request");
    assert_eq!(valid.request(), &req);
    let response = answer(&mut planner, &valid);
    assert_eq!((response.vehicle_id, response.sequence), (7, 42));
    let decided = response.outcome.as_decided().expect("a decision");
    let direct = planner.decide(&req.to_situation()).unwrap();
    assert_eq!(decision::Maneuver::from(decided.next_maneuver), direct.next_maneuver);
    assert_eq!(decision::SetPoint::from(decided.setpoint), direct.setpoint);
    // Wire checks first, then the planner's own.
    let probe = PlanRequest::probe(9).validate(&config).unwrap_err();
    assert_eq!((probe.vehicle_id, probe.sequence), (9, 0));
    assert_eq!(
        (probe.rejected.reason(), probe.rejected.field()),
        (Ok(RejectReason::UnsupportedVersion), "version")
    );
    let mut both = req.clone();
    both.ego.maneuver.beta = 3;
    both.ego.v_mps = -3.0;
    let rejected = both.validate(&config).unwrap_err().rejected;
    assert_eq!(
        (rejected.reason(), rejected.field()),
        (Ok(RejectReason::BetaOutOfRange), "ego.maneuver.beta")
    );
    let mut bad = req.clone();
    bad.ego.v_mps = -3.0;
    let rejected = bad.validate(&config).unwrap_err().response();
    let rejected = rejected.outcome.as_rejected().expect("a rejection");
    assert_eq!(
        (rejected.reason(), rejected.field()),
        (Ok(RejectReason::NegativeSpeed), "ego.v_mps")
    );
    // The configuration bounds the request: a previous plan longer than its horizon.
    let mut short = config.clone();
    short.timing.horizon = 2;
    let mut long_memory = req.clone();
    long_memory.memory.previous_plan = protocol::bounded("memory.previous_plan", &[Action::default(); 3]).unwrap();
    assert!(long_memory.clone().validate(&config).is_ok());
    let rejected = long_memory.validate(&short).unwrap_err().rejected;
    assert_eq!(
        (rejected.reason(), rejected.field()),
        (Ok(RejectReason::InvalidMemory), "memory.previous_plan")
    );
    // The watchdog's answer is the fallback, marked as the watchdog's, with a set-point.
    let fallback = fallback_answer(&config, &valid, Layer::WatchdogFallback);
    let decided = fallback.outcome.as_decided().expect("a decision");
    assert_eq!(decided.layer(), Ok(Layer::WatchdogFallback));
    // A stale request gets the same fallback under its own mark.
    let stale = fallback_answer(&config, &valid, Layer::StaleFallback);
    let stale_decided = stale.outcome.as_decided().expect("a decision");
    assert_eq!(stale_decided.layer(), Ok(Layer::StaleFallback));
    assert_eq!(stale_decided.setpoint, decided.setpoint);
    let core = decision::fallback_only(&config, valid.situation());
    assert_eq!(decision::SetPoint::from(decided.setpoint), core.setpoint);
}

#[test]
fn an_emergency_brake_reads_off_the_wire_from_every_fallback_layer() {
    // docs/protocol.md, "An emergency brake": a fallback layer with a set-point beyond the
    // strongest braking the MPC plans. The ego at 30 m/s 32 m (bumpers) behind a vehicle at
    // 8 m/s needs 8.07 m/s^2; the example request needs nothing of the kind.
    let config = PlannerConfig::default();
    let mut planner = decision::Planner::new(config.clone()).unwrap();
    let mut situation = example_request().to_situation();
    situation.ego.v_mps = 30.0;
    situation.svs = vec![decision::SvObservation::new(
        1,
        situation.ego.x_m + 32.0 + config.vehicle.length_m,
        situation.ego.y_m,
        8.0,
        0.0,
    )];
    let emergency = PlanRequest::from_situation(7, 43, 1, &situation).unwrap();
    let calm = example_request();
    let reads_as_emergency = |response: &PlanResponse| {
        let decided = response.outcome.as_decided().expect("a decision");
        decided.is_emergency_brake(config.ego.max_decel_mps2)
    };
    for (request, expected) in [(emergency, true), (calm, false)] {
        let valid = request.validate(&config).expect("a valid request");
        let response = decode_bincode(&encode_bincode(&answer(&mut planner, &valid))).unwrap();
        assert_eq!(reads_as_emergency(&response), expected, "{response:?}");
        assert_eq!(
            planner.decide(valid.situation().get()).unwrap().stats.emergency,
            expected
        );
        for layer in [Layer::WatchdogFallback, Layer::StaleFallback] {
            let response = decode_bincode(&encode_bincode(&fallback_answer(&config, &valid, layer))).unwrap();
            assert_eq!(reads_as_emergency(&response), expected, "{layer:?}: {response:?}");
        }
    }
}
