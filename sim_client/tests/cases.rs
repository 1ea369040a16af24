//! Cases 1 and 2 of the paper, the files they write, and the metrics they report, checked
//! against independent counts from the recorded trajectory.

use decision::PlannerConfig;
use sim_client::cases::{run_case1, run_case1_compared, run_case2, CaseRun};
use sim_client::episode::VehicleState;
use sim_client::metrics::EpisodeMetrics;
use sim_client::plot::snapshot_instants;
use sim_client::presets::paper_literal;
use sim_client::report::{predictions_at, write_case1, write_case2};
use sim_client::safety::HARD_BRAKING_MPS2;
use sim_client::Transport;

fn ego_states(run: &CaseRun) -> Vec<&VehicleState> {
    run.episode.trajectory.iter().filter(|s| s.id == 0).collect()
}

/// Checks the safety figures against what the trajectory shows directly.
fn check_safety_against_trajectory(run: &CaseRun) {
    let m = &run.metrics;
    let s = &m.safety;
    let ego = ego_states(run);
    assert_eq!(
        ego.len() as u64,
        run.episode.steps + 1,
        "initial state plus one per step"
    );
    assert_eq!(s.steps, run.episode.steps);
    // Hard braking: rising edges of "a <= -2.5" over the steps (the initial state is not braking).
    let braking: Vec<bool> = ego.iter().map(|e| e.a_mps2 <= HARD_BRAKING_MPS2).collect();
    let runs = braking.windows(2).filter(|w| w[1] && !w[0]).count() as u32 + u32::from(braking[0]);
    assert_eq!(s.hard_braking_events, runs);
    // Jerk from consecutive accelerations, 0.1 s apart.
    let jerks: Vec<f64> = ego.windows(2).map(|w| (w[1].a_mps2 - w[0].a_mps2) / 0.1).collect();
    let max = jerks.iter().fold(0.0f64, |m, j| m.max(j.abs()));
    let rms = (jerks.iter().map(|j| j * j).sum::<f64>() / jerks.len() as f64).sqrt();
    assert!(
        (s.jerk_max_abs_mps3 - max).abs() < 1e-9,
        "{} vs {max}",
        s.jerk_max_abs_mps3
    );
    assert!((s.jerk_rms_mps3 - rms).abs() < 1e-9);
    let min_speed = ego[1..].iter().map(|e| e.v_mps).fold(f64::INFINITY, f64::min);
    assert!((s.min_speed_mps - min_speed).abs() < 1e-12);
    for share in [s.ttc_below_3s_share, s.headway_below_1s_share] {
        assert!((0.0..=1.0).contains(&share), "share {share}");
    }
    assert!(s.ttc_below_3s_steps <= s.steps && s.headway_below_1s_steps <= s.steps);
    assert!(s.max_drac_mps2 >= 0.0 && s.max_drac_mps2.is_finite());
    if let Some(t) = s.min_ttc_s {
        assert!(t >= 0.0);
        assert_eq!(
            s.ttc_below_3s_steps > 0,
            t < 3.0,
            "min TTC {t} and steps below 3 s disagree"
        );
    } else {
        assert_eq!(s.ttc_below_3s_steps, 0);
    }
    check_collision_split(m);
    // The corrective ids come from the decision's memory, one per corrective SV.
    for d in &run.episode.decisions {
        assert_eq!(d.corrective_sv_ids.len(), d.corrective_svs, "decision {}", d.index);
    }
}

fn check_collision_split(m: &EpisodeMetrics) {
    assert_eq!(m.collision_split.ego_total(), u64::from(m.collisions));
}

#[test]
fn case1_runs_and_writes_its_files() {
    let run = run_case1(&PlannerConfig::default(), &Transport::InProcess, 1).unwrap();
    let m = &run.metrics;
    assert_eq!(m.decisions, 100, "40 s at 0.4 s");
    assert_eq!(m.decisions_by_layer.total(), m.decisions);
    assert!(run.episode.trajectory.len() >= 401 * 6);
    check_safety_against_trajectory(&run);
}

