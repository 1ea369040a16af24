//! The randomized campaign: consistency, thread-count independence, report formatting.

use sim_client::campaign::{
    aggregate, paper_entries, parse_entries, run_campaign, scale_trials, CampaignSettings, DriverKind, TrialOutcome,
};
use sim_client::campaign_compare::{compare, read_trials, Verdict};
use sim_client::presets::paper_literal;
use sim_client::report::{campaign_csv, campaign_markdown, write_campaign};
use traffic::SvBehaviour;

const TINY: &str = r#"
[[config]]
lanes = 2
sv_count = 8
speed_range = [25.0, 40.0]
trials = 2

[[config]]
lanes = 3
svs = 5
speed_range = [10.0, 20.0]
trials = 2

[[config]]
id = 42
lanes = 4
sv_count = 10
speed_range = [25.0, 40.0]
trials = 2
"#;

#[test]
fn custom_configs_parse_from_toml_and_json() {
    let t = parse_entries(TINY, false).unwrap();
    assert_eq!(t.iter().map(|e| e.id).collect::<Vec<_>>(), vec![1, 2, 42]);
    assert_eq!(t[1].traffic.sv_count, 5);
    let j = parse_entries(
        r#"[{"lanes": 2, "sv_count": 5, "speed_range": [10, 20], "trials": 3}]"#,
        true,
    )
    .unwrap();
    assert_eq!((j[0].traffic.lanes, j[0].trials), (2, 3));
    assert!(parse_entries(
        r#"[{"lanes": 9, "sv_count": 5, "speed_range": [10, 20], "trials": 3}]"#,
        true
    )
    .is_err());
    assert!(parse_entries("[[config]]\nlanes = 2\n", false).is_err());
}

#[test]
fn the_held_out_campaign_parses_and_lies_outside_table_i() {
    let held_out = parse_entries(include_str!("../campaigns/held-out.toml"), false).unwrap();
    assert_eq!(held_out.len(), 3);
    let paper = paper_entries();
    for e in &held_out {
        let t = &e.traffic;
        assert!(
            !paper.iter().any(|p| p.traffic.lanes == t.lanes
                && p.traffic.sv_count == t.sv_count
                && p.traffic.speed_range == t.speed_range),
            "configuration {} is one of Table I's",
            e.id
        );
    }
}

#[test]
fn trial_scaling_keeps_at_least_one_trial() {
    let e = scale_trials(&paper_entries(), 0.001).unwrap();
    assert_eq!(e.len(), 18);
    assert!(e.iter().all(|e| e.trials == 1));
    let total: u32 = scale_trials(&paper_entries(), 1.0)
        .unwrap()
        .iter()
        .map(|e| e.trials)
        .sum();
    assert_eq!(total, 8050);
    assert!(scale_trials(&paper_entries(), 0.0).is_err());
}

