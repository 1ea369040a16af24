//! The Python example client (`clients/python/hmdp_client.py`, eclipse-zenoh) against
//! `planner serve`, both as processes.
//!
//! The decisions it prints are held to the in-process decision core (the oracle: the same
//! snapshot, decoded and converted by the protocol crate, decided by a `decision::Planner`
//! with the service's configuration), also over a `--steps` sequence that carries the
//! hysteresis memory. Rejections and "no answer" are checked through the exit codes.
//!
//! Needs `python3` with the `zenoh` module (`scripts/install-build-deps` installs it); with
//! `HMDP_SKIP_PYTHON=1` the tests skip when it is missing. The `planner` binary must be
//! built (`cargo build -p planner`, or run under `cargo test --workspace`).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use decision::{Planner, PlannerConfig};
use protocol::{decode_json_str, Decided, PlanRequest, RejectReason, Rejected, WireError};
use serde_json::{json, Value};
use system_tests::{free_port, run_to_end, ZenohPlanner};

/// How long a planner may take to start answering (debug builds on a shared machine).
const STARTUP: Duration = Duration::from_secs(60);
/// A client run that takes longer than this is hung: killed, and the test fails.
const CLIENT_LIMIT: Duration = Duration::from_secs(60);
/// Period between two snapshots of `--steps` (the client's `STEP_S`).
const STEP_S: f64 = 0.4;
/// Lane change duration of the client's trivial ego model (its `LANE_CHANGE_S`).
const LANE_CHANGE_S: f64 = 3.0;

/// True when the client can run (see [`system_tests::python_ready`]).
fn python_ready() -> bool {
    system_tests::python_ready(
        "zenoh",
        "run scripts/install-build-deps (it installs the pinned eclipse-zenoh of clients/python/requirements.txt)",
    )
}

fn client_script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../clients/python/hmdp_client.py")
}

fn scratch_dir(name: &str) -> PathBuf {
    system_tests::scratch_dir(&format!("python-{name}"))
}

/// A `planner serve` over Zenoh and a scratch directory for the client's files.
struct PlannerProcess {
    planner: ZenohPlanner,
    dir: PathBuf,
}

impl PlannerProcess {
    fn start(name: &str, extra: &[&str]) -> Self {
        let mut planner = Self {
            planner: ZenohPlanner::start(&format!("python-{name}"), extra),
            dir: scratch_dir(name),
        };
        planner.wait_ready();
        planner
    }

    fn log(&self) -> String {
        self.planner.log()
    }