#[test]
fn case1_reports_the_planner_and_the_paper_preset_side_by_side() {
    let paper = paper_literal(None).unwrap();
    let case = run_case1_compared(&PlannerConfig::default(), Some(&paper), &Transport::InProcess, 1).unwrap();
    let preset = case.paper_literal.as_ref().expect("the preset ran");
    assert_eq!(preset.config, paper);
    for run in [&case.planner, preset] {
        assert_eq!(run.metrics.decisions, 100);
        check_safety_against_trajectory(run);
    }
    let dir = tempfile::tempdir().unwrap();
    let files = write_case1(dir.path(), &case).unwrap();
    for sub in ["", "paper_literal/"] {
        for name in [
            "trajectory.csv",
            "decisions.csv",
            "summary.json",
            "speed.svg",
            "beta.svg",
            "snapshots.svg",
        ] {
            let p = dir.path().join(format!("case1/{sub}{name}"));
            assert!(files.contains(&p), "{sub}{name} not reported");
            let text = std::fs::read_to_string(&p).unwrap();
            assert!(text.len() > 200, "{sub}{name} is nearly empty");
            if name.ends_with(".svg") {
                assert!(text.contains("<svg"), "{name} is not SVG");
            }
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
    for key in ["ego_at_fault", "ego_hit_in_lane", "sv_sv"] {
        assert!(summary["collision_split"].get(key).is_some(), "summary lacks {key}");
    }
    for key in [
        "min_ttc_s",
        "ttc_below_3s_share",
        "headway_below_1s_share",
        "max_drac_mps2",
        "hard_braking_events",
        "jerk_rms_mps3",
        "jerk_max_abs_mps3",
        "min_speed_mps",
    ] {
        assert!(summary["safety"].get(key).is_some(), "summary lacks safety.{key}");
    }
    assert_eq!(
        summary["safety"]["hard_braking_events"],
        case.planner.metrics.safety.hard_braking_events
    );
    let md = std::fs::read_to_string(dir.path().join("case1/comparison.md")).unwrap();
    assert!(md.contains("| metric | planner | paper_literal |"), "{md}");
    assert!(md.contains("hard-braking events") && md.contains("min TTC (s)"));
}

#[test]
fn snapshot_predictions_are_the_planners_scenario_trees() {
    let run = run_case1(&PlannerConfig::default(), &Transport::InProcess, 1).unwrap();
    let picks = snapshot_instants(&run.episode);
    let predictions = predictions_at(&run, &picks, std::path::Path::new("snapshots.svg")).unwrap();
    assert_eq!(predictions.len(), picks.len());
    let horizon = run.config.timing.horizon;
    for (k, at) in picks.iter().zip(&predictions) {
        let sent = run.episode.decisions[*k].request.as_ref().unwrap();
        assert!(!at.is_empty(), "no prediction at decision {k}");
        for p in at {
            let sv = sent.svs.iter().find(|s| s.id == p.sv_id).expect("a sent SV");
            let total: f64 = p.branches.iter().map(|b| b.probability).sum();
            assert!((total - 1.0).abs() < 1e-9, "branches of SV{} sum to {total}", p.sv_id);
            assert!(p.branches.len() <= run.config.prediction.max_branches);
            for b in &p.branches {
                assert_eq!(b.steps.len(), horizon);
                assert_eq!(b.steps[0].x_from_m, sv.x_m, "a branch starts at the SV");
                assert!(b.steps.windows(2).all(|w| w[0].x_to_m == w[1].x_from_m));
            }
        }
    }
}

#[test]
fn case2_writes_both_ablations_and_their_figures() {
    let paper = paper_literal(None).unwrap();
    let case = run_case2(&PlannerConfig::default(), Some(&paper), &Transport::InProcess, 1).unwrap();
    assert!(case.planner.with.hysteresis && !case.planner.without.hysteresis);
    let preset = case.paper_literal.as_ref().unwrap();
    assert!(preset.with.hysteresis && !preset.without.hysteresis);
    for run in [&case.planner.with, &case.planner.without, &preset.with, &preset.without] {
        check_safety_against_trajectory(run);
    }
    let dir = tempfile::tempdir().unwrap();
    write_case2(dir.path(), &case).unwrap();
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("case2/summary.json")).unwrap()).unwrap();
    assert_eq!(v["beta_switches_with"], case.planner.with.metrics.beta_switches);
    assert_eq!(v["beta_switches_without"], case.planner.without.metrics.beta_switches);
    assert_eq!(
        v["paper_literal"]["beta_switches_with"],
        preset.with.metrics.beta_switches
    );
    for sub in ["", "paper_literal/"] {
        for name in [
            "ablation.svg",
            "speed_with_hysteresis.svg",
            "speed_without_hysteresis.svg",
            "snapshots_with_hysteresis.svg",
            "snapshots_without_hysteresis.svg",
            "decisions_with_hysteresis.csv",
            "decisions_without_hysteresis.csv",
        ] {
            assert!(dir.path().join(format!("case2/{sub}{name}")).exists(), "{sub}{name}");
        }
    }
    let md = std::fs::read_to_string(dir.path().join("case2/comparison.md")).unwrap();
    assert!(md.contains("paper_literal, no hysteresis"), "{md}");
}
