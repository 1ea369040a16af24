//! The Python client (`clients/python/hmdp_client.py`) with several planner instances: a
//! router (`hmdp-router`, loopback, a free port), two `planner serve` instances `alpha` and
//! `beta` connected to it, the client as a process.
//!
//! * The client's rendezvous hashing is the Rust channel's, bit for bit: both order the same
//!   instances the same way for every vehicle id tried, so a vehicle meets the same instance
//!   whichever client it runs.
//! * The instance the built-in snapshot's vehicle hashes to stopped with SIGSTOP (its
//!   liveliness token stays until its 3 s lease runs out): the client, with a 0.4 s timeout
//!   per request (the vehicle's deadline), still gets every decision, from the other
//!   instance, the first one after one retry. Without the retry it gets nothing: run with
//!   `HMDP_PY_RETRY_AFTER=10` (the client's `--retry-after`, longer than its timeout) to see
//!   this test fail.
//!
//! Needs `python3` with the `zenoh` module (`HMDP_SKIP_PYTHON=1` skips), and the `planner`
//! and `hmdp-router` binaries (`cargo test --workspace` builds them).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;
use system_tests::instances::{RoutedPlanners, INSTANCES};
use system_tests::{python_ready, run_to_end, scratch_dir, signal};
use transport::zenoh::instances::rendezvous_order;

/// How long the processes may take to start serving (debug builds on a shared machine).
/// The vehicle id of the client's built-in snapshot (`EXAMPLE_REQUEST`).
const EXAMPLE_VEHICLE: u64 = 7;
/// The vehicle's deadline, the client's `--timeout` per request.
const DEADLINE_S: &str = "0.4";
/// A client run that takes longer than this is hung: killed, and the test fails.
const CLIENT_LIMIT: Duration = Duration::from_secs(60);

fn ready() -> bool {
    python_ready(
        "zenoh",
        "run scripts/install-build-deps (it installs the pinned eclipse-zenoh of clients/python/requirements.txt)",
    )
}

fn client_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../clients/python")
}

/// What one client process did.
struct ClientRun {
    code: i32,
    /// The decision lines, parsed.
    lines: Vec<Value>,
    stdout: String,
    stderr: String,
}

impl ClientRun {
    fn report(&self) -> String {
        format!("exit {}\nstdout:\n{}\nstderr:\n{}", self.code, self.stdout, self.stderr)
    }
}

/// Runs `python3 hmdp_client.py args...` to its end ([`run_to_end`], killed after
/// CLIENT_LIMIT).
fn run_client(dir: &Path, args: &[&str]) -> ClientRun {
    let run = run_to_end(
        Command::new("python3")
            .arg(client_dir().join("hmdp_client.py"))
            .args(args),
        dir,
        "client",
        CLIENT_LIMIT,
    );
    ClientRun {
        code: run.code,
        lines: run
            .stdout
            .lines()
            .filter_map(|l| serde_json::from_str(l).ok())
            .collect(),
        stdout: run.stdout,
        stderr: run.stderr,
    }
}

/// Resumes a stopped process when dropped, also when the test panics.
struct Resume(u32);

impl Drop for Resume {
    fn drop(&mut self) {
        signal(self.0, "CONT");
    }
}

