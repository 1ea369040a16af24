//! Stale input is answered as stale: `planner serve` (Zenoh and iceoryx2) answers a request
//! whose `sent_at_ns` is already older than its deadline with the fallback marked
//! `stale_fallback`, never with a fresh-looking solve of the old scene.
//!
//! * requests stamped in the past, over both transports and over ROS 2, beside fresh and
//!   unstamped ones;
//! * the planner stopped with SIGSTOP while a vehicle keeps sending: every request that
//!   waited in the socket buffers longer than its deadline comes back stale.
//!
//! No timing is asserted: which requests waited is known from when they were sent relative
//! to SIGSTOP / SIGCONT, which the test itself sends.

use std::time::{Duration, Instant};

use protocol::{
    decode_bincode, encode_bincode, unix_now_ns, Layer, PlanRequest, PlanResponse, WireFormat, ZENOH_PLAN_KEY,
};
use system_tests::ros2::Domain;
use system_tests::{signal, worked_example_request, Iceoryx2Prefix, Process, ZenohPlanner};
use transport::iceoryx2::{Client, ClientOptions};
use transport::zenoh::{encoding, ZenohChannel};
use zenoh::handlers::FifoChannelHandler;
use zenoh::query::Reply;
use zenoh::Wait;

/// How long a planner may take to start answering (debug builds on a shared machine).
const STARTUP: Duration = Duration::from_secs(60);
/// The planner's default deadline plus its default clock-skew tolerance.
const STALE_AFTER: Duration = Duration::from_millis(400 + 50);

fn layer(response: &PlanResponse) -> Layer {
    response
        .outcome
        .as_decided()
        .and_then(|d| d.layer().ok())
        .unwrap_or_else(|| panic!("not a decision: {response:?}"))
}

/// The worked example sent `age` ago (`None`: no send time).
fn sent_ago(sequence: u64, age: Option<Duration>) -> PlanRequest {
    let mut request = worked_example_request(7, sequence);
    request.sent_at_ns = age.map_or(0, |age| unix_now_ns() - age.as_nanos() as u64);
    request
}

#[test]
fn requests_older_than_their_deadline_are_answered_as_stale() {
    let prefix = Iceoryx2Prefix::new("stale");
    let planner = ZenohPlanner::start("stale", &["--iceoryx2", "--iceoryx2-prefix", prefix.as_str()]);
    let zenoh = planner.vehicle(None);
    let mut ask_zenoh = |request: &PlanRequest| -> PlanResponse {
        let replies = zenoh.ask_raw(&encode_bincode(request), WireFormat::Bincode, Duration::from_secs(5));
        assert_eq!(replies.len(), 1, "{}", planner.log());
        decode_bincode(&replies[0].0).unwrap()
    };
    let mut iceoryx2 = Client::connect(&ClientOptions {
        prefix: Some(prefix.as_str().to_string()),
        ready_timeout: STARTUP,
        node_name: "stale-vehicle".into(),
        ..ClientOptions::default()
    })
    .expect("the planner's iceoryx2 services");
    let mut ask_iceoryx2 = |request: &PlanRequest| -> PlanResponse {
        // The server port may come up after the services: ask again until it answers.
        for _ in 0..120 {
            if let Some(r) = iceoryx2
                .request(request.clone(), Duration::from_millis(500))
                .unwrap()
                .response
            {
                return r;
            }
        }
        panic!("no iceoryx2 answer\n{}", planner.log());
    };
    stale_and_fresh("zenoh", &mut ask_zenoh);
    stale_and_fresh("iceoryx2", &mut ask_iceoryx2);
    let stats = stats_document(&zenoh);
    assert_eq!(stats["by_layer"]["stale_fallback"], 4, "{stats}");
}

/// The ROS 2 front (`planner serve --ros2`) answers stale requests as the others do.
#[test]
fn requests_older_than_their_deadline_are_answered_as_stale_over_ros2() {
    let domain = Domain::new(0);
    let planner = Process::start_with_env("planner", &["serve", "--ros2"], "stale-ros2", &domain.env());
    let client = domain.plan_client("stale_vehicle", &planner, STARTUP);
    let mut ask_ros2 = |request: &PlanRequest| -> PlanResponse {
        client
            .exchange(request, Duration::from_secs(10))
            .expect("an exchange")
            .unwrap_or_else(|| panic!("no ROS 2 answer\n{}", planner.log()))
    };
    stale_and_fresh("ros2", &mut ask_ros2);
}

