//! protocol -> ROS message -> protocol gives the same message; what the protocol cannot hold
//! is a typed rejection with the request's ids.

mod common;

use hmdp_ros2::msg;
use hmdp_ros2::ConvertError;
use protocol::{PlanRequest, PlanResponse, RejectReason};

fn round_trip_request(request: &PlanRequest) -> PlanRequest {
    PlanRequest::try_from(msg::PlanRequest::from(request)).expect("a protocol request converts back")
}

fn round_trip_response(response: &PlanResponse) -> PlanResponse {
    PlanResponse::try_from(msg::PlanResponse::from(response)).expect("a protocol response converts back")
}

fn assert_rejection(error: ConvertError, reason: RejectReason, field: &str) {
    assert_eq!(error.rejected.reason(), Ok(reason), "{error}");
    assert_eq!(error.rejected.field(), field, "{error}");
    let answer = error.to_response();
    assert_eq!(answer.outcome.as_rejected(), Some(&error.rejected));
    assert_eq!((answer.vehicle_id, answer.sequence), (error.vehicle_id, error.sequence));
}

#[test]
fn the_worked_example_request_round_trips() {
    let request = common::worked_example(7, 42);
    let message = msg::PlanRequest::from(&request);
    assert_eq!(message.svs.len(), 1);
    assert_eq!(
        message.memory.previous_plan,
        vec![msg::Action {
            lateral: 0,
            longitudinal: 1
        }]
    );
    assert_eq!(round_trip_request(&request), request);
}

#[test]
fn decided_and_rejected_responses_round_trip() {
    let decided = common::canned_decision(7, 42);
    assert!(!decided.signature.is_unsigned());
    let message = msg::PlanResponse::from(&decided);
    assert_eq!(message.outcome, msg::PlanResponse::OUTCOME_DECIDED);
    assert_eq!(message.decided.layer, msg::Decided::LAYER_NOMINAL);
    assert_eq!(message.rejected, msg::Rejected::default());
    assert_eq!(message.signature, decided.signature.0);
    assert_eq!(round_trip_response(&decided), decided);

    let rejected = common::canned_rejection(7, 43);
    let message = msg::PlanResponse::from(&rejected);
    assert_eq!(message.outcome, msg::PlanResponse::OUTCOME_REJECTED);
    assert_eq!(message.rejected.reason, msg::Rejected::REASON_NEGATIVE_SPEED);
    assert_eq!(message.rejected.field, "ego.v_mps");
    assert_eq!(message.decided, msg::Decided::default());
    assert_eq!(round_trip_response(&rejected), rejected);
}

#[test]
fn values_the_planner_judges_pass_through() {
    let mut message = msg::PlanRequest::from(&common::worked_example(7, 42));
    message.version = 2;
    message.ego.v_mps = f64::NAN;
    message.ego.maneuver.beta = 5;
    message.road.lanes = 0;
    message.memory.previous_plan[0].lateral = -7;
    let request = PlanRequest::try_from(message).expect("not the conversion's business");
    assert_eq!(request.version, 2);
    assert!(request.ego.v_mps.is_nan());
    assert_eq!((request.ego.maneuver.beta, request.road.lanes), (5, 0));
    assert_eq!(request.memory.previous_plan[0].lateral, -7);
}

fn long_request() -> msg::PlanRequest {
    let mut message = msg::PlanRequest::from(&common::worked_example(7, 42));
    message.sequence = 43;
    message
}

#[test]
fn request_lists_over_capacity_are_typed_rejections() {
    let mut message = long_request();
    let sv = message.svs[0];
    message.svs = (0..65).map(|id| msg::SvObservation { id, ..sv }).collect();
    let error = PlanRequest::try_from(message).unwrap_err();
    assert_rejection(error, RejectReason::CapacityExceeded, "svs");
    assert_eq!((error.vehicle_id, error.sequence), (7, 43));

    let mut message = long_request();
    message.svs = (0..64).map(|id| msg::SvObservation { id, ..sv }).collect();
    assert_eq!(PlanRequest::try_from(message).unwrap().svs.len(), 64);

    let mut message = long_request();
    message.memory.corrective = vec![msg::CorrectiveEntry::default(); 17];
    assert_rejection(
        PlanRequest::try_from(message).unwrap_err(),
        RejectReason::CapacityExceeded,
        "memory.corrective",
    );

    let mut message = long_request();
    message.memory.previous_plan = vec![msg::Action::default(); 7];
    assert_rejection(
        PlanRequest::try_from(message).unwrap_err(),
        RejectReason::CapacityExceeded,
        "memory.previous_plan",
    );
}

#[test]
fn response_violations_are_typed_rejections() {
    let decided = || msg::PlanResponse::from(&common::canned_decision(7, 42));
    let rejected = || msg::PlanResponse::from(&common::canned_rejection(7, 43));

    let mut message = decided();
    message.decided.plan = vec![msg::PlanStep::default(); 7];
    assert_rejection(
        PlanResponse::try_from(message).unwrap_err(),
        RejectReason::CapacityExceeded,
        "plan",
    );

    let mut message = decided();
    message.decided.memory.corrective = vec![msg::CorrectiveEntry::default(); 17];
    assert_rejection(
        PlanResponse::try_from(message).unwrap_err(),
        RejectReason::CapacityExceeded,
        "memory.corrective",
    );

    let mut message = decided();
    message.decided.memory.previous_plan = vec![msg::Action::default(); 7];
    assert_rejection(
        PlanResponse::try_from(message).unwrap_err(),
        RejectReason::CapacityExceeded,
        "memory.previous_plan",
    );

    let mut message = decided();
    message.decided.layer = 5;
    assert_rejection(
        PlanResponse::try_from(message).unwrap_err(),
        RejectReason::Malformed,
        "layer",
    );

    let mut message = decided();
    message.outcome = 2;
    let error = PlanResponse::try_from(message).unwrap_err();
    assert_rejection(error, RejectReason::Malformed, "outcome");
    assert_eq!((error.vehicle_id, error.sequence), (7, 42));

    let mut message = rejected();
    message.rejected.reason = 3;
    assert_rejection(
        PlanResponse::try_from(message).unwrap_err(),
        RejectReason::Malformed,
        "reason",
    );

    let mut message = rejected();
    message.rejected.field = "x".repeat(32);
    assert_rejection(
        PlanResponse::try_from(message).unwrap_err(),
        RejectReason::CapacityExceeded,
        "field",
    );
    let mut message = rejected();
    message.rejected.field = "x".repeat(31);
    assert_eq!(
        PlanResponse::try_from(message)
            .unwrap()
            .outcome
            .as_rejected()
            .unwrap()
            .field()
            .len(),
        31
    );

    for bad in ["ego.v_mps\u{e9}", "nul\0"] {
        let mut message = rejected();
        message.rejected.field = bad.to_owned();
        assert_rejection(
            PlanResponse::try_from(message).unwrap_err(),
            RejectReason::Malformed,
            "field",
        );
    }

    // The inactive body is not judged.
    let mut message = decided();
    message.rejected.reason = 99;
    message.rejected.field = "x".repeat(100);
    assert!(PlanResponse::try_from(message).is_ok());
}
