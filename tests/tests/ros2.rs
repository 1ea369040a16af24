//! The planner as a ROS 2 node (`planner serve --ros2`, docs/ros2.md), with real partners:
//! rclpy on Fast DDS from the venv of `scripts/ros2-env`, and the simulator over ROS 2.
//! Every test has a DDS domain of its own and discovers on loopback only; every wait for
//! discovery is bounded and event-driven (the tools wait for the service or the match).

use std::time::Duration;

use hmdp_ros2::msg;
use protocol::{OutcomeRef, RejectReason};
use system_tests::ros2::{rclpy_client, venv, Domain};
use system_tests::{case1_decisions_with_env, free_port, scratch_dir, Process};

fn path_str(p: &std::path::Path) -> &str {
    p.to_str().expect("a UTF-8 path")
}

/// The simulator drives the paper's Case 1 over ROS 2 and over Zenoh, each against its own
/// planner: the decisions are the same, bit for bit.
#[test]
fn case1_over_ros2_decides_exactly_as_over_zenoh() {
    let domain = Domain::new(0);
    let dir = scratch_dir("ros2-case1");
    let env = domain.env();
    let no_log = String::new;
    let ros2 = case1_decisions_with_env(&dir, "ros2", &["--transport", "ros2", "--spawn-planner"], &env, &no_log);
    let zenoh = case1_decisions_with_env(
        &dir,
        "zenoh",
        &["--transport", "zenoh", "--spawn-planner"],
        &env,
        &no_log,
    );
    assert!(ros2.len() > 1000, "a full Case 1 run");
    assert!(ros2 == zenoh, "decisions.csv differs between ROS 2 and Zenoh");
}

/// One planner serves Zenoh and ROS 2 and records: the simulator drives Case 1 over Zenoh,
/// then an rclpy node sends every recorded request over `/hmdp/plan` and gets, in every
/// field of every answer, what the vehicle got over Zenoh.
#[test]
fn rclpy_gets_the_answers_the_zenoh_vehicle_got() {
    let domain = Domain::new(1);
    let dir = scratch_dir("ros2-replay");
    let recording = dir.join("planner.mcap");
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let mut planner = Process::start_with_env(
        "planner",
        &[
            "serve",
            "--ros2",
            "--zenoh-listen",
            &endpoint,
            "--workers",
            "2",
            "--record",
            path_str(&recording),
        ],
        "ros2-replay-planner",
        &domain.env(),
    );
    case1_decisions_with_env(
        &dir,
        "zenoh",
        &["--transport", "zenoh", "--zenoh-connect", &endpoint],
        &[],
        &|| planner.log(),
    );
    // The recording is complete once the planner has stopped.
    assert!(
        planner.terminate(Duration::from_secs(30)).is_some_and(|s| s.success()),
        "{}",
        planner.log()
    );
    let planner = Process::start_with_env(
        "planner",
        &["serve", "--ros2", "--workers", "2"],
        "ros2-replay-second",
        &domain.env(),
    );
    let (report, out) = rclpy_client(
        &domain,
        &[
            "replay",
            path_str(&recording),
            "--timeout",
            "10",
            "--discovery-timeout",
            "60",
        ],
    );
    let shown = || {
        format!(
            "{report}\n{}\nplanner:\n{}",
            String::from_utf8_lossy(&out.stderr),
            planner.log()
        )
    };
    assert!(out.status.success(), "{}", shown());
    assert!(report["sent"].as_u64().unwrap_or(0) >= 100, "{}", shown());
    assert_eq!(report["identical"], report["sent"], "{}", shown());
    assert_eq!(report["different"], 0, "{}", shown());
    assert_eq!(report["unanswered"], 0, "{}", shown());
}

/// rclpy sends requests the planner must refuse (a longitudinal state of 5, a NaN speed,
/// lane 0, two SVs with one id): each gets its typed rejection naming the field.
#[test]
fn rclpy_gets_typed_rejections() {
    let domain = Domain::new(2);
    let planner = Process::start_with_env(
        "planner",
        &["serve", "--ros2", "--workers", "2"],
        "ros2-reject",
        &domain.env(),
    );
    let (report, out) = rclpy_client(&domain, &["reject", "--timeout", "10", "--discovery-timeout", "60"]);
    let shown = || {
        format!(
            "{report}\n{}\nplanner:\n{}",
            String::from_utf8_lossy(&out.stderr),
            planner.log()
        )
    };
    assert!(out.status.success(), "{}", shown());
    let cases = report.as_array().expect("a list of cases");
    let reasons: Vec<(&str, &str)> = cases
        .iter()
        .map(|c| {
            (
                c["reason_name"].as_str().unwrap_or(""),
                c["field"].as_str().unwrap_or(""),
            )
        })
        .collect();
    assert_eq!(
        reasons,
        [
            ("beta_out_of_range", "ego.maneuver.beta"),
            ("non_finite", "ego.v_mps"),
            ("lane_out_of_range", "ego.maneuver.lane"),
            ("duplicate_sv_id", "sv.id"),
        ],
        "{}",
        shown()
    );
}