/// Over one transport: two requests stamped in the past come back stale, a fresh and an
/// unstamped one do not.
fn stale_and_fresh(transport: &str, ask: &mut dyn FnMut(&PlanRequest) -> PlanResponse) {
    // Two seconds old: the fallback at once, marked stale, with nothing solved.
    let stale = ask(&sent_ago(1, Some(Duration::from_secs(2))));
    assert_eq!(
        (stale.vehicle_id, stale.sequence, layer(&stale)),
        (7, 1, Layer::StaleFallback),
        "{transport}"
    );
    assert_eq!(stale.solve_us, 0, "{transport}");
    let setpoint = stale.outcome.as_decided().unwrap().setpoint;
    // Fresh, and unknown send time: decided as before.
    for (sequence, age) in [(2, Some(Duration::ZERO)), (3, None)] {
        let fresh = ask(&sent_ago(sequence, age));
        assert_ne!(layer(&fresh), Layer::StaleFallback, "{transport} {age:?}");
    }
    // A shorter deadline makes a younger request stale: 100 ms + 50 ms tolerance.
    let mut short = sent_ago(4, Some(Duration::from_millis(1000)));
    short.deadline_us = 100_000;
    let answer = ask(&short);
    assert_eq!(layer(&answer), Layer::StaleFallback, "{transport}");
    assert_eq!(answer.outcome.as_decided().unwrap().setpoint, setpoint, "{transport}");
}

/// The planner's statistics document, from its next publication.
fn stats_document(channel: &ZenohChannel) -> serde_json::Value {
    let subscriber = channel
        .session()
        .declare_subscriber(protocol::ZENOH_STATS_KEY)
        .wait()
        .unwrap();
    let sample = subscriber
        .recv_timeout(Duration::from_secs(10))
        .unwrap()
        .expect("statistics");
    serde_json::from_slice(&sample.payload().to_bytes()).unwrap()
}

#[test]
fn requests_that_waited_while_the_planner_was_stopped_come_back_stale() {
    let planner = ZenohPlanner::start("sigstop", &[]);
    let vehicle = planner.vehicle(None);
    let pid = planner.process.id();
    // One request every 50 ms, none waiting for its answer (a vehicle keeps perceiving).
    let mut sequence = 0;
    let mut in_flight = Vec::new();
    let mut send_for = |period: Duration, in_flight: &mut Vec<(u64, Instant, FifoChannelHandler<Reply>)>| {
        let until = Instant::now() + period;
        while Instant::now() < until {
            sequence += 1;
            let request = sent_ago(sequence, Some(Duration::ZERO));
            let replies = vehicle
                .session()
                .get(ZENOH_PLAN_KEY)
                .payload(encode_bincode(&request))
                .encoding(encoding(WireFormat::Bincode))
                .timeout(Duration::from_secs(30))
                .wait()
                .expect("query sent");
            in_flight.push((sequence, Instant::now(), replies));
            std::thread::sleep(Duration::from_millis(50));
        }
    };
    send_for(Duration::from_millis(300), &mut in_flight);
    signal(pid, "STOP");
    // Sent at least 100 ms after SIGSTOP took effect: nobody reads them until SIGCONT.
    std::thread::sleep(Duration::from_millis(100));
    let stopped_from = Instant::now();
    send_for(Duration::from_millis(1500), &mut in_flight);
    let continued_at = Instant::now();
    signal(pid, "CONT");
    send_for(Duration::from_millis(500), &mut in_flight);

    let (mut waited, mut fresh_after) = (0, 0);
    for (sequence, sent, replies) in in_flight {
        let reply = replies
            .recv_timeout(Duration::from_secs(30))
            .ok()
            .flatten()
            .unwrap_or_else(|| panic!("request {sequence} unanswered\n{}", planner.log()));
        let response: PlanResponse = decode_bincode(&reply.result().expect("a reply").payload().to_bytes()).unwrap();
        assert_eq!(response.sequence, sequence);
        // Waited in the buffers longer than deadline + tolerance: it must not be solved.
        if sent >= stopped_from && continued_at.duration_since(sent) > STALE_AFTER {
            waited += 1;
            assert_eq!(
                layer(&response),
                Layer::StaleFallback,
                "request {sequence} waited {:?} and was answered as fresh",
                continued_at.duration_since(sent)
            );
        } else if sent > continued_at && layer(&response) != Layer::StaleFallback {
            fresh_after += 1;
        }
    }
    assert!(
        waited >= 5,
        "only {waited} requests waited while the planner was stopped"
    );
    assert!(fresh_after > 0, "the planner never served fresh requests after SIGCONT");
}
