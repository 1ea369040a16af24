//! A `PlanServer` and a `PlanClient` in one process over RustDDS on loopback, each test on
//! its own domain: one answer per request, typed rejections, late answers not taken for
//! newer requests, undecodable requests answered.

mod common;

use std::collections::HashMap;
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use hmdp_ros2::{ClientOptions, DecisionSubscriber, Incoming, PlanClient, PlanServer, Reply, ServerOptions};
use protocol::{PlanResponse, RejectReason};

const DISCOVERY: Duration = Duration::from_secs(20);
const WAIT: Duration = Duration::from_secs(10);

/// Requests the handler got, by (vehicle id, sequence).
type Seen = Arc<Mutex<HashMap<(u64, u64), usize>>>;

/// A server whose "planner" answers from a worker thread, as the real one does: the
/// canned decision for requests, the conversion's rejection for undecodable ones.
fn canned_server(k: u32, seen: &Seen) -> PlanServer {
    let (jobs, queue) = mpsc::channel::<(Incoming, Reply)>();
    thread::spawn(move || {
        for (incoming, reply) in queue {
            match incoming {
                Incoming::Request(request) => reply(common::canned_decision(request.vehicle_id, request.sequence)),
                Incoming::Undecodable {
                    vehicle_id,
                    sequence,
                    rejected,
                } => reply(PlanResponse::rejected(vehicle_id, sequence, rejected, 0)),
            }
        }
    });
    let seen = Arc::clone(seen);
    let jobs = Mutex::new(jobs);
    let options = ServerOptions {
        node: common::node("hmdp_planner", k),
        ..ServerOptions::default()
    };
    PlanServer::start(options, move |incoming, arrival, reply| {
        assert!(arrival <= Instant::now());
        let ids = match &incoming {
            Incoming::Request(r) => (r.vehicle_id, r.sequence),
            Incoming::Undecodable {
                vehicle_id, sequence, ..
            } => (*vehicle_id, *sequence),
        };
        *seen.lock().unwrap().entry(ids).or_default() += 1;
        jobs.lock().unwrap().send((incoming, reply)).expect("the worker runs");
    })
    .expect("the server starts")
}

fn client(k: u32, name: &str) -> PlanClient {
    PlanClient::new(ClientOptions {
        node: common::node(name, k),
    })
    .expect("the client starts")
}

#[test]
fn every_request_gets_exactly_its_answer_and_over_capacity_is_a_typed_rejection() {
    common::setup();
    let seen = Seen::default();
    let server = canned_server(1, &seen);
    let subscriber = DecisionSubscriber::new(ClientOptions {
        node: common::node("hmdp_observer", 1),
    })
    .expect("the subscriber starts");
    let client = Arc::new(client(1, "hmdp_vehicle_e2e"));
    client.wait_for_service(DISCOVERY).expect("the server is found");
    server
        .wait_for_decision_subscriber(DISCOVERY)
        .expect("the observer is matched");
    subscriber
        .wait_for_publisher(DISCOVERY)
        .expect("the server's topic is matched");

    // Four vehicles at once through one client, ten requests each.
    let vehicles: Vec<_> = (1..=4u64)
        .map(|vehicle| {
            let client = Arc::clone(&client);
            thread::spawn(move || {
                for sequence in 1..=10 {
                    let request = common::worked_example(vehicle, sequence);
                    let answer = client
                        .exchange(&request, WAIT)
                        .expect("no error")
                        .expect("answered in time");
                    assert_eq!(answer, common::canned_decision(vehicle, sequence));
                }
            })
        })
        .collect();
    for vehicle in vehicles {
        vehicle.join().expect("every exchange got its answer");
    }

    // 65 SVs: the conversion's typed rejection, with the request's ids.
    let request = common::worked_example(9, 1);
    let sv = request.svs[0];
    let mut message = hmdp_ros2::msg::PlanRequest::from(&request);
    message.svs = (0..65)
        .map(|id| hmdp_ros2::msg::SvObservation { id, ..sv.into() })
        .collect();
    let answer = client
        .exchange_msg(message, WAIT)
        .expect("no error")
        .expect("answered in time");
    assert_eq!((answer.vehicle_id, answer.sequence), (9, 1));
    let rejected = answer.outcome.as_rejected().expect("a rejection");
    assert_eq!(rejected.reason(), Ok(RejectReason::CapacityExceeded));
    assert_eq!(rejected.field(), "svs");

    // Every request reached the handler exactly once (probes aside) ...
    let seen = seen.lock().unwrap().clone();
    for vehicle in 1..=4 {
        for sequence in 1..=10 {
            assert_eq!(
                seen.get(&(vehicle, sequence)),
                Some(&1),
                "vehicle {vehicle} request {sequence}"
            );
        }
    }
    assert_eq!(seen.get(&(9, 1)), Some(&1));

    // ... and each answer was published once on /hmdp/decisions (probes' answers aside).
    let ours = |(vehicle, _): &(u64, u64)| (1..=4).contains(vehicle) || *vehicle == 9;
    let mut published = HashMap::<(u64, u64), usize>::new();
    while published.keys().filter(|ids| ours(ids)).count() < 41 {
        let decision = subscriber.recv_timeout(WAIT).expect("no error").expect("published");
        *published.entry((decision.vehicle_id, decision.sequence)).or_default() += 1;
    }
    // Whatever else comes (a duplicate would) within a short while.
    while let Some(decision) = subscriber.recv_timeout(Duration::from_millis(300)).expect("no error") {
        *published.entry((decision.vehicle_id, decision.sequence)).or_default() += 1;
    }
    assert!(
        published.iter().filter(|(ids, _)| ours(ids)).all(|(_, n)| *n == 1),
        "{published:?}"
    );
    // A reply counts its answer before it publishes it: every decision seen, every count in.
    let counters = server.counters();
    assert_eq!(counters.answered, counters.received);
    assert_eq!(counters.send_errors, 0);
    assert_eq!(counters.undecodable, 1);
    server.stop();
}

