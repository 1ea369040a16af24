//! `planner serve --iceoryx2` as a process, with clients in this process and as processes:
//! determinism against the in-process planner, concurrent vehicles, the watchdog, typed
//! rejections, and crashes (the planner killed and restarted, a vehicle killed mid-request).
//!
//! Every test uses its own iceoryx2 prefix, so that tests running in parallel never share
//! shared memory.

use std::time::{Duration, Instant};

use protocol::{Layer, OutcomeRef, PlanRequest, PlanResponse, RejectReason};
use system_tests::{
    case1_decisions, concurrent_vehicles_each_answered_once, free_port, scratch_dir, worked_example_request,
    Iceoryx2Prefix, Process,
};
use transport::iceoryx2::{Client, ClientOptions, Exchange};

/// How long a planner may take to start answering (a shared machine).
const STARTUP: Duration = Duration::from_secs(60);

fn start_planner(prefix: &str, tag: &str, extra: &[&str]) -> Process {
    let mut args = vec!["serve", "--iceoryx2", "--iceoryx2-prefix", prefix, "--workers", "2"];
    args.extend_from_slice(extra);
    Process::start("planner", &args, tag)
}

fn connect(prefix: &str, name: &str) -> Client {
    let options = ClientOptions {
        prefix: Some(prefix.to_string()),
        ready_timeout: STARTUP,
        node_name: name.to_string(),
        ..ClientOptions::default()
    };
    Client::connect(&options).expect("the planner's iceoryx2 services")
}