#[test]
fn python_and_rust_pick_the_same_instance_for_every_vehicle() {
    if !ready() {
        return;
    }
    let instances = ["alpha", "beta", "gamma", "host-a-101", "planner-1.site_b", "x"];
    let vehicles: Vec<u64> = (0..2000)
        .chain([u64::MAX, u64::MAX - 1, 1 << 63, 0x9e37_79b9_7f4a_7c15])
        .collect();
    let script = format!(
        "import json, sys\nsys.path.insert(0, {dir:?})\nimport hmdp_client as c\n\
         vehicles, instances = json.load(sys.stdin)\n\
         print(json.dumps([[str(c.rendezvous_score(v, i)) for i in instances] for v in vehicles]))\n\
         print(json.dumps([c.rendezvous_order(v, instances) for v in vehicles]))",
        dir = client_dir().to_str().unwrap()
    );
    let mut child = Command::new("python3")
        .args(["-c", &script])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3 runs");
    let input = serde_json::to_string(&(&vehicles, &instances)).unwrap();
    std::io::Write::write_all(child.stdin.as_mut().unwrap(), input.as_bytes()).unwrap();
    drop(child.stdin.take());
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let mut lines = stdout.lines();
    let scores: Vec<Vec<String>> = serde_json::from_str(lines.next().unwrap()).unwrap();
    let orders: Vec<Vec<String>> = serde_json::from_str(lines.next().unwrap()).unwrap();
    for (i, &v) in vehicles.iter().enumerate() {
        let rust_scores: Vec<String> = instances
            .iter()
            .map(|id| transport::zenoh::instances::rendezvous_score(v, id).to_string())
            .collect();
        assert_eq!(scores[i], rust_scores, "scores of vehicle {v}");
        assert_eq!(orders[i], rendezvous_order(v, instances), "order of vehicle {v}");
    }
}

#[test]
fn python_client_fails_over_from_a_stopped_instance_within_the_deadline() {
    if !ready() {
        return;
    }
    let network = RoutedPlanners::start("py-failover");
    // Until a vehicle gets an answer and sees both instances' tokens.
    drop(network.vehicle(Duration::from_millis(400)));
    let dir = scratch_dir("py-failover");
    let order = rendezvous_order(EXAMPLE_VEHICLE, INSTANCES);
    let (preferred, other) = (order[0].clone(), order[1].clone());
    let retry_after = std::env::var("HMDP_PY_RETRY_AFTER").ok();
    let mut args = vec!["--connect", network.endpoint.as_str(), "--timeout", DEADLINE_S];
    if let Some(r) = &retry_after {
        args.extend(["--retry-after", r.as_str()]);
    }
    let steps = 5;
    let steps_arg = steps.to_string();
    args.extend(["--steps", steps_arg.as_str()]);

    // Both instances serving: every request to the vehicle's own instance, no retry.
    let run = run_client(&dir, &args);
    assert_eq!(run.code, 0, "{}\n{}", run.report(), network.logs());
    assert_eq!(run.lines.len(), steps, "{}", run.report());
    for line in &run.lines {
        assert_eq!(line["instance"], preferred.as_str(), "{}", run.report());
        assert_eq!(line["retries"], 0, "{}", run.report());
    }

    // The vehicle's instance hangs; its token stays for its 3 s lease.
    let stopped_pid = network.planners[INSTANCES.iter().position(|i| *i == preferred).unwrap()].id();
    signal(stopped_pid, "STOP");
    let _resume = Resume(stopped_pid);
    let stopped_at = Instant::now();
    let run = run_client(&dir, &args);
    let took = stopped_at.elapsed();
    eprintln!(
        "python_failover: {preferred} stopped, client run {:.2} s (retry after {}):\n{}",
        took.as_secs_f64(),
        retry_after.as_deref().unwrap_or("default"),
        run.stderr.trim_end()
    );
    // Each request must be answered within the client's --timeout (the deadline): exit 0
    // and one decision per step.
    assert_eq!(
        run.code,
        0,
        "a decision missed its {DEADLINE_S} s deadline with {preferred} stopped\n{}\n{}",
        run.report(),
        network.logs()
    );
    assert_eq!(run.lines.len(), steps, "{}", run.report());
    for line in &run.lines {
        assert_eq!(line["instance"], other.as_str(), "{}", run.report());
        assert!(line.get("layer").is_some(), "a decision: {line}");
    }
    // The first request reached the other instance by the retry (not because the stopped
    // one's token had expired already: the run ended inside its lease); the later ones
    // went there first, the stopped instance being suspected.
    if took < Duration::from_millis(2500) {
        assert_eq!(run.lines[0]["retries"], 1, "{}", run.report());
    }
    for line in &run.lines[1..] {
        assert_eq!(line["retries"], 0, "{}", run.report());
    }
}