/// What a bad peer can send that rclpy's checks would stop: 65 SVs, over the protocol's
/// capacity of 64, is refused with `capacity_exceeded` naming the list and the request's
/// ids; the planner keeps serving the next request.
#[test]
fn sixty_five_svs_over_ros2_are_a_typed_rejection() {
    let domain = Domain::new(3);
    let planner = Process::start_with_env(
        "planner",
        &["serve", "--ros2", "--workers", "2"],
        "ros2-capacity",
        &domain.env(),
    );
    let client = domain.plan_client("test_vehicle", &planner, Duration::from_secs(60));
    let mut request = msg::PlanRequest::from(&protocol::worked_example_request(9, 1));
    let sv = request.svs[0];
    request.svs = (0..65u32).map(|id| msg::SvObservation { id, ..sv }).collect();
    let answer = client
        .exchange_msg(request, Duration::from_secs(10))
        .expect("an exchange")
        .expect("an answer");
    assert_eq!((answer.vehicle_id, answer.sequence), (9, 1));
    match answer.outcome.get().expect("a valid outcome") {
        OutcomeRef::Rejected(r) => assert_eq!((r.reason(), r.field()), (Ok(RejectReason::CapacityExceeded), "svs")),
        OutcomeRef::Decided(_) => panic!("65 SVs were decided"),
    }
    let next = client
        .exchange(&protocol::worked_example_request(9, 2), Duration::from_secs(10))
        .expect("an exchange")
        .expect("an answer");
    assert!(next.outcome.as_decided().is_some(), "{next:?}\n{}", planner.log());
}

/// An rclpy node subscribed to `/hmdp/decisions` and `/hmdp/plan_markers` gets every answer
/// and the markers of the plan (ego plan, occupied lanes, the SVs and their predictions).
#[test]
fn rclpy_receives_the_decisions_and_the_markers() {
    let domain = Domain::new(4);
    let planner = Process::start_with_env(
        "planner",
        &["serve", "--ros2", "--workers", "2"],
        "ros2-markers",
        &domain.env(),
    );
    let (report, out) = rclpy_client(
        &domain,
        &[
            "markers",
            "--count",
            "5",
            "--timeout",
            "10",
            "--discovery-timeout",
            "60",
        ],
    );
    let shown = || {
        format!(
            "{report}\n{}\nplanner:\n{}",
            String::from_utf8_lossy(&out.stderr),
            planner.log()
        )
    };
    assert!(out.status.success(), "{}", shown());
    assert_eq!(report["decisions_of_these_requests"], 5, "{}", shown());
    assert!(report["marker_arrays"].as_u64().unwrap_or(0) >= 5, "{}", shown());
    let namespaces = report["last_marker_array"]["namespaces"]
        .as_object()
        .expect("namespaces");
    for ns in ["ego_plan", "occupied_lanes", "svs", "sv_ids", "sv_predictions"] {
        assert!(
            namespaces.get(ns).and_then(|n| n.as_u64()).unwrap_or(0) > 0,
            "no {ns}: {}",
            shown()
        );
    }
}

/// The rclpy tool's own tests (conversions, CDR bytes, every subcommand against a mock
/// planner node): the tool the other tests trust.
#[test]
fn the_rclpy_tool_passes_its_own_tests() {
    let domain = Domain::new(5);
    // The no-planner case needs a domain no other test's planner is on: reserve one too.
    let empty = Domain::new(6);
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../clients/ros2");
    let out = domain
        .command(venv().join("bin/python"))
        .env("HMDP_TEST_EMPTY_DOMAIN", empty.id().to_string())
        .args(["-m", "unittest", "discover", "-s"])
        .arg(&dir)
        .output()
        .expect("the venv's python runs");
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
