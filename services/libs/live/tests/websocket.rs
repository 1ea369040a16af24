//! The live view from outside: a WebSocket client speaking Foxglove's protocol
//! (`live_view::client`, written from the protocol's specification) against the server.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

use live_view::client::{ClientError, WatchClient};
use live_view::{LiveOptions, LiveServer, PlannerView};
use protocol::{EgoState, PlanRequest, PlanResponse, RejectReason, Rejected, Road, SvObservation};
use recording::{
    ChannelSpec, Observers, PlanObserver, PLANNER_CHANNELS, PLANNER_SCENE_TOPIC, REQUEST_TOPIC, RESPONSE_TOPIC,
    STATS_TOPIC,
};

/// Upper bound of every wait (a loaded machine), never a delay.
const PATIENCE: Duration = Duration::from_secs(30);

fn options() -> LiveOptions {
    LiveOptions::new("127.0.0.1:0".parse().expect("address"), "live view test")
}

fn other_schema() -> serde_json::Value {
    serde_json::json!({ "type": "object" })
}

const OTHER: ChannelSpec = ChannelSpec {
    topic: "/test/other",
    schema_name: "test.Other",
    schema: other_schema,
};

fn deadline() -> Instant {
    Instant::now() + PATIENCE
}

fn connect(addr: SocketAddr) -> WatchClient {
    WatchClient::connect(addr, PATIENCE).expect("connects")
}

fn request(sequence: u64) -> PlanRequest {
    let road = Road {
        lanes: 3,
        lane_width_m: 3.5,
        speed_limit_mps: 30.0,
    };
    let ego = EgoState {
        x_m: 50.0,
        y_m: 3.5,
        v_mps: 25.0,
        desired_speed_mps: 28.0,
        ..EgoState::default()
    };
    PlanRequest {
        // A NaN: the recording's JSON writes it as "NaN", and so does the live view.
        svs: protocol::bounded("svs", &[SvObservation::new(3, 80.0, 3.5, f64::NAN, 0.0)]).expect("svs"),
        ..PlanRequest::new(7, sequence, 0, road, ego)
    }
}

