//! The live view of a running planner: `planner serve --zenoh-listen ... --foxglove ADDR`
//! (a free port), a vehicle asking over Zenoh, and a WebSocket client speaking Foxglove's
//! protocol (`live_view::client`) that must receive the request, its answer and its scene
//! while the planner runs, byte for byte as the vehicle sent and got them.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use live_view::client::{Received, WatchClient};
use recording::{PLANNER_SCENE_TOPIC, REQUEST_TOPIC, RESPONSE_TOPIC, STATS_TOPIC};
use system_tests::{free_port, worked_example_request, ZenohPlanner};
use transport::PlanChannel;

/// Upper bound of every wait (a debug build on a loaded machine), never a delay.
const PATIENCE: Duration = Duration::from_secs(60);
/// How long one request's messages may take to show up before the next request is sent
/// (the subscription reaches the planner at its own pace; the protocol does not confirm it).
const PER_REQUEST: Duration = Duration::from_secs(2);

/// The live messages of `(vehicle, sequence)` that arrive by `deadline`, by topic.
fn messages_of(watch: &mut WatchClient, vehicle: u64, sequence: u64, deadline: Instant) -> Vec<Received> {
    let mut got = Vec::new();
    while got.len() < 3 {
        let Some(m) = watch.next_message(deadline).expect("the live view reads") else {
            break;
        };
        let json: serde_json::Value = serde_json::from_slice(&m.data).expect("JSON");
        let ours = match m.topic.as_str() {
            REQUEST_TOPIC | RESPONSE_TOPIC => json["vehicle_id"] == vehicle && json["sequence"] == sequence,
            // The scene of an answer carries no ids: it follows the answer.
            PLANNER_SCENE_TOPIC => got.iter().any(|r: &Received| r.topic == RESPONSE_TOPIC),
            _ => false,
        };
        if ours {
            got.push(m);
        }
    }
    got
}

#[test]
fn a_running_planner_shows_requests_answers_and_scenes_live() {
    let addr: SocketAddr = format!("127.0.0.1:{}", free_port()).parse().expect("address");
    let planner = ZenohPlanner::start("live-view", &["--foxglove", &addr.to_string()]);
    // The live view listens before the service starts: once the planner answers, it is there.
    let mut vehicle = planner.vehicle(None);
    let mut watch = WatchClient::connect(addr, PATIENCE).unwrap_or_else(|e| panic!("{e}\n{}", planner.log()));
    assert_eq!(watch.server_name, "hmdp planner");
    let deadline = Instant::now() + PATIENCE;
    watch
        .subscribe(
            &[REQUEST_TOPIC, RESPONSE_TOPIC, PLANNER_SCENE_TOPIC, STATS_TOPIC],
            deadline,
        )
        .expect("subscribed");
    for (topic, schema) in [
        (REQUEST_TOPIC, "hmdp.PlanRequest"),
        (RESPONSE_TOPIC, "hmdp.PlanResponse"),
        (STATS_TOPIC, "hmdp.PlannerStats"),
        (PLANNER_SCENE_TOPIC, "foxglove.SceneUpdate"),
    ] {
        let c = watch.channels().iter().find(|c| c.topic == topic).expect("advertised");
        assert_eq!(
            (c.schema_name.as_str(), c.encoding.as_str()),
            (schema, "json"),
            "{topic}"
        );
    }

    // Until one exchange shows up whole (the first ones may go before the subscriptions
    // are in place, one channel's before another's).
    let vehicle_id = 4242;
    let mut last = Vec::new();
    let (request, response, got) = (1..)
        .find_map(|sequence| {
            assert!(
                Instant::now() < deadline,
                "no exchange shown live; last seen {:?}\n{}",
                last.iter().map(|m: &Received| m.topic.clone()).collect::<Vec<_>>(),
                planner.log()
            );
            let request = worked_example_request(vehicle_id, sequence);
            let answer = vehicle
                .exchange(request.clone(), Duration::from_secs(5))
                .expect("exchange");
            let response = answer.response.expect("answered");
            assert!(response.outcome.as_decided().is_some(), "{response:?}");
            last = messages_of(&mut watch, vehicle_id, sequence, Instant::now() + PER_REQUEST);
            let topics: Vec<&str> = last.iter().map(|m| m.topic.as_str()).collect();
            (topics == [REQUEST_TOPIC, RESPONSE_TOPIC, PLANNER_SCENE_TOPIC]).then(|| (request, response, last.clone()))
        })
        .expect("an exchange");
    // What the vehicle sent and got, in the recording's JSON.
    let sent: protocol::PlanRequest = recording::json::from_slice(&got[0].data).expect("a request");
    assert_eq!(sent, request);
    assert_eq!(got[1].data, recording::json::to_vec(&response).expect("JSON"));
    let scene = recording::scene::plan_scene(&request, &response, got[2].log_time_ns);
    let shown: serde_json::Value = serde_json::from_slice(&got[2].data).expect("JSON");
    assert_eq!(shown, scene);
    assert_eq!(got[2].log_time_ns, got[1].log_time_ns);

    // And the statistics, once a second, counting the answers.
    let stats = loop {
        let m = watch
            .next_message(deadline)
            .expect("read")
            .expect("statistics within the patience");
        if m.topic == STATS_TOPIC {
            break m;
        }
    };
    let stats: serde_json::Value = serde_json::from_slice(&stats.data).expect("JSON");
    assert!(stats["answered"].as_u64().is_some_and(|n| n >= 1), "{stats}");
}