    /// Until the client gets a decision: the port listening is not enough, the queryable
    /// is declared after the session opens.
    fn wait_ready(&mut self) {
        let give_up = Instant::now() + STARTUP;
        loop {
            let run = run_client(&self.dir, &["--connect", &self.planner.endpoint]);
            if run.code == 0 {
                return;
            }
            if !self.planner.process.is_running() {
                panic!("planner exited before serving\n{}", self.log());
            }
            assert!(
                Instant::now() < give_up,
                "planner never answered the client\nclient: {}\nplanner log:\n{}",
                run.stderr,
                self.log()
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// Writes `request` into the scratch directory and runs the client on it.
    fn ask(&self, name: &str, request: &Value, extra: &[&str]) -> ClientRun {
        let file = self.dir.join(format!("{name}.json"));
        std::fs::write(&file, serde_json::to_string_pretty(request).unwrap()).unwrap();
        let mut args = vec!["--connect", &self.planner.endpoint, "--request", file.to_str().unwrap()];
        args.extend_from_slice(extra);
        let run = run_client(&self.dir, &args);
        run.expect_parsed(&self.log());
        run
    }
}

/// What one client process did.
struct ClientRun {
    code: i32,
    /// stdout, one JSON document per line (`None` for a line that is not JSON).
    lines: Vec<Option<Value>>,
    stdout: String,
    stderr: String,
    elapsed: Duration,
}

impl ClientRun {
    fn expect_parsed(&self, planner_log: &str) {
        assert!(
            self.lines.iter().all(Option::is_some),
            "client printed a line that is not JSON:\n{}\nstderr: {}\nplanner log:\n{}",
            self.stdout,
            self.stderr,
            planner_log
        );
    }

    fn values(&self) -> Vec<&Value> {
        self.lines.iter().flatten().collect()
    }
}

/// Runs the client with `args` to its end ([`run_to_end`], killed after [`CLIENT_LIMIT`]).
fn run_client(dir: &Path, args: &[&str]) -> ClientRun {
    let run = run_to_end(
        Command::new("python3").arg(client_script()).args(args),
        dir,
        "client",
        CLIENT_LIMIT,
    );
    ClientRun {
        code: run.code,
        lines: run.stdout.lines().map(|l| serde_json::from_str(l).ok()).collect(),
        stdout: run.stdout,
        stderr: run.stderr,
        elapsed: run.elapsed,
    }
}

/// The outcome the service gives for `request`, computed in process, in the JSON form of
/// the wire outcome (`{"decided": {...}}` or `{"rejected": {...}}`). It follows the
/// service's path: decode, wire checks, then the decision core.
fn oracle(planner: &mut Planner, request: &Value) -> Value {
    let rejected = |r: Rejected| json!({ "rejected": serde_json::to_value(r).unwrap() });
    let decoded: Result<PlanRequest, WireError> = decode_json_str(&request.to_string());
    let text = request.to_string();
    let request = match decoded {
        Ok(r) => r,
        // Undecodable JSON: the service names the list that is over capacity.
        Err(WireError::CapacityExceeded(_)) => {
            let field = protocol::WireFormat::Json
                .over_capacity_field(text.as_bytes())
                .unwrap_or("");
            return rejected(Rejected::new(RejectReason::CapacityExceeded, field));
        }
        Err(e) => panic!("the test sent a request the service cannot decode: {e}"),
    };
    if let Err(r) = request.check_wire() {
        return rejected(r);
    }
    match planner.decide(&request.to_situation()) {
        Ok(d) => json!({ "decided": serde_json::to_value(Decided::try_from(&d).unwrap()).unwrap() }),
        Err(e) => rejected(Rejected::from(&e)),
    }
}

/// The decision fields of a client line, in the wire's `Decided` form.
fn printed_decision(line: &Value) -> Value {
    assert!(line.get("rejected").is_none(), "expected a decision, got {line}");
    let mut decided = serde_json::Map::new();
    for key in ["action", "next_maneuver", "setpoint", "plan", "layer", "memory"] {
        let value = line.get(key).unwrap_or_else(|| panic!("no {key} in {line}"));
        decided.insert(key.into(), value.clone());
    }
    Value::Object(decided)
}

/// Asserts the client printed `expected` (an oracle outcome) at `step`.
fn assert_same_outcome(step: usize, line: &Value, expected: &Value) {
    if let Some(rejected) = expected.get("rejected") {
        assert_eq!(
            line.get("rejected"),
            Some(rejected),
            "step {step}: rejection differs from the oracle"
        );
        return;
    }
    let expected = &expected["decided"];
    let printed = printed_decision(line);
    // The parts a vehicle acts on first, for a readable failure; then everything.
    for key in ["action", "next_maneuver", "layer"] {
        assert_eq!(
            printed[key], expected[key],
            "step {step}: {key} differs from the oracle"
        );
    }
    assert_eq!(&printed, expected, "step {step}: decision differs from the oracle");
}

/// The snapshot one period after `request`, carrying `decided`'s memory: the client's
/// trivial model (SVs at constant speed, the ego on its plan's first step, drifting towards
/// its target lane at one lane width per `LANE_CHANGE_S`), with the same float operations.
fn advance(request: &Value, decided: &Value) -> Value {
    let mut next = request.clone();
    let f = |v: &Value| v.as_f64().unwrap();
    next["sequence"] = (request["sequence"].as_u64().unwrap() + 1).into();
    next["timestamp_ns"] = (request["timestamp_ns"].as_u64().unwrap() + 400_000_000).into();
    let road = &request["road"];
    let ego = &mut next["ego"];
    ego["x_m"] = decided["plan"][0]["x_m"].clone();
    ego["v_mps"] = decided["plan"][0]["v_mps"].clone();
    ego["maneuver"] = decided["next_maneuver"].clone();
    let lane = decided["next_maneuver"]["lane"].as_u64().unwrap();
    let target_y = (road["lanes"].as_u64().unwrap() - lane) as f64 * f(&road["lane_width_m"]);
    let max_dy = f(&road["lane_width_m"]) * STEP_S / LANE_CHANGE_S;
    let y = f(&ego["y_m"]);
    ego["y_m"] = (y + (target_y - y).clamp(-max_dy, max_dy)).into();
    for sv in next["svs"].as_array_mut().unwrap() {
        sv["x_m"] = (f(&sv["x_m"]) + f(&sv["v_mps"]) * STEP_S).into();
    }
    next["memory"] = decided["memory"].clone();
    next
}

/// The oracle's outcomes over `steps` snapshots from `first`; with `carry` false every
/// snapshot goes out with an empty memory (what a client that drops it would get).
fn oracle_sequence(planner: &mut Planner, first: &Value, steps: usize, carry: bool) -> Vec<Value> {
    let mut request = first.clone();
    let mut out = Vec::new();
    for _ in 0..steps {
        let outcome = oracle(planner, &request);
        let decided = outcome["decided"].clone();
        out.push(outcome);
        request = advance(&request, &decided);
        if !carry {
            request["memory"] = json!({ "corrective": [], "previous_plan": [] });
        }
    }
    out
}

fn default_planner() -> Planner {
    Planner::new(PlannerConfig::default()).unwrap()
}

/// A 3-lane road, the ego in lane 2 at `v_ego` (wanting 28 m/s); `svs` as `(id, x, lane, v)`.
fn snapshot(v_ego: f64, svs: &[(u32, f64, u8, f64)]) -> Value {
    let svs: Vec<Value> = svs
        .iter()
        .map(|&(id, x, lane, v)| {
            let y = f64::from(3 - lane) * 3.5;
            json!({ "id": id, "x_m": x, "y_m": y, "v_mps": v, "a_mps2": 0.0 })
        })
        .collect();
    json!({
        "version": 3,
        "vehicle_id": 11,
        "sequence": 1,
        "timestamp_ns": 5_000_000_000u64,
        "road": { "lanes": 3, "lane_width_m": 3.5, "speed_limit_mps": 30.0 },
        "ego": {
            "x_m": 0.0, "y_m": 3.5, "v_mps": v_ego, "desired_speed_mps": 28.0,
            "maneuver": { "lane": 2, "beta": 0 },
        },
        "svs": svs,
    })
}

#[test]
fn decisions_equal_the_in_process_planner() {
    if !python_ready() {
        return;
    }
    let planner = PlannerProcess::start("decisions", &[]);
    let mut oracle_planner = default_planner();

    // The built-in snapshot, as the client itself describes it, with the statistics.
    let example = run_client(&planner.dir, &["--print-example"]);
    assert_eq!(example.code, 0, "{}", example.stderr);
    let example: Value = serde_json::from_str(&example.stdout).expect("the example is JSON");
    let run = run_client(&planner.dir, &["--connect", &planner.planner.endpoint, "--stats"]);
    run.expect_parsed(&planner.log());
    assert_eq!(run.code, 0, "{}", run.stderr);
    let lines = run.values();
    assert_eq!(lines.len(), 2, "a decision and the statistics:\n{}", run.stdout);
    assert_same_outcome(1, lines[0], &oracle(&mut oracle_planner, &example));
    assert_eq!(lines[0]["sequence"], example["sequence"]);
    let stats = &lines[1]["stats"];
    assert!(stats["answered"].as_u64().is_some_and(|n| n >= 1), "{stats}");

    // Scenes that exercise other answers: a free road, following a slower SV (corrective),
    // a plan with a lane change, the global relaxation, and an SV too close for anything but
    // the fallback.
    let scenes = [
        ("free", snapshot(25.0, &[])),
        ("follow", snapshot(25.0, &[(1, 150.0, 2, 15.0), (2, -40.0, 3, 24.0)])),
        ("lane-change", snapshot(18.0, &[(1, 60.0, 2, 18.0)])),
        ("relaxation", snapshot(25.0, &[(1, 120.0, 2, 15.0)])),
        ("too-close", snapshot(25.0, &[(1, 12.0, 2, 10.0)])),
    ];
    let mut layers = Vec::new();
    for (name, scene) in &scenes {
        let run = planner.ask(name, scene, &[]);
        assert_eq!(run.code, 0, "{name}: {}", run.stderr);
        let lines = run.values();
        assert_eq!(lines.len(), 1, "{name}: one decision:\n{}", run.stdout);
        let expected = oracle(&mut oracle_planner, scene);
        assert_same_outcome(1, lines[0], &expected);
        layers.push(expected["decided"]["layer"].as_str().unwrap().to_owned());
    }
    eprintln!("layers of the scenes: {layers:?}");
}

#[test]
fn steps_carry_the_hysteresis_memory() {
    if !python_ready() {
        return;
    }
    let planner = PlannerProcess::start("steps", &[]);
    let mut oracle_planner = default_planner();
    // A slower SV ahead in the ego's lane: the gap closes until it falls below the trigger
    // distance, after which the frozen thresholds must travel with every request.
    let first = snapshot(25.0, &[(1, 93.0, 2, 22.0)]);
    let steps = 8;
    let run = planner.ask("steps", &first, &["--steps", &steps.to_string()]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    let lines = run.values();
    assert_eq!(lines.len(), steps, "one decision per step:\n{}", run.stdout);

    let expected = oracle_sequence(&mut oracle_planner, &first, steps, true);
    for (i, (line, outcome)) in lines.iter().zip(&expected).enumerate() {
        assert_eq!(line["step"], json!(i + 1));
        assert_eq!(line["sequence"], json!(i + 1), "the sequence number advances");
        assert_same_outcome(i + 1, line, outcome);
    }

    // The scene does what it is chosen for: the SV turns corrective after the first
    // request and its entry is carried through the later steps (frozen, or re-sized down to
    // the release distance at the leader's speed, never up).
    let corrective = |i: usize| lines[i]["memory"]["corrective"].as_array().unwrap().clone();
    let first_trigger = (0..steps)
        .find(|&i| !corrective(i).is_empty())
        .expect("the SV enters corrective mode");
    assert!(first_trigger > 0, "corrective from the first request: nothing to carry");
    assert!(first_trigger + 2 < steps, "too few steps after the trigger");
    let entry = corrective(first_trigger);
    assert_eq!(entry[0]["sv_id"], 1);
    let release = |e: &[serde_json::Value]| e[0]["release_m"].as_f64().unwrap();
    let mut last = release(&entry);
    for i in first_trigger + 1..steps {
        let now = corrective(i);
        assert_eq!(now[0]["sv_id"], 1, "step {}: the entry was not carried", i + 1);
        assert!(
            release(&now) <= last + 1e-9,
            "step {}: the release distance grew",
            i + 1
        );
        last = release(&now);
    }
    // Dropping the memory gives other answers on this scene: agreement with the carrying
    // oracle is evidence that the client fed the memory back.
    let forgetful = oracle_sequence(&mut oracle_planner, &first, steps, false);
    assert!(
        forgetful
            .iter()
            .zip(&expected)
            .any(|(a, b)| a["decided"]["memory"]["corrective"] != b["decided"]["memory"]["corrective"]),
        "the scene does not tell a client that carries the memory from one that drops it"
    );
}

#[test]
fn bad_snapshots_exit_2_with_the_reason() {
    if !python_ready() {
        return;
    }
    // A planner that uses at most 4 SVs: more are accepted (it uses the nearest), up to the
    // wire capacity of 64.
    let config = "[perception]\nmax_svs = 4\n";
    let dir = scratch_dir("rejections-config");
    let config_path = dir.join("planner.toml");
    std::fs::write(&config_path, config).unwrap();
    let planner = PlannerProcess::start("rejections", &["--config", config_path.to_str().unwrap()]);
    let mut oracle_planner = Planner::new(PlannerConfig::from_toml_str(config).unwrap()).unwrap();

    let mut off_road = snapshot(25.0, &[(1, 50.0, 2, 20.0)]);
    off_road["ego"]["maneuver"]["lane"] = 4.into();
    // Beyond the tolerance of -0.5 m/s, read as 0.
    let mut reversing = snapshot(25.0, &[(1, 50.0, 2, 20.0)]);
    reversing["ego"]["v_mps"] = (-0.75).into();
    let too_many: Vec<_> = (1..=65)
        .map(|i| (i, 5.0 * f64::from(i), 1 + (i % 3) as u8, 20.0))
        .collect();
    let cases = [
        ("lane", off_road, "lane_out_of_range", "ego.maneuver.lane"),
        ("reversing", reversing, "negative_speed", "ego.v_mps"),
        ("sixty-five-svs", snapshot(25.0, &too_many), "capacity_exceeded", "svs"),
    ];
    for (name, request, reason, field) in &cases {
        // Also with --steps: a rejection ends the sequence.
        let run = planner.ask(name, request, &["--steps", "3"]);
        assert_eq!(
            run.code, 2,
            "{name}: exit code\nstdout: {}\nstderr: {}",
            run.stdout, run.stderr
        );
        let lines = run.values();
        assert_eq!(lines.len(), 1, "{name}: nothing after the rejection:\n{}", run.stdout);
        let expected = oracle(&mut oracle_planner, request);
        assert_same_outcome(1, lines[0], &expected);
        // The oracle agrees with the documented reason, so the case tests what it names.
        assert_eq!(
            expected["rejected"],
            json!({ "reason": reason, "field": field }),
            "{name}"
        );
        assert!(
            run.stderr.contains(reason),
            "{name}: reason not on stderr: {}",
            run.stderr
        );
    }
}

#[test]
fn no_answer_exits_1_after_the_timeout() {
    if !python_ready() {
        return;
    }
    // How long it took is printed, not asserted (CLIENT_LIMIT catches a hang).
    // Nothing listens on the port.
    let dir = scratch_dir("no-planner");
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let run = run_client(&dir, &["--connect", &endpoint, "--timeout", "1.0"]);
    assert_eq!(run.code, 1, "stdout: {}\nstderr: {}", run.stdout, run.stderr);
    assert!(run.stdout.is_empty(), "no decision printed: {}", run.stdout);
    eprintln!("no planner: client gave up after {:?} (process total)", run.elapsed);

    // A planner that answers too late: every solve is held for 1 s, so the watchdog answers
    // at the 400 ms deadline, after the client's 0.2 s timeout.
    let planner = PlannerProcess::start("late", &["--inject-solve-delay-ms", "1000"]);
    let run = planner.ask("late", &snapshot(25.0, &[]), &["--timeout", "0.2"]);
    assert_eq!(run.code, 1, "stdout: {}\nstderr: {}", run.stdout, run.stderr);
    assert!(run.stdout.is_empty(), "no decision printed: {}", run.stdout);
    assert!(
        run.elapsed >= Duration::from_millis(200),
        "gave up before its timeout: {:?}",
        run.elapsed
    );
    eprintln!("late planner: client gave up after {:?} (process total)", run.elapsed);
}

/// Size: a request Zenoh delivers gets a typed answer, however wrong it is; one above the
/// planner's message limit could never be answered (every session drops it while
/// reassembling it, and nothing goes back), so the client refuses it before sending and
/// exits 1 at once instead of waiting out its timeout (docs/protocol.md, "Size"). Without
/// that check the client would wait its whole `--timeout 600` and be killed after
/// CLIENT_LIMIT.
#[test]
fn an_oversized_request_is_refused_before_it_is_sent() {
    if !python_ready() {
        return;
    }
    let planner = PlannerProcess::start("oversized", &[]);
    let padded = |bytes: usize| {
        let mut request = snapshot(25.0, &[(1, 50.0, 2, 20.0)]);
        // An unknown field: the planner rejects it as malformed once it has it whole.
        request["padding"] = "x".repeat(bytes).into();
        request
    };
    let run = planner.ask("below-limit", &padded(50_000), &["--timeout", "600"]);
    assert_eq!(run.code, 2, "stdout: {}\nstderr: {}", run.stdout, run.stderr);
    assert!(run.stderr.contains("rejected: malformed"), "{}", run.stderr);
    let run = planner.ask("above-limit", &padded(100_000), &["--timeout", "600"]);
    assert_eq!(run.code, 1, "stdout: {}\nstderr: {}", run.stdout, run.stderr);
    assert!(run.stdout.is_empty(), "no decision printed: {}", run.stdout);
    assert!(run.stderr.contains("the planner receives at most"), "{}", run.stderr);
    eprintln!(
        "oversized request: refused in {:?} (process total): {}",
        run.elapsed,
        run.stderr.trim()
    );
}