#[test]
fn a_published_message_arrives_byte_for_byte_on_its_channel() {
    let server = LiveServer::start(&options(), &[PLANNER_CHANNELS[0].clone(), OTHER]).expect("server");
    let mut client = connect(server.local_addr());
    assert_eq!(client.server_name, "live view test");
    let advertised = client.wait_for_channel(REQUEST_TOPIC, deadline()).expect("advertised");
    assert_eq!(advertised.encoding, "json");
    assert_eq!(advertised.schema_name, "hmdp.PlanRequest");
    assert_eq!(advertised.schema_encoding, "jsonschema");
    let schema: serde_json::Value = serde_json::from_str(&advertised.schema).expect("schema is JSON");
    assert_eq!(schema, recording::schema::plan_request());
    client.wait_for_channel(OTHER.topic, deadline()).expect("advertised");

    client.subscribe(&[REQUEST_TOPIC], deadline()).expect("subscribed");
    assert!(
        server.wait_for_subscriber(REQUEST_TOPIC, PATIENCE),
        "the server saw the subscription"
    );
    let (request_channel, other) = (
        server.channel(REQUEST_TOPIC).unwrap(),
        server.channel(OTHER.topic).unwrap(),
    );
    assert!(server.is_watched(request_channel));
    assert!(!server.is_watched(other));

    // Not subscribed: never sent. Then the request, as the recording would hold it.
    server.publish(other, 1, b"{}".to_vec());
    let data = recording::json::to_vec(&request(1)).expect("encoded");
    assert!(String::from_utf8_lossy(&data).contains(r#""v_mps":"NaN""#));
    server.publish(request_channel, 1_767_225_600_123_456_789, data.clone());
    let got = client.next_message(deadline()).expect("read").expect("a message");
    assert_eq!(got.topic, REQUEST_TOPIC);
    assert_eq!(got.log_time_ns, 1_767_225_600_123_456_789);
    assert_eq!(got.data, data);
    let counters = server.counters();
    assert_eq!((counters.published, counters.dropped, counters.failed), (1, 0, 0));
    assert_eq!(server.clients(), 1);
}

/// The four messages of one exchange and a statistics document, by topic.
fn receive(client: &mut WatchClient, n: usize) -> Vec<live_view::client::Received> {
    let mut got: Vec<_> = (0..n)
        .map(|_| client.next_message(deadline()).expect("read").expect("a message"))
        .collect();
    got.sort_by(|a, b| a.topic.cmp(&b.topic));
    got
}

#[test]
fn the_planner_view_publishes_requests_answers_scenes_and_statistics() {
    let view = Arc::new(PlannerView::start(&options()).expect("view"));
    let mut client = connect(view.server().local_addr());
    let topics = [REQUEST_TOPIC, RESPONSE_TOPIC, STATS_TOPIC, PLANNER_SCENE_TOPIC];
    client.subscribe(&topics, deadline()).expect("subscribed");
    for topic in topics {
        assert!(view.server().wait_for_subscriber(topic, PATIENCE), "{topic}");
    }
    let scene_channel = client
        .channels()
        .iter()
        .find(|c| c.topic == PLANNER_SCENE_TOPIC)
        .cloned();
    assert_eq!(scene_channel.expect("scene").schema_name, "foxglove.SceneUpdate");

    let observers = Observers::new(vec![view.clone() as Arc<dyn PlanObserver>]);
    let request = request(2);
    let answer = PlanResponse::rejected(7, 2, Rejected::new(RejectReason::OutOfRange, "svs[0].v_mps"), 5);
    let (sent_tx, sent) = mpsc::channel();
    let reply = observers.wrap_reply(&request, Instant::now(), move |r| sent_tx.send(r).expect("sent"));
    reply(answer.clone());
    assert_eq!(sent.recv().expect("the transport got it"), answer);
    observers.stats(&serde_json::json!({ "answered": 1 }));

    let got = receive(&mut client, 4);
    let topics: Vec<&str> = got.iter().map(|m| m.topic.as_str()).collect();
    assert_eq!(
        topics,
        [REQUEST_TOPIC, RESPONSE_TOPIC, PLANNER_SCENE_TOPIC, STATS_TOPIC]
    );
    let (req, resp, scene, stats) = (&got[0], &got[1], &got[2], &got[3]);
    assert_eq!(req.data, recording::json::to_vec(&request).unwrap());
    assert_eq!(resp.data, recording::json::to_vec(&answer).unwrap());
    assert_eq!(stats.data, br#"{"answered":1}"#);
    // The scene of the answer, at the answer's time.
    assert_eq!(scene.log_time_ns, resp.log_time_ns);
    assert!(req.log_time_ns <= resp.log_time_ns);
    let expected = recording::scene::plan_scene(&request, &answer, resp.log_time_ns);
    assert_eq!(
        serde_json::from_slice::<serde_json::Value>(&scene.data).unwrap(),
        expected
    );
    assert_eq!(view.dropped(), 0);
}

#[test]
fn nothing_is_made_for_a_channel_nobody_watches() {
    let server = LiveServer::start(&options(), &[OTHER]).expect("server");
    let channel = server.channel(OTHER.topic).unwrap();
    // A client that subscribes to nothing.
    let _client = connect(server.local_addr());
    let built = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&built);
    server.publish_with(channel, 0, move || {
        flag.store(true, Ordering::SeqCst);
        Ok(Vec::new())
    });
    drop(server);
    assert!(!built.load(Ordering::SeqCst), "built for nobody");
}

#[test]
fn a_full_queue_drops_and_counts_instead_of_blocking() {
    let mut options = options();
    options.capacity = 1;
    let server = LiveServer::start(&options, &[OTHER]).expect("server");
    let mut client = connect(server.local_addr());
    client.subscribe(&[OTHER.topic], deadline()).expect("subscribed");
    assert!(server.wait_for_subscriber(OTHER.topic, PATIENCE));
    let channel = server.channel(OTHER.topic).unwrap();
    // The publisher thread takes the first message and waits in it until released.
    let (started_tx, started) = mpsc::channel();
    let (release, released) = mpsc::channel::<()>();
    server.publish_with(channel, 0, move || {
        started_tx.send(()).expect("test waits");
        let _ = released.recv();
        Ok(b"1".to_vec())
    });
    started.recv_timeout(PATIENCE).expect("the publisher took it");
    // One place: the second waits, the next three are dropped; none of these calls waits.
    for k in 2..=5u8 {
        server.publish(channel, 0, vec![b'0' + k]);
    }
    assert_eq!(server.counters().dropped, 3);
    release.send(()).expect("publisher waits");
    let first = client.next_message(deadline()).expect("read").expect("first");
    let second = client.next_message(deadline()).expect("read").expect("second");
    assert_eq!((first.data, second.data), (b"1".to_vec(), b"2".to_vec()));
}

#[test]
fn the_former_subprotocol_name_is_refused() {
    let server = LiveServer::start(&options(), &[OTHER]).expect("server");
    match WatchClient::connect_as(server.local_addr(), "foxglove.websocket.v1", PATIENCE) {
        Err(ClientError::Handshake(_)) => {}
        Err(e) => panic!("not a handshake refusal: {e}"),
        Ok(_) => panic!("foxglove.websocket.v1 accepted"),
    }
}

#[test]
fn dropping_the_server_stops_it() {
    let server = LiveServer::start(&options(), &[OTHER]).expect("server");
    let addr = server.local_addr();
    let mut client = connect(addr);
    drop(server);
    // The connection ends (a close frame or a reset), and nobody listens any more.
    match client.next_message(deadline()) {
        Err(_) => {}
        Ok(m) => panic!("still served: {m:?}"),
    }
    assert!(std::net::TcpStream::connect(addr).is_err(), "still listening on {addr}");
}

#[test]
fn an_address_in_use_is_a_typed_error() {
    let server = LiveServer::start(&options(), &[OTHER]).expect("server");
    let taken = LiveOptions::new(server.local_addr(), "second");
    match LiveServer::start(&taken, &[OTHER]) {
        Err(live_view::LiveError::Bind { addr, .. }) => assert_eq!(addr, server.local_addr()),
        other => panic!("{other:?}"),
    }
    let duplicate = LiveServer::start(&options(), &[OTHER, OTHER]);
    assert!(matches!(duplicate, Err(live_view::LiveError::DuplicateTopic(t)) if t == OTHER.topic));
}