#[test]
fn rejections_arrive_as_sent_and_late_answers_are_not_taken_for_newer_requests() {
    common::setup();
    let late: Arc<Mutex<Option<Reply>>> = Arc::default();
    let stash = Arc::clone(&late);
    let options = ServerOptions {
        node: common::node("hmdp_planner", 2),
        ..ServerOptions::default()
    };
    let server = PlanServer::start(options, move |incoming, _, reply| {
        let Incoming::Request(request) = incoming else {
            panic!("only decodable requests here");
        };
        match request.sequence {
            // Answered only when request 2 comes, after the vehicle has given up on it.
            1 => *stash.lock().unwrap() = Some(reply),
            2 => {
                if let Some(late) = stash.lock().unwrap().take() {
                    late(common::canned_rejection(request.vehicle_id, 1));
                }
                reply(common::canned_decision(request.vehicle_id, 2));
            }
            _ => reply(common::canned_rejection(request.vehicle_id, request.sequence)),
        }
    })
    .expect("the server starts");
    let client = client(2, "hmdp_vehicle_late");
    client.wait_for_service(DISCOVERY).expect("the server is found");

    let answer = client.exchange(&common::worked_example(3, 5), WAIT).unwrap().unwrap();
    assert_eq!(answer, common::canned_rejection(3, 5));

    assert_eq!(
        client
            .exchange(&common::worked_example(3, 1), Duration::from_millis(300))
            .unwrap(),
        None
    );
    let answer = client.exchange(&common::worked_example(3, 2), WAIT).unwrap().unwrap();
    assert_eq!(answer, common::canned_decision(3, 2));
    server.stop();
}

/// The client has no thread of its own: the first waiting exchange polls the reply reader
/// and routes the others' answers. Here it gives up (a short wait) while two others wait
/// for answers that come only afterwards: one of them must take over the polling, or both
/// time out with their answers unread.
#[test]
fn a_waiting_exchange_takes_over_when_the_polling_one_leaves() {
    common::setup();
    let (arrived, arrivals) = mpsc::channel::<(u64, Reply)>();
    let arrived = Mutex::new(arrived);
    let options = ServerOptions {
        node: common::node("hmdp_planner", 5),
        ..ServerOptions::default()
    };
    let server = PlanServer::start(options, move |incoming, _, reply| {
        let Incoming::Request(request) = incoming else {
            panic!("only decodable requests here");
        };
        if request.is_probe() {
            reply(common::canned_decision(request.vehicle_id, request.sequence));
            return;
        }
        arrived.lock().unwrap().send((request.vehicle_id, reply)).unwrap();
    })
    .expect("the server starts");
    let client = Arc::new(client(5, "hmdp_vehicle_takeover"));
    client.wait_for_service(DISCOVERY).expect("the server is found");

    // Vehicle 1 asks first and alone, so it is the one polling; it waits 300 ms.
    let first = {
        let client = Arc::clone(&client);
        thread::spawn(move || client.exchange(&common::worked_example(1, 1), Duration::from_millis(300)))
    };
    let (vehicle, reply_1) = arrivals.recv_timeout(WAIT).expect("vehicle 1's request arrives");
    assert_eq!(vehicle, 1);
    let others: Vec<_> = (2..=3u64)
        .map(|vehicle| {
            let client = Arc::clone(&client);
            thread::spawn(move || client.exchange(&common::worked_example(vehicle, 1), WAIT))
        })
        .collect();
    let mut replies: Vec<_> = (0..2)
        .map(|_| arrivals.recv_timeout(WAIT).expect("the others' requests arrive"))
        .collect();
    assert_eq!(
        first.join().unwrap().expect("no error"),
        None,
        "vehicle 1 was not answered"
    );

    replies.sort_by_key(|(vehicle, _)| *vehicle);
    for (vehicle, reply) in replies {
        reply(common::canned_decision(vehicle, 1));
    }
    for (vehicle, other) in (2..=3u64).zip(others) {
        let answer = other.join().unwrap().expect("no error").expect("answered");
        assert_eq!(answer, common::canned_decision(vehicle, 1));
    }
    // Vehicle 1's answer, late: nobody takes it.
    reply_1(common::canned_decision(1, 1));
    server.stop();
}

