//! What the tests share: the ROS 2 venv (rclpy and hmdp_msgs), a private DDS domain, the
//! environment every node reads, and canned answers.
#![allow(dead_code)]

use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Output, Stdio};
use std::sync::Once;

use hmdp_ros2::NodeConfig;
use protocol::{PlanResponse, RejectReason, Rejected};

/// The venv with rclpy, rmw_fastrtps and hmdp_msgs: `HMDP_ROS2_VENV`, by default
/// `<workspace>/target/ros2-venv` (built by `scripts/ros2-env`). Missing is a failure, not
/// a skip: CI builds it, and a test that passes without running proves nothing.
pub fn venv() -> PathBuf {
    let path = std::env::var_os("HMDP_ROS2_VENV").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../target/ros2-venv"),
        PathBuf::from,
    );
    assert!(
        path.join("bin/python").exists(),
        "no ROS 2 venv at {}: build it with `scripts/ros2-env target/ros2-venv` (CI does), \
         or set HMDP_ROS2_VENV to one with rclpy, rmw_fastrtps_cpp and hmdp_msgs",
        path.display()
    );
    path
}

/// Runs `script` with the venv's python: `args` as `sys.argv[1..]`, `stdin` on its
/// standard input, `env` added to the environment.
pub fn python(script: &str, args: &[&str], stdin: &str, env: &[(&str, String)]) -> Output {
    let mut command = Command::new(venv().join("bin/python"));
    command
        .arg("-c")
        .arg(script)
        .args(args)
        .env("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    for (key, value) in env {
        command.env(key, value);
    }
    let mut child = command.spawn().expect("the venv's python starts");
    child
        .stdin
        .take()
        .expect("stdin is piped")
        .write_all(stdin.as_bytes())
        .expect("python reads its input");
    child.wait_with_output().expect("python runs")
}

/// Python helpers: a ROS message from the JSON of our message structs (serde_json, ROS
/// field names) and back, for any message type rclpy has.
pub const PY_MESSAGES: &str = r#"
import array, importlib, json, sys

def message_class(type_name):
    if type_name.startswith('sequence<'):
        type_name = type_name[len('sequence<'):-1].split(',')[0]
    package, name = type_name.split('/')
    return getattr(importlib.import_module(package + '.msg'), name)

def fill(message, document):
    types = message.get_fields_and_field_types()
    for key, value in document.items():
        if isinstance(value, dict):
            fill(getattr(message, key), value)
        elif isinstance(value, list) and '/' in types[key]:
            setattr(message, key, [fill(message_class(types[key])(), item) for item in value])
        else:
            setattr(message, key, value)
    return message

def to_dict(message):
    out = {}
    for key in message.get_fields_and_field_types():
        value = getattr(message, key)
        if hasattr(value, 'get_fields_and_field_types'):
            out[key] = to_dict(value)
        elif isinstance(value, list):
            out[key] = [to_dict(item) if hasattr(item, 'get_fields_and_field_types') else item for item in value]
        elif hasattr(value, 'tolist'):
            out[key] = [int(x) for x in value.tolist()] if isinstance(value, array.array) else value.tolist()
        else:
            out[key] = value
    return out
"#;

/// A DDS domain for test `k` (0..8) of this process, in 100..=230: tests running at once
/// (threads here, other test binaries, other checkouts) do not see each other's servers.
pub fn domain(k: u32) -> u16 {
    assert!(k < 8);
    let slot = std::process::id() % 16 * 8 + k;
    u16::try_from(100 + slot).expect("a small number")
}

/// Loopback discovery for every node of this process, set once before any is created.
pub fn setup() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        std::env::set_var("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST");
        std::env::set_var("ROS_DOMAIN_ID", domain(0).to_string());
    });
}

/// A node on test domain `k`, discovery from the environment.
pub fn node(name: &str, k: u32) -> NodeConfig {
    NodeConfig {
        domain_id: Some(domain(k)),
        ..NodeConfig::named(name)
    }
}

/// `protocol::worked_example_request` with the memory of docs/protocol.md's worked example
/// (previous plan: one action, (0, +1)).
pub fn worked_example(vehicle_id: u64, sequence: u64) -> protocol::PlanRequest {
    let mut request = protocol::worked_example_request(vehicle_id, sequence);
    let previous = [protocol::Action {
        lateral: 0,
        longitudinal: 1,
    }];
    request.memory.previous_plan = protocol::bounded("memory.previous_plan", &previous).expect("one action");
    request
}

/// The decision of docs/protocol.md's JSON example, signed with the example key.
pub const DOCUMENTED_DECISION: &str = r#"{"version":3,"vehicle_id":7,"sequence":42,"solve_us":1850,"queue_us":12,
  "outcome":{"decided":{"action":{"lateral":0,"longitudinal":0},"next_maneuver":{"lane":2,"beta":0},
  "setpoint":{"accel_mps2":0.0,"target_speed_mps":25.0},
  "plan":[{"action":{"lateral":0,"longitudinal":0},"maneuver":{"lane":2,"beta":0},"x_m":10.0,"v_mps":25.0,"occupied_lanes":2},
          {"action":{"lateral":-1,"longitudinal":0},"maneuver":{"lane":1,"beta":0},"x_m":20.0,"v_mps":25.0,"occupied_lanes":3}],
  "layer":"nominal",
  "memory":{"corrective":[{"sv_id":1,"release_m":40.0,"trigger_m":30.0}],
            "previous_plan":[{"lateral":0,"longitudinal":0},{"lateral":-1,"longitudinal":0}]}}},
  "signature":"be69c041e2adb2ea3b270268b2d6ed6e425e505567b2449f571bfdd8d9f3601c5ab97228565b5ef0e2ab74ec6ae85b59c427a024f4a8ad489bc300ee4c763e02"}"#;

/// The documented decision, echoing `vehicle_id` and `sequence`.
pub fn canned_decision(vehicle_id: u64, sequence: u64) -> PlanResponse {
    let mut response: PlanResponse = protocol::decode_json_str(DOCUMENTED_DECISION).expect("the documented decision");
    response.vehicle_id = vehicle_id;
    response.sequence = sequence;
    response
}

/// The documented rejection (`negative_speed` of `ego.v_mps`).
pub fn canned_rejection(vehicle_id: u64, sequence: u64) -> PlanResponse {
    PlanResponse::rejected(
        vehicle_id,
        sequence,
        Rejected::new(RejectReason::NegativeSpeed, "ego.v_mps"),
        5,
    )
}
