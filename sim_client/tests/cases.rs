//! Cases 1 and 2 of the paper, and the files they write.

use decision::PlannerConfig;
use sim_client::cases::{run_case1, run_case2};
use sim_client::report::{write_case1, write_case2};
use sim_client::Transport;

#[test]
fn case1_runs_and_writes_its_files() {
    let run = run_case1(&PlannerConfig::default(), &Transport::InProcess, 1).unwrap();
    let m = &run.metrics;
    assert_eq!(m.decisions, 100, "40 s at 0.4 s");
    assert_eq!(m.decisions_by_layer.total(), m.decisions);
    assert!(run.episode.trajectory.len() >= 401 * 6);
    let dir = tempfile::tempdir().unwrap();
    let files = write_case1(dir.path(), &run).unwrap();
    for name in [
        "trajectory.csv",
        "decisions.csv",
        "summary.json",
        "speed.svg",
        "beta.svg",
        "snapshots.svg",
    ] {
        let p = dir.path().join("case1").join(name);
        assert!(files.contains(&p), "{name} not reported");
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.len() > 200, "{name} is nearly empty");
        if name.ends_with(".svg") {
            assert!(text.contains("<svg"), "{name} is not SVG");
        }
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("case1/summary.json")).unwrap()).unwrap();
    for key in [
        "collisions",
        "lane_changes",
        "beta_switches",
        "corrective_time_s",
        "mean_speed_mps",
    ] {
        assert!(summary.get(key).is_some(), "summary lacks {key}");
    }
    for key in ["nominal", "global_relaxation", "fallback"] {
        assert!(summary["decisions_by_layer"].get(key).is_some());
    }
}

#[test]
fn case2_writes_both_switch_counts() {
    let case = run_case2(&PlannerConfig::default(), &Transport::InProcess, 1).unwrap();
    assert!(case.with.hysteresis && !case.without.hysteresis);
    let dir = tempfile::tempdir().unwrap();
    write_case2(dir.path(), &case).unwrap();
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("case2/summary.json")).unwrap()).unwrap();
    assert_eq!(v["beta_switches_with"], case.with.metrics.beta_switches);
    assert_eq!(v["beta_switches_without"], case.without.metrics.beta_switches);
    assert!(dir.path().join("case2/ablation.svg").exists());
}

/// The paper's Case 2 claim: hysteresis cuts beta switches from 33 to 1.
#[test]
fn hysteresis_reduces_beta_switches_five_fold() {
    let case = run_case2(&PlannerConfig::default(), &Transport::InProcess, 1).unwrap();
    let (with, without) = (case.with.metrics.beta_switches, case.without.metrics.beta_switches);
    assert!(
        5 * with.max(1) <= without,
        "beta switches with hysteresis {with}, without {without}: less than five-fold"
    );
}