#[test]
fn without_a_server_waiting_fails_in_time() {
    common::setup();
    let client = client(3, "hmdp_vehicle_alone");
    let error = client.wait_for_service(Duration::from_millis(500)).unwrap_err();
    assert!(
        matches!(error, hmdp_ros2::Ros2Error::ServiceUnavailable { .. }),
        "{error}"
    );
    assert_eq!(
        client
            .exchange(&common::worked_example(1, 1), Duration::from_millis(100))
            .unwrap(),
        None
    );
}

/// What a peer with another `hmdp_msgs` might send: the first three fields only.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct ShortRequest {
    version: u16,
    vehicle_id: u64,
    sequence: u64,
}

impl ros2_client::Message for ShortRequest {}

/// Runs `f` on a thread of its own and waits at most `timeout` for it (a hung DDS call
/// fails the test instead of hanging it).
fn within<T: Send + 'static>(timeout: Duration, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (done, result) = mpsc::channel();
    thread::spawn(move || {
        let _ = done.send(f());
    });
    result.recv_timeout(timeout).expect("finished in time")
}

#[test]
fn an_undecodable_request_is_answered_malformed_with_the_ids_read() {
    use ros2_client::dds::rustdds::DomainParticipantBuilder;
    use ros2_client::qos::{Durability, History, WhenFull};
    use ros2_client::{Context, Name, NodeName, NodeOptions, QosProfile, ServiceMapping, ServiceTypeName};

    common::setup();
    let seen = Seen::default();
    let server = canned_server(4, &seen);

    let participant = DomainParticipantBuilder::new(common::domain(4))
        .with_only_networks([std::net::IpAddr::from([127, 0, 0, 1])])
        .build()
        .unwrap();
    let context = Context::from_domain_participant(participant).unwrap();
    let options = NodeOptions::new().enable_rosout(false).start_parameter_services(false);
    let mut node = context
        .new_node(NodeName::new("/", "hmdp_garbler").unwrap(), options)
        .unwrap();
    let spinner = node.spinner().unwrap();
    thread::spawn(move || futures::executor::block_on(spinner.spin()));
    let qos = QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 });
    let client = node
        .create_client::<ShortRequest, hmdp_ros2::incoming::IncomingResponse>(
            ServiceMapping::Enhanced,
            &Name::parse("/hmdp/plan").unwrap(),
            &ServiceTypeName::new("hmdp_msgs", "Plan"),
            qos.clone(),
            qos,
        )
        .unwrap();
    let (node, client) = (Arc::new(node), Arc::new(client));
    {
        let (node, client) = (Arc::clone(&node), Arc::clone(&client));
        within(DISCOVERY, move || {
            futures::executor::block_on(client.wait_for_service(&node))
        });
    }
    let short = ShortRequest {
        version: 3,
        vehicle_id: 5,
        sequence: 77,
    };
    let id = client.send_request(short).expect("sent");
    let answer = {
        let client = Arc::clone(&client);
        within(WAIT, move || {
            futures::executor::block_on(client.async_receive_response(id))
        })
    };
    let hmdp_ros2::incoming::IncomingResponse::Decoded(message) = answer.expect("read") else {
        panic!("the answer decodes");
    };
    let answer = PlanResponse::try_from(message).expect("a protocol answer");
    assert_eq!((answer.vehicle_id, answer.sequence), (5, 77));
    let rejected = answer.outcome.as_rejected().expect("a rejection");
    assert_eq!(rejected.reason(), Ok(RejectReason::Malformed));
    assert_eq!(seen.lock().unwrap().get(&(5, 77)), Some(&1));
    assert_eq!(server.counters().undecodable, 1);
    server.stop();
}
