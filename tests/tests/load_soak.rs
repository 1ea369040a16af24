//! `sim_client soak` and `load` against real planner processes: the soak (every request
//! answered exactly once by its deadline, planner memory flat), overload (answers still on
//! time, as fallbacks where needed; recovery when the load drops).
//!
//! The CI slice runs each soak for 60 s; `HMDP_SOAK_SECONDS` makes them longer.

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use serde_json::Value;
use system_tests::{binary, scratch_dir, Iceoryx2Prefix, Process};

fn soak_seconds() -> u64 {
    std::env::var("HMDP_SOAK_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(60)
}

/// Runs `sim_client <args> --json <dir>/report.json`; the report (and the exit status).
fn run_sim_client(dir: &Path, args: &[&str]) -> (bool, Value, String) {
    let json = dir.join("report.json");
    let out = Command::new(binary("sim_client"))
        .args(args)
        .arg("--json")
        .arg(&json)
        .arg("--out")
        .arg(dir)
        .output()
        .expect("sim_client runs");
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let report = std::fs::read_to_string(&json)
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or_else(|| panic!("no report in {}:\n{text}", json.display()));
    (out.status.success(), report, text)
}

fn count(report: &Value, key: &str) -> u64 {
    report["counts"][key]
        .as_u64()
        .unwrap_or_else(|| panic!("counts.{key} in {report}"))
}

fn check_soak(transport_args: &[&str], tag: &str) {
    let seconds = soak_seconds();
    let dir = scratch_dir(tag);
    let duration = format!("{seconds}s");
    // Half the run: Zenoh and the allocator settle within the first tens of seconds.
    let warmup = format!("{}s", seconds / 2);
    let mut args = vec![
        "soak",
        "--clients",
        "16",
        "--rate",
        "2.5",
        "--duration",
        &duration,
        "--warmup",
        &warmup,
        "--spawn-planner",
    ];
    args.extend_from_slice(transport_args);
    let (ok, report, text) = run_sim_client(&dir, &args);
    eprintln!("{text}");
    let sent = count(&report, "sent");
    // 16 vehicles at 2.5 Hz; the first requests wait for the planner to come up.
    let expected = 16.0 * 2.5 * seconds as f64;
    assert!(
        (sent as f64) > 0.9 * expected && (sent as f64) <= expected + 16.0,
        "sent {sent}, expected about {expected}"
    );
    assert_eq!(count(&report, "lost"), 0, "lost answers");
    assert_eq!(count(&report, "duplicated"), 0, "duplicated answers");
    assert_eq!(count(&report, "mismatched"), 0, "answers to the wrong request");
    assert_eq!(count(&report, "discarded"), 0, "answers for other requests received");
    assert_eq!(count(&report, "late"), 0, "deadline misses at nominal load");
    assert_eq!(count(&report, "in_time"), sent);
    assert_eq!(report["by_layer"]["watchdog_fallback"].as_u64(), Some(0), "{report}");
    let planner = &report["planner"];
    let growth = planner["rss_growth_percent"].as_f64().expect("planner RSS sampled");
    assert!(growth < 5.0, "planner RSS grew {growth:.2} % after the warm-up");
    assert!(planner["samples"]
        .as_array()
        .is_some_and(|s| s.len() as u64 >= seconds / 2));
    assert!(ok, "soak reported a failure:\n{text}");
}

#[test]
fn soak_sixteen_vehicles_over_iceoryx2() {
    // The spawned planner gets a prefix of its own (sim_client's pid).
    check_soak(&["--transport", "iceoryx2"], "soak-iceoryx2");
}

#[test]
fn soak_sixteen_vehicles_over_zenoh() {
    check_soak(&["--transport", "zenoh"], "soak-zenoh");
}

#[test]
fn overload_answers_on_time_as_fallbacks_and_recovers() {
    // One worker whose every solve takes 40 ms: capacity about 25 decisions/s.
    let files = Iceoryx2Prefix::new("overload");
    let prefix = files.as_str().to_string();
    let planner = Process::start(
        "planner",
        &[
            "serve",
            "--iceoryx2",
            "--iceoryx2-prefix",
            &prefix,
            "--workers",
            "1",
            "--queue-capacity",
            "4",
            "--inject-solve-delay-ms",
            "40",
        ],
        "overload-planner",
    );
    let pid = planner.id().to_string();
    let dir = scratch_dir("overload");
    let transport = [
        "--transport",
        "iceoryx2",
        "--iceoryx2-prefix",
        &prefix,
        "--planner-pid",
        &pid,
    ];
    // 16 vehicles at 5 Hz: 80 requests/s, three times the capacity.
    let mut args = vec!["load", "--clients", "16", "--rate", "5", "--duration", "15s"];
    args.extend_from_slice(&transport);
    let (ok, overload, text) = run_sim_client(&dir.join("over"), &args);
    assert!(ok, "{text}\n{}", planner.log());
    let sent = count(&overload, "sent");
    assert!(sent > 900, "sent {sent}");
    assert_eq!(count(&overload, "lost"), 0, "{text}");
    assert_eq!(count(&overload, "duplicated"), 0);
    assert_eq!(count(&overload, "late"), 0, "every answer by its deadline:\n{text}");
    let watchdog = overload["by_layer"]["watchdog_fallback"].as_u64().unwrap();
    let decided = sent - watchdog;
    assert!(
        watchdog > sent / 2,
        "overload must be answered by fallbacks: {watchdog} of {sent}"
    );
    // The worker still decides at its own pace meanwhile.
    assert!(decided > 100, "decided {decided}");
    // The load drops: two vehicles at 2 Hz are decided normally again.
    let mut args = vec!["load", "--clients", "2", "--rate", "2", "--duration", "5s"];
    args.extend_from_slice(&transport);
    let (ok, calm, text) = run_sim_client(&dir.join("calm"), &args);
    assert!(ok, "{text}");
    assert_eq!(count(&calm, "late") + count(&calm, "lost"), 0, "{text}");
    assert_eq!(
        calm["by_layer"]["watchdog_fallback"].as_u64(),
        Some(0),
        "recovered:\n{text}"
    );
    assert!(count(&calm, "in_time") >= 15);
    drop(planner);
    drop(files);
}

#[test]
fn load_in_several_processes_accounts_for_every_request() {
    let files = Iceoryx2Prefix::new("procs");
    let prefix = files.as_str().to_string();
    let planner = Process::start(
        "planner",
        &["serve", "--iceoryx2", "--iceoryx2-prefix", &prefix, "--workers", "2"],
        "procs-planner",
    );
    let dir = scratch_dir("procs");
    let (ok, report, text) = run_sim_client(
        &dir,
        &[
            "load",
            "--clients",
            "6",
            "--processes",
            "3",
            "--rate",
            "4",
            "--duration",
            "5s",
            "--transport",
            "iceoryx2",
            "--iceoryx2-prefix",
            &prefix,
            "--plot",
        ],
    );
    assert!(ok, "{text}\n{}", planner.log());
    assert_eq!(report["clients"].as_u64(), Some(6));
    let sent = count(&report, "sent");
    assert!((100..=130).contains(&sent), "6 vehicles x 4 Hz x 5 s: sent {sent}");
    assert_eq!(count(&report, "in_time"), sent, "{text}");
    assert!(dir.join("load/latency.svg").exists() && dir.join("load/timeline.svg").exists());
    // Every vehicle id once: the planner saw 6 distinct vehicles.
    assert!(
        text.contains("6 vehicles"),
        "the report names the merged vehicle count:\n{text}"
    );
    std::thread::sleep(Duration::from_millis(10));
}

#[test]
fn busy_poll_load_over_iceoryx2_answers_every_request() {
    // The latency mode on both sides (the spawned planner gets --busy-poll too); a plain
    // number of seconds as the duration.
    let dir = scratch_dir("busy-poll");
    let args = [
        "load",
        "--transport",
        "iceoryx2",
        "--spawn-planner",
        "--busy-poll",
        "--clients",
        "2",
        "--rate",
        "5",
        "--duration",
        "4",
    ];
    let (ok, report, text) = run_sim_client(&dir, &args);
    assert!(ok, "{text}");
    let sent = count(&report, "sent");
    assert!(sent >= 20, "sent {sent}:\n{text}");
    assert_eq!(count(&report, "in_time"), sent, "{text}");
    assert_eq!(count(&report, "duplicated") + count(&report, "mismatched"), 0, "{text}");
    // Readiness probes are not rejections.
    assert_eq!(report["by_layer"]["rejected"].as_u64(), Some(0), "{text}");
}
