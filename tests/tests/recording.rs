//! Recording and replay: `planner serve --record` during a `sim_client case1` run, the file
//! read back by the reference Python `mcap` package, `planner replay` as a regression gate
//! (identical with the same planner, differences and a non-zero exit with another), bad
//! files rejected with a clear error; `sim_client case2 --record`, `load --record` and
//! `--planner-record` (a planner started with `--spawn-planner` recording).
//!
//! The Python check needs `python3` with the `mcap` package (`scripts/install-build-deps`
//! installs the pinned one of clients/mcap_check/requirements.txt); without it the test fails
//! unless HMDP_SKIP_PYTHON=1.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;
use std::time::Duration;

use system_tests::{binary, case1_decisions, scratch_dir, Iceoryx2Prefix, Process};

/// A `case1` run recorded by the planner, shared by the tests of this file.
struct Recorded {
    file: PathBuf,
    /// Rows of the run's decisions.csv: the decisions the vehicle asked for.
    decisions: usize,
    dir: PathBuf,
}

fn recorded_case1() -> &'static Recorded {
    static RECORDED: OnceLock<Recorded> = OnceLock::new();
    RECORDED.get_or_init(|| {
        let dir = scratch_dir("recording");
        let file = dir.join("planner.mcap");
        let prefix = Iceoryx2Prefix::new("rec");
        let mut planner = recording_planner(&prefix, &file, &["--workers", "2"], "recording-planner");
        let csv = case1_decisions(
            &dir,
            "case1",
            &["--transport", "iceoryx2", "--iceoryx2-prefix", prefix.as_str()],
            &|| planner.log(),
        );
        let status = planner.terminate(Duration::from_secs(20));
        assert!(
            status.is_some_and(|s| s.success()),
            "planner exit {status:?}\n{}",
            planner.log()
        );
        assert!(planner.log().contains("recording finished"), "{}", planner.log());
        let decisions = String::from_utf8(csv).expect("utf-8 csv").lines().count() - 1;
        assert!(decisions > 50, "case1 made {decisions} decisions");
        Recorded { file, decisions, dir }
    })
}

fn replay(args: &[&str]) -> Output {
    Command::new(binary("planner"))
        .arg("replay")
        .args(args)
        .output()
        .expect("planner replay runs")
}