/// Sends requests until the planner answers (its server port may come up after its
/// services).
fn wait_until_serving(client: &mut Client, planner: &Process) {
    let give_up = Instant::now() + STARTUP;
    loop {
        let exchange = client
            .request(PlanRequest::probe(999), Duration::from_millis(500))
            .unwrap();
        if exchange.response.is_some() {
            return;
        }
        assert!(
            Instant::now() < give_up,
            "the planner never answered\n{}",
            planner.log()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn request(vehicle_id: u64, sequence: u64) -> PlanRequest {
    worked_example_request(vehicle_id, sequence)
}

fn answered(exchange: Exchange, vehicle_id: u64, sequence: u64) -> PlanResponse {
    assert_eq!(exchange.extra_responses, 0, "exactly one answer");
    let response = exchange
        .response
        .unwrap_or_else(|| panic!("vehicle {vehicle_id} sequence {sequence}: no answer"));
    assert_eq!((response.vehicle_id, response.sequence), (vehicle_id, sequence));
    response
}

fn rejection(response: &PlanResponse) -> (RejectReason, String) {
    match response.outcome.get().unwrap() {
        OutcomeRef::Rejected(r) => (r.reason().unwrap(), r.field().to_string()),
        OutcomeRef::Decided(d) => panic!("expected a rejection, got a decision of layer {:?}", d.layer()),
    }
}

fn iceoryx2_config(prefix: &str) -> transport::iceoryx2::IceoryxConfig {
    transport::iceoryx2::config(Some(prefix)).unwrap()
}

#[test]
fn case1_over_iceoryx2_matches_in_process_byte_for_byte() {
    let _files = Iceoryx2Prefix::new("case1");
    let prefix = _files.as_str().to_string();
    let planner = start_planner(&prefix, "case1-planner", &[]);
    let mut probe = connect(&prefix, "probe");
    wait_until_serving(&mut probe, &planner);
    let dir = scratch_dir("iceoryx2-case1");
    let run = |name: &str, args: &[&str]| case1_decisions(&dir, name, args, &|| planner.log());
    let inproc = run("inproc", &["--transport", "inproc"]);
    let shared = run("iceoryx2", &["--transport", "iceoryx2", "--iceoryx2-prefix", &prefix]);
    // The simulator starting its own planner under a prefix of its own.
    let spawned = run("spawned", &["--transport", "iceoryx2", "--spawn-planner"]);
    assert!(!inproc.is_empty());
    assert!(inproc == shared, "decisions.csv differs between inproc and iceoryx2");
    assert!(
        inproc == spawned,
        "decisions.csv differs between inproc and a spawned iceoryx2 planner"
    );
}

#[test]
fn eight_concurrent_vehicles_each_get_every_answer_exactly_once() {
    let _files = Iceoryx2Prefix::new("eight");
    let prefix = _files.as_str().to_string();
    let planner = start_planner(&prefix, "eight-planner", &[]);
    let mut probe = connect(&prefix, "probe");
    wait_until_serving(&mut probe, &planner);
    concurrent_vehicles_each_answered_once(
        8,
        20,
        |vehicle| connect(&prefix, &format!("vehicle-{vehicle}")),
        |client, vehicle, sequence| {
            let exchange = client
                .request(request(vehicle, sequence), Duration::from_secs(5))
                .unwrap();
            answered(exchange, vehicle, sequence)
        },
    );
}

#[test]
fn watchdog_answers_the_fallback_by_the_deadline() {
    let _files = Iceoryx2Prefix::new("watchdog");
    let prefix = _files.as_str().to_string();
    let planner = start_planner(&prefix, "watchdog-planner", &["--inject-solve-delay-ms", "1000"]);
    let mut client = connect(&prefix, "watchdog-vehicle");
    wait_until_serving(&mut client, &planner);
    let mut round_trips = Vec::new();
    for sequence in 1..=5u64 {
        let mut r = request(3, sequence);
        r.deadline_us = 100_000;
        let sent = Instant::now();
        let exchange = client.request(r, Duration::from_secs(2)).unwrap();
        let elapsed = sent.elapsed();
        let response = answered(exchange, 3, sequence);
        let decided = response.outcome.as_decided().expect("a decision");
        assert_eq!(decided.layer().unwrap(), Layer::WatchdogFallback);
        // The planner's own clock: the watchdog answered no earlier than the deadline and
        // before the injected 1 s solve could have ended (how close to the deadline is a
        // figure of the load tool, not of a test).
        let server_us = u64::from(response.queue_us) + u64::from(response.solve_us);
        assert!(
            (100_000..1_000_000).contains(&server_us),
            "answered {server_us} us after arrival"
        );
        round_trips.push(elapsed);
    }
    eprintln!("watchdog round trips over iceoryx2 (deadline 100 ms): {round_trips:?}");
    // Exactly one answer: the late solves of the five requests come to nothing, and the
    // next request is answered with its own sequence, not a stale one.
    std::thread::sleep(Duration::from_millis(1_100));
    let mut r = request(3, 6);
    r.deadline_us = 100_000;
    answered(client.request(r, Duration::from_secs(2)).unwrap(), 3, 6);
}

#[test]
fn invalid_requests_get_typed_rejections() {
    let _files = Iceoryx2Prefix::new("reject");
    let prefix = _files.as_str().to_string();
    let planner = start_planner(&prefix, "reject-planner", &[]);
    let mut client = connect(&prefix, "reject-vehicle");
    wait_until_serving(&mut client, &planner);
    let mut ask = |r: PlanRequest| {
        let (v, s) = (r.vehicle_id, r.sequence);
        answered(client.request(r, Duration::from_secs(5)).unwrap(), v, s)
    };
    let mut wrong_version = request(5, 1);
    wrong_version.version = 1;
    assert_eq!(
        rejection(&ask(wrong_version)),
        (RejectReason::UnsupportedVersion, "version".into())
    );
    let mut nan = request(5, 2);
    nan.ego.v_mps = f64::NAN;
    assert_eq!(rejection(&ask(nan)).0, RejectReason::NonFinite);
    let mut lane = request(5, 3);
    lane.ego.maneuver.lane = 9;
    assert_eq!(rejection(&ask(lane)).0, RejectReason::LaneOutOfRange);
    // The planner is unaffected: the next valid request is decided.
    assert!(ask(request(5, 4)).outcome.as_decided().is_some());
}

#[test]
fn planner_killed_and_restarted_clients_recover_and_stale_memory_is_removed() {
    let _files = Iceoryx2Prefix::new("restart");
    let prefix = _files.as_str().to_string();
    let config = iceoryx2_config(&prefix);
    let mut planner = start_planner(&prefix, "restart-planner-1", &[]);
    let mut client = connect(&prefix, "restart-vehicle");
    wait_until_serving(&mut client, &planner);
    for sequence in 1..=3 {
        answered(
            client.request(request(7, sequence), Duration::from_secs(5)).unwrap(),
            7,
            sequence,
        );
    }
    assert_eq!(transport::iceoryx2::dead_nodes(&config), 0);
    planner.kill();
    assert!(
        transport::iceoryx2::dead_nodes(&config) >= 1,
        "a SIGKILLed planner leaves its node behind"
    );
    // No answer, but no hang either: every request returns by its wait.
    let wait = Duration::from_millis(300);
    for sequence in 4..=6 {
        let exchange = client.request(request(7, sequence), wait).unwrap();
        assert!(exchange.response.is_none());
    }
    let planner = start_planner(&prefix, "restart-planner-2", &[]);
    let give_up = Instant::now() + STARTUP;
    let mut sequence = 7;
    loop {
        let exchange = client.request(request(7, sequence), wait).unwrap();
        if let Some(response) = exchange.response {
            assert_eq!((response.vehicle_id, response.sequence), (7, sequence));
            break;
        }
        assert!(
            Instant::now() < give_up,
            "no answer after the restart\n{}",
            planner.log()
        );
        sequence += 1;
    }
    assert_eq!(
        transport::iceoryx2::dead_nodes(&config),
        0,
        "the restarted planner removed the dead node's resources"
    );
    for s in sequence + 1..sequence + 4 {
        answered(client.request(request(7, s), Duration::from_secs(5)).unwrap(), 7, s);
    }
}

#[test]
fn a_vehicle_killed_mid_request_does_not_disturb_the_others() {
    let _files = Iceoryx2Prefix::new("vkill");
    let prefix = _files.as_str().to_string();
    // Slow solves (still inside the deadline) so that the victim dies while waiting.
    let planner = start_planner(&prefix, "vkill-planner", &["--inject-solve-delay-ms", "150"]);
    let mut client = connect(&prefix, "vkill-survivor");
    wait_until_serving(&mut client, &planner);
    let mut victim = Process::start(
        "sim_client",
        &[
            "case1",
            "--out",
            scratch_dir("vkill").to_str().unwrap(),
            "--transport",
            "iceoryx2",
            "--iceoryx2-prefix",
            &prefix,
        ],
        "vkill-victim",
    );
    std::thread::sleep(Duration::from_millis(1500));
    assert!(victim.is_running(), "the victim ended early:\n{}", victim.log());
    victim.kill();
    for sequence in 1..=10 {
        let r = answered(
            client.request(request(8, sequence), Duration::from_secs(5)).unwrap(),
            8,
            sequence,
        );
        let layer = r.outcome.as_decided().expect("a decision").layer().unwrap();
        assert_ne!(layer, Layer::WatchdogFallback, "the survivor is served normally");
    }
    // A new vehicle (a new node) removes what the victim left behind.
    drop(connect(&prefix, "vkill-newcomer"));
    assert_eq!(transport::iceoryx2::dead_nodes(&iceoryx2_config(&prefix)), 0);
}

#[test]
fn one_planner_serves_iceoryx2_and_zenoh_at_once() {
    use zenoh::Wait;
    let _files = Iceoryx2Prefix::new("both");
    let prefix = _files.as_str().to_string();
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let mut planner = start_planner(&prefix, "both-planner", &["--zenoh-listen", &endpoint]);
    let mut shm = connect(&prefix, "both-vehicle");
    wait_until_serving(&mut shm, &planner);
    let session = zenoh::open(transport::zenoh::client_config(&endpoint).unwrap())
        .wait()
        .expect("a zenoh session to the planner");
    let over_zenoh = |sequence: u64| -> PlanResponse {
        let replies = session
            .get(protocol::ZENOH_PLAN_KEY)
            .payload(protocol::encode_bincode(&request(2, sequence)))
            .encoding(zenoh::bytes::Encoding::from(protocol::ENCODING_BINCODE))
            .timeout(Duration::from_secs(5))
            .wait()
            .unwrap();
        let reply = replies.recv().expect("a zenoh answer");
        protocol::decode_bincode(&reply.result().expect("an ok reply").payload().to_bytes()).unwrap()
    };
    for sequence in 1..=5 {
        let a = answered(
            shm.request(request(1, sequence), Duration::from_secs(5)).unwrap(),
            1,
            sequence,
        );
        let b = over_zenoh(sequence);
        assert_eq!((b.vehicle_id, b.sequence), (2, sequence));
        // The same snapshot gets the same decision whichever way it came.
        assert_eq!(a.outcome.as_decided(), b.outcome.as_decided());
    }
    drop(session);
    drop(shm);
    assert!(planner.terminate(Duration::from_secs(10)).is_some_and(|s| s.success()));
    // Both front ends fed one service: its final statistics count every answer, the probes
    // apart.
    let stats = planner.final_statistics();
    assert_eq!(stats["answered"].as_u64(), Some(10), "{stats}");
    assert_eq!(stats["by_layer"]["rejected"].as_u64(), Some(0), "{stats}");
    assert!(stats["probes"].as_u64().is_some_and(|p| p >= 1), "{stats}");
}
