//! The service core without a transport: stale requests (on arrival and in the queue) and
//! signed answers.

use std::sync::mpsc;
use std::time::{Duration, Instant};

use decision::PlannerConfig;
use planner_service::{Service, ServiceConfig};
use protocol::containers::Vector;
use protocol::{
    unix_now_ns, EgoState, Layer, Maneuver, PlanRequest, PlanResponse, ResponseSigner, Road, SvObservation, WireFormat,
};

/// A 3-lane road, the ego in lane 2 at 25 m/s, one SV 30 m ahead.
fn request(sequence: u64) -> PlanRequest {
    let road = Road {
        lanes: 3,
        lane_width_m: 3.5,
        speed_limit_mps: 30.0,
    };
    let ego = EgoState {
        x_m: 0.0,
        y_m: 3.5,
        v_mps: 25.0,
        desired_speed_mps: 28.0,
        maneuver: Maneuver { lane: 2, beta: 0 },
    };
    let mut r = PlanRequest::new(7, sequence, 0, road, ego);
    r.svs.push(SvObservation::new(1, 30.0, 3.5, 20.0, 0.0)).unwrap();
    r
}

/// Submits `request` now; the receiver gets its answer.
fn submit(service: &Service, request: PlanRequest) -> mpsc::Receiver<PlanResponse> {
    let (tx, rx) = mpsc::channel();
    service.submit(
        request,
        Instant::now(),
        Box::new(move |r| {
            let _ = tx.send(r);
        }),
    );
    rx
}

fn layer(response: &PlanResponse) -> Layer {
    response.outcome.as_decided().expect("a decision").layer().unwrap()
}

fn ms(n: u64) -> u64 {
    n * 1_000_000
}

#[test]
fn a_request_older_than_its_deadline_is_answered_stale_at_once() {
    let service = Service::start(PlannerConfig::default(), ServiceConfig::default()).unwrap();
    let mut old = request(1);
    old.sent_at_ns = unix_now_ns() - ms(2_000);
    let answer = submit(&service, old).recv().unwrap();
    assert_eq!((layer(&answer), answer.solve_us), (Layer::StaleFallback, 0));
    // Within deadline + tolerance, or without a send time: solved.
    let mut young = request(2);
    young.sent_at_ns = unix_now_ns() - ms(300);
    for r in [young, request(3)] {
        assert_ne!(layer(&submit(&service, r).recv().unwrap()), Layer::StaleFallback);
    }
    let stats = service.stats().snapshot();
    assert_eq!((stats.by_layer.stale_fallback, stats.stale_in_queue), (1, 0));
}

#[test]
fn a_request_that_turns_stale_in_the_queue_is_not_solved() {
    // One worker, busy for a second with the first request; long deadlines so that the
    // watchdog stays out of it.
    let config = ServiceConfig {
        workers: 1,
        queue_capacity: 4,
        max_deadline: Duration::from_secs(3),
        inject_solve_delay: Duration::from_secs(1),
        ..ServiceConfig::default()
    };
    let service = Service::start(PlannerConfig::default(), config).unwrap();
    let mut blocker = request(1);
    blocker.deadline_us = 3_000_000;
    let first = submit(&service, blocker);
    // Fresh on arrival (2 s deadline, sent 1.5 s ago, 50 ms tolerance), stale 0.55 s later:
    // the worker takes it a second later at the earliest.
    let mut queued = request(2);
    queued.deadline_us = 2_000_000;
    queued.sent_at_ns = unix_now_ns() - ms(1_500);
    let second = submit(&service, queued).recv().unwrap();
    assert_eq!(layer(&second), Layer::StaleFallback);
    assert_ne!(layer(&first.recv().unwrap()), Layer::StaleFallback);
    assert_eq!(service.stats().snapshot().stale_in_queue, 1);
}

#[test]
fn with_a_key_every_answer_is_signed() {
    let signer = ResponseSigner::from_seed(&[9; 32]);
    let verifier = signer.verifier();
    let config = ServiceConfig {
        signer: Some(signer),
        ..ServiceConfig::default()
    };
    let service = Service::start(PlannerConfig::default(), config).unwrap();
    let mut stale = request(2);
    stale.sent_at_ns = 1;
    let mut bad = request(3);
    bad.ego.maneuver.beta = 5;
    let mut answers: Vec<PlanResponse> = [request(1), stale, bad, PlanRequest::probe(7)]
        .into_iter()
        .map(|r| submit(&service, r).recv().unwrap())
        .collect();
    // Undecodable bytes too.
    let (tx, rx) = mpsc::channel();
    service.handle_bytes(
        b"garbage",
        WireFormat::Bincode,
        Instant::now(),
        Box::new(move |r| {
            let _ = tx.send(r);
        }),
    );
    answers.push(rx.recv().unwrap());
    for answer in &answers {
        assert_eq!(verifier.verify(answer), Ok(()), "{answer:?}");
    }
    // Without a key: unsigned, as before.
    let plain = Service::start(PlannerConfig::default(), ServiceConfig::default()).unwrap();
    assert!(submit(&plain, request(1)).recv().unwrap().signature.is_unsigned());
}