#[test]
fn tiny_campaign_is_consistent_and_independent_of_thread_count() {
    let entries = parse_entries(TINY, false).unwrap();
    let run = |threads| {
        let mut s = CampaignSettings::new(entries.clone(), 9, threads);
        s.duration_s = 12.0;
        s.paper_literal = Some(paper_literal(None).unwrap());
        run_campaign(&s, &|| {}).unwrap()
    };
    let one = run(1);
    let two = run(2);
    assert_eq!(one.without_timing(), two.without_timing());
    assert_eq!(one.groups.len(), 12);
    assert_eq!(one.overall.len(), 4);
    for g in one.groups.iter().chain(&one.overall) {
        assert_eq!(g.trials, if g.config_id.is_some() { 2 } else { 6 });
        let layers = g.decisions_by_layer.total();
        if g.driver == DriverKind::IdmMobil {
            assert_eq!(layers, 0);
            assert!(g.nor.is_none());
        } else {
            assert_eq!(layers, g.decisions, "layers must sum to decisions");
            let sum = g.nor.unwrap() + g.gsrr.unwrap() + g.fbr.unwrap();
            assert!((sum - 1.0).abs() < 1e-9);
            assert_eq!(g.solve_time.samples, g.decisions);
        }
        for r in [
            g.collision_rate,
            g.nor.unwrap_or(0.0),
            g.gsrr.unwrap_or(0.0),
            g.fbr.unwrap_or(0.0),
        ] {
            assert!((0.0..=1.0).contains(&r), "rate {r} out of [0, 1]");
        }
        // 12 s = 30 decisions unless the episode ended in a collision.
        assert!(g.decisions <= 30 * g.trials);
        assert!(g.decisions >= 30 * (g.trials - g.collisions));
        assert_eq!(g.collision_split.ego_total(), g.collisions, "collision split of {g:?}");
        let s = &g.safety;
        for share in [s.ttc_below_3s_share, s.headway_below_1s_share] {
            assert!((0.0..=1.0).contains(&share), "share {share} out of [0, 1]");
        }
        assert!(s.min_ttc_min_s <= s.min_ttc_p5_s.or(Some(f64::INFINITY)));
        assert!(s.min_ttc_p5_s.unwrap_or(f64::INFINITY) <= s.min_ttc_p50_s.unwrap_or(f64::INFINITY));
        // 12 s per trial: events per hour from the count.
        let hours = g.simulated_s / 3600.0;
        assert!((s.hard_braking_per_hour * hours - s.hard_braking_events as f64).abs() < 1e-6);
    }
    // The overall rows pool the configuration rows.
    for &d in &one.drivers {
        let parts: Vec<_> = one.groups.iter().filter(|g| g.driver == d).collect();
        let all = one.overall_for(d).unwrap();
        let events: u64 = parts.iter().map(|g| g.safety.hard_braking_events).sum();
        assert_eq!(all.safety.hard_braking_events, events);
        let sv_sv: u64 = parts.iter().map(|g| g.collision_split.sv_sv).sum();
        assert_eq!(all.collision_split.sv_sv, sv_sv);
        let drac = parts.iter().map(|g| g.safety.max_drac_mps2).fold(0.0, f64::max);
        assert_eq!(all.safety.max_drac_mps2, drac);
        let min_speed = parts
            .iter()
            .map(|g| g.safety.min_speed_mps)
            .fold(f64::INFINITY, f64::min);
        assert_eq!(all.safety.min_speed_mps, min_speed);
    }
    // All drivers saw the same scenarios: equal trial counts, same configs.
    for d in [
        DriverKind::PaperLiteral,
        DriverKind::Planner,
        DriverKind::PlannerNoHysteresis,
        DriverKind::IdmMobil,
    ] {
        assert_eq!(one.overall_for(d).unwrap().trials, 6);
    }
    let dir = tempfile::tempdir().unwrap();
    write_campaign(dir.path(), &one).unwrap();
    for f in ["results.json", "results.csv", "results.md", "trials.jsonl"] {
        assert!(dir.path().join("campaign").join(f).exists());
    }
    // trials.jsonl holds every trial of every driver, enough to compute every row again.
    let trials = read_trials(dir.path()).unwrap();
    assert_eq!(trials, one.trials);
    assert_eq!(trials.len(), 3 * 2 * 4);
    for g in one.groups.iter().chain(&one.overall) {
        let outcomes: Vec<TrialOutcome> = trials
            .iter()
            .filter(|t| t.driver == g.driver && g.config_id.is_none_or(|c| c == t.config_id))
            .map(|t| TrialOutcome {
                config_id: t.config_id,
                trial: t.trial,
                driver: t.driver,
                metrics: t.metrics.clone(),
                solve_us: Vec::new(),
                hard_braking: Vec::new(),
            })
            .collect();
        let entry = one.entries.iter().find(|e| Some(e.id) == g.config_id);
        let mut again = aggregate(entry, g.driver, outcomes.iter(), trials[0].dt_s);
        again.solve_time = g.solve_time;
        assert_eq!(&again, g, "row {:?} {:?} from trials.jsonl", g.config_id, g.driver);
    }
    // Paired with itself, the planner differs in nothing.
    let same = compare(
        &trials,
        &trials,
        (DriverKind::Planner, DriverKind::Planner),
        200,
        0.95,
        1,
    )
    .unwrap();
    assert_eq!(same.trials, 6);
    assert!(same
        .figures
        .iter()
        .all(|f| f.verdict != Verdict::Better && f.verdict != Verdict::Worse));
    let csv = String::from_utf8(campaign_csv(&one).unwrap()).unwrap();
    assert_eq!(csv.lines().count(), 1 + 12 + 4);
    let header = csv.lines().next().unwrap();
    for column in [
        "collisions_ego_at_fault",
        "sv_sv_collisions",
        "hard_braking_per_hour",
        "min_ttc_p5_s",
        "min_ttc_p50_s",
        "ttc_below_3s_share",
        "headway_below_1s_share",
        "max_drac_mps2",
        "jerk_rms_mps3",
        "min_speed_mps",
    ] {
        assert!(header.split(',').any(|c| c == column), "results.csv lacks {column}");
    }
    let md = campaign_markdown(&one);
    assert!(md.contains("| paper (Table I) | 8050 |"), "{md}");
    for d in &one.drivers {
        assert!(
            md.contains(&format!("| {} |", d.name())),
            "results.md lacks {}",
            d.name()
        );
    }
}