fn json_of(out: &Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "not JSON ({e}): {}\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

fn path_str(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// `planner serve --iceoryx2` under `prefix`, recording to `file`.
fn recording_planner(prefix: &Iceoryx2Prefix, file: &Path, extra: &[&str], label: &str) -> Process {
    let mut args = vec![
        "serve",
        "--iceoryx2",
        "--iceoryx2-prefix",
        prefix.as_str(),
        "--record",
        path_str(file),
    ];
    args.extend_from_slice(extra);
    Process::start("planner", &args, label)
}

#[test]
fn replay_with_the_same_planner_is_identical() {
    let rec = recorded_case1();
    let out = replay(&[path_str(&rec.file), "--json"]);
    let report = json_of(&out);
    assert!(out.status.success(), "{report}");
    assert_eq!(report["compared"], rec.decisions as u64, "{report}");
    assert_eq!(report["identical"], rec.decisions as u64, "{report}");
    assert_eq!(report["different"], 0, "{report}");
    assert_eq!(report["unanswered"], 0, "{report}");
}

#[test]
fn replay_with_a_changed_parameter_reports_differences_and_fails() {
    let rec = recorded_case1();
    let config = rec.dir.join("changed.toml");
    std::fs::write(&config, "[ego]\naccel_mps2 = 1.2\n").expect("config written");
    let out = replay(&[path_str(&rec.file), "--config", path_str(&config), "--json"]);
    let report = json_of(&out);
    assert_eq!(out.status.code(), Some(1), "{report}");
    let different = report["different"].as_u64().expect("count");
    assert!(different > 0, "{report}");
    assert_eq!(
        report["identical"].as_u64().expect("count") + different,
        rec.decisions as u64,
        "{report}"
    );
    let first = &report["first_differences"][0];
    assert!(first["recorded"] != first["replayed"], "{report}");
    assert!(!first["fields"].as_array().expect("fields").is_empty(), "{report}");
    // The text form names the differences too.
    let text = replay(&[path_str(&rec.file), "--config", path_str(&config)]);
    assert_eq!(text.status.code(), Some(1));
    let stdout = String::from_utf8_lossy(&text.stdout);
    assert!(stdout.contains(&format!("different {different}")), "{stdout}");
    assert!(stdout.contains("recorded:") && stdout.contains("replayed:"), "{stdout}");
}

#[test]
fn a_truncated_or_foreign_file_is_a_clear_error() {
    let rec = recorded_case1();
    let bytes = std::fs::read(&rec.file).expect("recording");
    let truncated = rec.dir.join("truncated.mcap");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).expect("written");
    let not_mcap = rec.dir.join("not.mcap");
    std::fs::write(&not_mcap, b"{\"a\": 1}\n").expect("written");
    for (file, expected) in [
        (&truncated, "not a valid MCAP file"),
        (&not_mcap, "not a valid MCAP file"),
    ] {
        let out = replay(&[path_str(file)]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains(expected), "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}

/// True when python3 has the `mcap` package (see [`system_tests::python_ready`]).
fn python_mcap_ready() -> bool {
    system_tests::python_ready("mcap", "run scripts/install-build-deps")
}

/// The reference reader's view of `file` (clients/mcap_check/check_recording.py).
pub fn python_view(file: &Path) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../clients/mcap_check/check_recording.py");
    let out = Command::new("python3")
        .arg(script)
        .arg(file)
        .output()
        .expect("python3 runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    json_of(&out)
}

#[test]
fn the_python_mcap_reader_sees_every_request_and_answer() {
    if !python_mcap_ready() {
        return;
    }
    let rec = recorded_case1();
    let view = python_view(&rec.file);
    let channels = &view["channels"];
    for (topic, schema) in [
        ("/planner/request", "hmdp.PlanRequest"),
        ("/planner/response", "hmdp.PlanResponse"),
        ("/planner/stats", "hmdp.PlannerStats"),
    ] {
        let c = &channels[topic];
        assert_eq!(c["schema_name"], schema, "{view}");
        assert_eq!(c["schema_title"], schema, "{view}");
        assert_eq!(c["schema_encoding"], "jsonschema", "{view}");
        assert_eq!(c["message_encoding"], "json", "{view}");
        assert_eq!(c["missing_fields"], serde_json::json!([]), "{topic}: {view}");
    }
    assert_eq!(channels["/planner/request"]["count"], rec.decisions as u64, "{view}");
    assert_eq!(channels["/planner/response"]["count"], rec.decisions as u64, "{view}");
    // At least the final statistics; one a second while serving.
    assert!(
        channels["/planner/stats"]["count"].as_u64().expect("count") >= 1,
        "{view}"
    );
    assert_eq!(channels["/planner/stats"]["log_times_ordered"], true, "{view}");
    let ids = |topic: &str| {
        let mut v: Vec<(u64, u64)> = channels[topic]["ids"]
            .as_array()
            .expect("ids")
            .iter()
            .map(|p| (p[0].as_u64().expect("id"), p[1].as_u64().expect("sequence")))
            .collect();
        v.sort_unstable();
        v
    };
    let requests = ids("/planner/request");
    assert_eq!(requests, ids("/planner/response"));
    let mut unique = requests.clone();
    unique.dedup();
    assert_eq!(unique.len(), rec.decisions, "every request once");
    let total: u64 = ["/planner/request", "/planner/response", "/planner/stats"]
        .iter()
        .map(|t| channels[*t]["count"].as_u64().expect("count"))
        .sum();
    assert_eq!(view["statistics_message_count"], total, "{view}");
}

/// `sim_client case1 --record` in process; the recording's path and the decision count.
fn simulated_case1() -> &'static (PathBuf, usize) {
    static RECORDED: OnceLock<(PathBuf, usize)> = OnceLock::new();
    RECORDED.get_or_init(|| {
        let dir = scratch_dir("sim-recording");
        let file = dir.join("sim.mcap");
        let csv = case1_decisions(&dir, "case1", &["--record", path_str(&file)], &String::new);
        let decisions = String::from_utf8(csv).expect("utf-8 csv").lines().count() - 1;
        (file, decisions)
    })
}

fn log_replay(file: &Path, extra: &[&str], tag: &str) -> serde_json::Value {
    let json = file.with_file_name(format!("{tag}.json"));
    let out = Command::new(binary("sim_client"))
        .arg("replay")
        .arg(file)
        .args(["--json", path_str(&json)])
        .args(extra)
        .output()
        .expect("sim_client replay runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&std::fs::read(&json).expect("report")).expect("JSON report")
}

#[test]
fn the_simulator_recording_holds_the_ground_truth_and_a_foxglove_scene() {
    if !python_mcap_ready() {
        return;
    }
    let (file, decisions) = simulated_case1();
    let view = python_view(file);
    let c = &view["channels"];
    assert_eq!(c["/sim/scene"]["schema_name"], "foxglove.SceneUpdate", "{view}");
    assert_eq!(c["/sim/vehicles"]["schema_name"], "hmdp.VehicleStates", "{view}");
    assert_eq!(c["/sim/trial"]["count"], 1, "{view}");
    assert_eq!(c["/sim/decision"]["count"], *decisions as u64, "{view}");
    let steps = c["/sim/vehicles"]["count"].as_u64().expect("count");
    // 40 s of low-level steps, the initial state included.
    assert!(steps > 100, "{view}");
    assert_eq!(c["/sim/scene"]["count"], steps, "{view}");
    for topic in ["/sim/trial", "/sim/vehicles", "/sim/decision", "/sim/scene"] {
        assert_eq!(c[topic]["missing_fields"], serde_json::json!([]), "{topic}: {view}");
        assert_eq!(c[topic]["log_times_ordered"], true, "{topic}: {view}");
    }
}

#[test]
fn log_replay_reproduces_the_recorded_ego_and_scores_a_perturbed_run() {
    let (file, decisions) = simulated_case1();
    let same = log_replay(file, &[], "same");
    let d = &same["ego_deviation"];
    assert!(d["steps"].as_u64().expect("steps") > 100, "{same}");
    for field in ["max_dx_m", "max_dy_m", "max_dv_mps"] {
        assert!(d[field].as_f64().expect("number") < 0.05, "{field}: {same}");
    }
    assert_eq!(same["metrics"]["decisions"], *decisions as u64, "{same}");
    let shifted = log_replay(file, &["--perturb-sv-m", "20", "--perturb-seed", "3"], "shifted");
    assert!(
        shifted["metrics"]["decisions"].as_u64().expect("count") > 0,
        "{shifted}"
    );
    assert_eq!(shifted["svs"], same["svs"]);
    let dx = shifted["ego_deviation"]["max_dx_m"].as_f64().expect("number");
    assert!(dx > 0.05, "moved SVs should change the ego's run: {shifted}");
}

/// Messages per topic of a recording, read with the recording crate's reader.
fn topic_counts(file: &Path) -> BTreeMap<String, usize> {
    let mut counts = BTreeMap::new();
    for m in recording::read_messages(file).unwrap_or_else(|e| panic!("{e}")) {
        *counts.entry(m.topic).or_insert(0) += 1;
    }
    counts
}

fn csv_rows(path: &Path) -> usize {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines().count() - 1
}

fn sim_client(args: &[&str]) -> Output {
    let out = Command::new(binary("sim_client"))
        .args(args)
        .output()
        .expect("sim_client runs");
    assert!(
        out.status.success(),
        "sim_client {args:?}: {}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

#[test]
fn case2_records_each_of_its_runs_to_a_file_of_its_own() {
    let dir = scratch_dir("case2-recording");
    let (out_dir, base) = (dir.join("out"), dir.join("c2.mcap"));
    let out = sim_client(&["case2", "--out", path_str(&out_dir), "--record", path_str(&base)]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let runs = [
        (
            "c2.with_hysteresis.mcap",
            "case2/decisions_with_hysteresis.csv",
            "case2 with hysteresis",
        ),
        (
            "c2.without_hysteresis.mcap",
            "case2/decisions_without_hysteresis.csv",
            "case2 without hysteresis",
        ),
        (
            "c2.paper_literal.with_hysteresis.mcap",
            "case2/paper_literal/decisions_with_hysteresis.csv",
            "case2 paper_literal with hysteresis",
        ),
        (
            "c2.paper_literal.without_hysteresis.mcap",
            "case2/paper_literal/decisions_without_hysteresis.csv",
            "case2 paper_literal without hysteresis",
        ),
    ];
    for (file, csv, label) in runs {
        let file = dir.join(file);
        assert!(stdout.contains(&format!("recorded {}", file.display())), "{stdout}");
        let counts = topic_counts(&file);
        assert_eq!(counts.get("/sim/trial"), Some(&1), "{file:?}: {counts:?}");
        assert_eq!(
            counts.get("/sim/decision"),
            Some(&csv_rows(&out_dir.join(csv))),
            "{file:?}: {counts:?}"
        );
        let steps = counts["/sim/vehicles"];
        assert!(steps > 100, "{file:?}: {counts:?}");
        assert_eq!(counts["/sim/scene"], steps, "{file:?}: {counts:?}");
        let trial = recording::read_messages(&file)
            .expect("read")
            .into_iter()
            .find(|m| m.topic == "/sim/trial")
            .expect("trial");
        let trial: serde_json::Value = serde_json::from_slice(&trial.data).expect("JSON");
        assert_eq!(trial["label"], label, "{trial}");
    }
    // The run with hysteresis is the default planner's: log replay reproduces its ego.
    let same = log_replay(&dir.join(runs[0].0), &[], "case2-same");
    for field in ["max_dx_m", "max_dy_m", "max_dv_mps"] {
        assert!(
            same["ego_deviation"][field].as_f64().expect("number") < 0.05,
            "{field}: {same}"
        );
    }
}

#[test]
fn a_spawned_planner_records_what_planner_replay_finds_identical() {
    let dir = scratch_dir("spawned-recording");
    let (file, log) = (dir.join("spawned.mcap"), dir.join("planner.log"));
    let csv = case1_decisions(
        &dir,
        "case1",
        &[
            "--transport",
            "iceoryx2",
            "--spawn-planner",
            "--planner-log",
            path_str(&log),
            "--planner-record",
            path_str(&file),
        ],
        &|| std::fs::read_to_string(&log).unwrap_or_default(),
    );
    let decisions = String::from_utf8(csv).expect("utf-8 csv").lines().count() - 1;
    let planner_log = std::fs::read_to_string(&log).unwrap_or_default();
    assert!(planner_log.contains("recording finished"), "{planner_log}");
    let out = replay(&[path_str(&file), "--json"]);
    let report = json_of(&out);
    assert!(out.status.success(), "{report}");
    assert_eq!(report["compared"], decisions as u64, "{report}");
    assert_eq!(report["identical"], decisions as u64, "{report}");
    assert_eq!(report["unanswered"], 0, "{report}");
}

#[test]
fn load_records_what_its_vehicles_sent_and_got_and_it_replays_identically() {
    let dir = scratch_dir("load-recording");
    let (vehicles, planner, json) = (
        dir.join("vehicles.mcap"),
        dir.join("planner.mcap"),
        dir.join("load.json"),
    );
    #[rustfmt::skip]
    let out = sim_client(&[
        "load", "--transport", "iceoryx2", "--spawn-planner", "--planner-workers", "2",
        "--clients", "2", "--rate", "5", "--duration", "4", "--out", path_str(&dir),
        "--json", path_str(&json), "--record", path_str(&vehicles), "--planner-record", path_str(&planner),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains(&format!("recorded {}", vehicles.display())), "{stdout}");
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).expect("report")).expect("JSON");
    let sent = report["counts"]["sent"].as_u64().expect("sent");
    let lost = report["counts"]["lost"].as_u64().expect("lost");
    assert!(sent >= 20, "{report}");
    let counts = topic_counts(&vehicles);
    assert_eq!(
        counts.get("/planner/request").copied(),
        Some(sent as usize),
        "{counts:?}"
    );
    assert_eq!(
        counts.get("/planner/response").copied().unwrap_or(0),
        (sent - lost) as usize,
        "{counts:?}"
    );
    // The vehicles' side and the planner's side: each re-decided identically.
    for (file, expected) in [(&vehicles, sent - lost), (&planner, sent)] {
        let out = replay(&[path_str(file), "--json"]);
        let r = json_of(&out);
        assert!(out.status.success(), "{file:?}: {r}");
        assert_eq!(r["compared"], expected, "{file:?}: {r}");
        assert_eq!(r["identical"], expected, "{file:?}: {r}");
    }
}

#[test]
fn a_request_with_non_finite_numbers_is_recorded_and_replayed() {
    use transport::iceoryx2::{Client, ClientOptions};
    let dir = scratch_dir("nan-recording");
    let file = dir.join("nan.mcap");
    let prefix = Iceoryx2Prefix::new("nan");
    let mut planner = recording_planner(&prefix, &file, &[], "nan-planner");
    let options = ClientOptions {
        prefix: Some(prefix.as_str().to_string()),
        ready_timeout: Duration::from_secs(60),
        node_name: "nan-vehicle".into(),
        ..ClientOptions::default()
    };
    let mut client = Client::connect(&options).expect("the planner's iceoryx2 services");
    // Probes (not recorded) until the planner answers.
    let give_up = std::time::Instant::now() + Duration::from_secs(60);
    while client
        .request(protocol::PlanRequest::probe(999), Duration::from_millis(500))
        .expect("probe")
        .response
        .is_none()
    {
        assert!(std::time::Instant::now() < give_up, "{}", planner.log());
    }
    let mut nan = system_tests::worked_example_request(4, 1);
    nan.ego.v_mps = f64::NAN;
    let mut inf = system_tests::worked_example_request(4, 2);
    inf.svs[0].x_m = f64::NEG_INFINITY;
    for r in [nan, inf, system_tests::worked_example_request(4, 3)] {
        let answer = client.request(r, Duration::from_secs(5)).expect("exchange");
        assert!(answer.response.is_some(), "{}", planner.log());
    }
    drop(client);
    let status = planner.terminate(Duration::from_secs(20));
    assert!(status.is_some_and(|s| s.success()), "{}", planner.log());
    let out = replay(&[path_str(&file), "--json"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let report = json_of(&out);
    assert!(out.status.success(), "{report}\n{stderr}");
    assert_eq!(report["compared"], 3, "{report}");
    assert_eq!(report["identical"], 3, "{report}");
}
