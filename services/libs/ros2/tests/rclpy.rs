//! Interoperation with a real ROS 2 (rclpy on rmw_fastrtps_cpp, Kilted, from the venv of
//! `scripts/ros2-env`): an rclpy client calls our server, our client calls an rclpy server,
//! and an rclpy node subscribes to what our server publishes. Loopback discovery, a domain
//! of this process's own (`ROS_DOMAIN_ID` set by `common::setup`).

mod common;

use std::io::{BufRead, BufReader, Write};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use hmdp_ros2::msg;
use hmdp_ros2::{ClientOptions, Incoming, MarkersFor, PlanClient, PlanServer, ServerOptions};
use protocol::PlanResponse;

/// The environment of the python processes: test domain `k`, loopback discovery.
fn ros_env(k: u32) -> Vec<(&'static str, String)> {
    common::setup();
    vec![
        ("ROS_DOMAIN_ID", common::domain(k).to_string()),
        ("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST".to_owned()),
    ]
}

/// Serves canned decisions (or the conversion's rejection); domain from `ROS_DOMAIN_ID`.
fn canned_server(markers: MarkersFor) -> PlanServer {
    let options = ServerOptions {
        markers,
        ..ServerOptions::default()
    };
    PlanServer::start(options, |incoming, _, reply| match incoming {
        Incoming::Request(r) => reply(common::canned_decision(r.vehicle_id, r.sequence)),
        Incoming::Undecodable {
            vehicle_id,
            sequence,
            rejected,
        } => reply(PlanResponse::rejected(vehicle_id, sequence, rejected, 0)),
    })
    .expect("the server starts")
}

/// Calls /hmdp/plan once with the request on stdin and prints the response as JSON.
const CALL: &str = r#"
import rclpy
from hmdp_msgs.srv import Plan
rclpy.init()
node = rclpy.create_node('hmdp_rclpy_vehicle')
client = node.create_client(Plan, '/hmdp/plan')
if not client.wait_for_service(timeout_sec=20.0):
    sys.exit('no /hmdp/plan within 20 s')
future = client.call_async(Plan.Request(request=fill(message_class('hmdp_msgs/PlanRequest')(), json.load(sys.stdin))))
rclpy.spin_until_future_complete(node, future, timeout_sec=20.0)
if not future.done():
    sys.exit('no answer within 20 s')
print(json.dumps(to_dict(future.result().response)))
"#;