#[test]
fn markdown_has_all_paper_rows() {
    let entries = scale_trials(&paper_entries(), 0.001).unwrap();
    let mut s = CampaignSettings::new(entries, 1, 2);
    s.duration_s = 0.8;
    s.baselines = false;
    let r = run_campaign(&s, &|| {}).unwrap();
    let md = campaign_markdown(&r);
    let table_rows: Vec<&str> = md
        .lines()
        .filter(|l| l.starts_with("| ") && l.contains(" / "))
        .collect();
    // 18 configurations + overall in Table I, plus the header of the baseline table.
    assert!(table_rows.len() >= 19, "{md}");
    for (id, nor) in [(1, "99.84%"), (6, "93.34%"), (12, "97.96%"), (18, "98.88%")] {
        assert!(
            md.lines()
                .any(|l| l.starts_with(&format!("| {id} |")) && l.contains(nor)),
            "row {id} lacks the paper's NOR {nor}:\n{md}"
        );
    }
    assert!(md.contains("**Overall**") && md.contains("98.77%") && md.contains("8050"));
    assert!(md.contains("## Baselines and safety"));
}

#[test]
fn the_svs_behaviour_reaches_the_traffic_and_is_recorded() {
    let entries = parse_entries(TINY, false).unwrap();
    let run = |sv: SvBehaviour| {
        let mut s = CampaignSettings::new(entries.clone(), 9, 2);
        s.duration_s = 12.0;
        s.baselines = false;
        s.params.sv = sv;
        run_campaign(&s, &|| {}).unwrap()
    };
    let random = run(SvBehaviour::default());
    let calm = run(SvBehaviour::deterministic());
    for (r, sv) in [(&random, SvBehaviour::default()), (&calm, SvBehaviour::deterministic())] {
        assert_eq!(r.sv, sv);
        assert!(r.trials.iter().all(|t| t.sv == sv));
        assert!(campaign_markdown(r).contains(&format!(
            "keep their longitudinal maneuver with probability {}",
            sv.p_keep_long
        )));
    }
    // Same seeds, other SV behaviour: the trials are not those of the default traffic.
    assert_eq!(random.trials.len(), calm.trials.len());
    let differ = random
        .trials
        .iter()
        .zip(&calm.trials)
        .filter(|(a, b)| a.metrics != b.metrics)
        .count();
    assert!(differ > 0, "calm SVs changed no trial");
    // The command line: the values reach the run and its files.
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("tiny.toml");
    std::fs::write(&config, TINY).unwrap();
    let sim_client = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_sim_client"))
            .arg("campaign")
            .args(args)
            .output()
            .unwrap()
    };
    let out_dir = dir.path().join("calm");
    let ran = sim_client(&[
        "--config",
        config.to_str().unwrap(),
        "--seed",
        "9",
        "--threads",
        "1",
        "--baselines",
        "false",
        "--sv-keep-long",
        "1",
        "--sv-lane-change",
        "0",
        "--sv-slowdown-decel",
        "2.5",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    let sv = SvBehaviour {
        gentle_decel: 2.5,
        ..SvBehaviour::deterministic()
    };
    assert!(ran.status.success(), "{}", String::from_utf8_lossy(&ran.stderr));
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("campaign/results.json")).unwrap()).unwrap();
    assert_eq!(results["sv"], serde_json::to_value(sv).unwrap());
    let trials = read_trials(&out_dir).unwrap();
    assert_eq!(trials.len(), 6);
    assert!(trials.iter().all(|t| t.sv == sv));
    // A probability outside [0, 1] is refused before anything is opened: with a Zenoh transport
    // and no router to reach, a valid value fails on the missing endpoint instead.
    let remote = ["--transport", "zenoh", "--baselines", "false"];
    let refused = sim_client(&[&remote[..], &["--sv-keep-long", "1.5"]].concat());
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("sv.p_keep_long") && err.contains("[0, 1]"), "{err}");
    // So is a slowdown harder than any vehicle brakes (the simulator's 9 m/s^2), or none.
    for decel in ["9.5", "0"] {
        let refused = sim_client(&[&remote[..], &["--sv-slowdown-decel", decel]].concat());
        assert!(!refused.status.success());
        let err = String::from_utf8_lossy(&refused.stderr);
        assert!(err.contains("sv.gentle_decel"), "{decel}: {err}");
    }
    let unreachable = sim_client(&remote);
    assert!(!unreachable.status.success());
    let err = String::from_utf8_lossy(&unreachable.stderr);
    assert!(
        err.contains("--zenoh-connect") && !err.contains("sv.p_keep_long"),
        "{err}"
    );
}