#[test]
fn an_rclpy_client_gets_the_planners_answer() {
    // Domain 0 of the test: the server takes it from ROS_DOMAIN_ID, as a ROS node does.
    let env = ros_env(0);
    let server = canned_server(MarkersFor::Nobody);
    let request = msg::PlanRequest::from(&common::worked_example(7, 42));
    let script = format!("{}{CALL}", common::PY_MESSAGES);
    let out = common::python(&script, &[], &serde_json::to_string(&request).unwrap(), &env);
    assert!(
        out.status.success(),
        "the rclpy client failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let answer: msg::PlanResponse = serde_json::from_slice(&out.stdout).expect("the response as JSON");
    assert_eq!(answer, msg::PlanResponse::from(&common::canned_decision(7, 42)));
    assert_eq!(server.counters().received, 1);
    server.stop();
}

/// Serves /hmdp/plan: the canned decision (JSON of our message, stdin) with the request's
/// ids; exits after answering sequence 99. Prints `ready` once the service exists.
const SERVE: &str = r#"
import time, rclpy
from hmdp_msgs.srv import Plan
canned = json.loads(sys.stdin.readline())
rclpy.init()
node = rclpy.create_node('hmdp_rclpy_planner')
done = []
def answer(request, response):
    fill(response.response, canned)
    response.response.vehicle_id = request.request.vehicle_id
    response.response.sequence = request.request.sequence
    if request.request.sequence == 99:
        done.append(time.monotonic())
    return response
service = node.create_service(Plan, '/hmdp/plan', answer)
print('ready', flush=True)
end = time.monotonic() + 60
while time.monotonic() < end and not (done and time.monotonic() > done[0] + 1.0):
    rclpy.spin_once(node, timeout_sec=0.1)
sys.exit(0 if done else 'sequence 99 never came')
"#;

fn spawn_python(script: &str, stdin_line: &str, env: &[(&str, String)]) -> Child {
    let mut command = Command::new(common::venv().join("bin/python"));
    command
        .arg("-c")
        .arg(format!("{}{script}", common::PY_MESSAGES))
        .env("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    for (key, value) in env {
        command.env(key, value);
    }
    let mut child = command.spawn().expect("python starts");
    let mut stdin = child.stdin.take().expect("piped");
    writeln!(stdin, "{stdin_line}").expect("python reads");
    child
}

/// The first line python prints (after it has set up).
fn first_line(child: &mut Child) -> String {
    let mut line = String::new();
    BufReader::new(child.stdout.as_mut().expect("piped"))
        .read_line(&mut line)
        .expect("python prints");
    line
}

#[test]
fn our_client_gets_an_rclpy_servers_answer() {
    let env = ros_env(2);
    let canned = msg::PlanResponse::from(&common::canned_decision(0, 0));
    let mut python = spawn_python(SERVE, &serde_json::to_string(&canned).unwrap(), &env);
    assert_eq!(first_line(&mut python).trim(), "ready", "the rclpy service started");

    let client = PlanClient::new(ClientOptions {
        node: common::node("hmdp_vehicle_rust", 2),
    })
    .expect("the client starts");
    client
        .wait_for_service(Duration::from_secs(20))
        .expect("the rclpy service is found");
    for sequence in [1, 2, 3, 99] {
        let answer = client
            .exchange(&common::worked_example(11, sequence), Duration::from_secs(10))
            .expect("no error")
            .expect("answered in time");
        assert_eq!(answer, common::canned_decision(11, sequence));
    }
    let out = python.wait_with_output().expect("python ends");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// Subscribes to /hmdp/decisions and /hmdp/plan_markers, prints `ready` when both are
/// matched, then the first decision for vehicle 21 and the first marker array as JSON lines
/// (`["decision", {...}]`, `["markers", {...}]`).
const OBSERVE: &str = r#"
import time, rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from hmdp_msgs.msg import PlanResponse
from visualization_msgs.msg import MarkerArray
rclpy.init()
node = rclpy.create_node('hmdp_rclpy_observer')
got = {}
def keep(kind):
    def callback(message):
        if kind == 'decision' and message.vehicle_id != 21:
            return
        if kind not in got:
            got[kind] = message
            print(json.dumps([kind, to_dict(message)]), flush=True)
    return callback
qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
node.create_subscription(PlanResponse, '/hmdp/decisions', keep('decision'), qos)
node.create_subscription(MarkerArray, '/hmdp/plan_markers', keep('markers'), qos)
end = time.monotonic() + 20
while time.monotonic() < end and (node.count_publishers('/hmdp/decisions') == 0 or node.count_publishers('/hmdp/plan_markers') == 0):
    rclpy.spin_once(node, timeout_sec=0.05)
print('ready', flush=True)
end = time.monotonic() + 30
while time.monotonic() < end and len(got) < 2:
    rclpy.spin_once(node, timeout_sec=0.1)
sys.exit(0 if len(got) == 2 else 'missing: %s' % ({'decision', 'markers'} - set(got)))
"#;

#[test]
fn an_rclpy_node_receives_the_decisions_and_the_markers() {
    let env = ros_env(1);
    let options = ServerOptions {
        node: common::node("hmdp_planner", 1),
        // Not for the client's readiness probes.
        markers: MarkersFor::Vehicle(21),
        ..ServerOptions::default()
    };
    let server = PlanServer::start(options, |incoming, _, reply| {
        if let Incoming::Request(r) = incoming {
            reply(common::canned_decision(r.vehicle_id, r.sequence));
        }
    })
    .expect("the server starts");
    let mut python = spawn_python(OBSERVE, "", &env);
    assert_eq!(
        first_line(&mut python).trim(),
        "ready",
        "the rclpy observer matched our topics"
    );
    server
        .wait_for_decision_subscriber(Duration::from_secs(20))
        .expect("matched");

    let client = PlanClient::new(ClientOptions {
        node: common::node("hmdp_vehicle_observed", 1),
    })
    .expect("the client starts");
    client.wait_for_service(Duration::from_secs(20)).expect("found");
    let request = common::worked_example(21, 8);
    // Until rclpy has both (our server may not yet count its marker subscription).
    let mut decision = None;
    let mut markers = None;
    let lines = BufReader::new(python.stdout.take().expect("piped")).lines();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in lines.map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    for attempt in 0..50 {
        let answer = client.exchange(&request, Duration::from_secs(10)).unwrap().unwrap();
        assert_eq!(answer.sequence, 8, "attempt {attempt}");
        while let Ok(line) = rx.recv_timeout(Duration::from_millis(200)) {
            let (kind, body): (String, serde_json::Value) = serde_json::from_str(&line).expect("a JSON line");
            match kind.as_str() {
                "decision" => decision = Some(serde_json::from_value::<msg::PlanResponse>(body).unwrap()),
                _ => markers = Some(serde_json::from_value::<msg::viz::MarkerArray>(body).unwrap()),
            }
        }
        if decision.is_some() && markers.is_some() {
            break;
        }
    }
    assert_eq!(decision, Some(msg::PlanResponse::from(&common::canned_decision(21, 8))));
    let markers = markers.expect("rclpy got the markers");
    assert_eq!(markers.markers[0].action, msg::viz::Marker::DELETEALL);
    let expected = hmdp_ros2::markers::plan_markers(
        &request,
        &common::canned_decision(21, 8),
        markers.markers[0].header.stamp,
    );
    assert_eq!(markers, expected);
    let out = python.wait_with_output().expect("python ends");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    server.stop();
}
