//! `campaign --trace-hard-braking`: every planner decision that brakes hard, with the
//! situation it answered, checked against the episodes run again and decided afresh.

use std::collections::BTreeMap;

use decision::{Planner, PlannerConfig, Situation};
use sim_client::campaign::{parse_entries, run_campaign, trial_spec, CampaignSettings, DriverKind};
use sim_client::campaign_report::{hard_braking_jsonl, write_campaign, HARD_BRAKING_FILE};
use sim_client::episode::{run_episode, Driver};
use sim_client::safety::HARD_BRAKING_MPS2;
use sim_client::Transport;

/// Dense mixed-speed traffic on three lanes, where SVs brake and cut in ahead of the ego
/// (held-out traffic).
const DENSE: &str = r#"
[[config]]
lanes = 3
sv_count = 16
speed_range = [15.0, 30.0]
trials = 30
"#;

/// `(time in tenths of a second, acceleration, situation)` of a trial's hard-braking
/// decisions.
type Braking = Vec<(i64, f64, Situation)>;

fn tenths(t: f64) -> i64 {
    (t * 10.0).round() as i64
}

#[test]
fn the_trace_holds_every_hard_braking_decision_with_the_situation_it_answered() {
    let entries = parse_entries(DENSE, false).unwrap();
    // With the baselines (the planner without hysteresis, IDM + MOBIL): only the "planner"
    // driver is traced, the one `explain_decision` re-decides.
    let mut settings = CampaignSettings::new(entries.clone(), 4242, 2);
    let untraced = run_campaign(&settings, &|| {}).unwrap();
    assert_eq!(untraced.hard_braking, None);
    settings.trace_hard_braking = true;
    let traced = run_campaign(&settings, &|| {}).unwrap();
    // Tracing changes no result.
    let mut same = traced.without_timing();
    same.hard_braking = None;
    assert_eq!(same, untraced.without_timing());
    let traced_decisions = traced.hard_braking.clone().unwrap();

    let mut by_trial: BTreeMap<(u32, u32), Braking> = BTreeMap::new();
    let mut fresh = Planner::new(PlannerConfig::default()).unwrap();
    for t in &traced_decisions {
        assert_eq!(t.driver, DriverKind::Planner);
        assert!(t.decision.accel_mps2 <= HARD_BRAKING_MPS2, "{t:?}");
        // The situation is the one answered: decided afresh, the same answer.
        let d = fresh.decide(&t.decision.situation).unwrap();
        assert_eq!(d.setpoint.accel_mps2, t.decision.accel_mps2, "{t:?}");
        assert_eq!(protocol::Layer::from(d.layer), t.decision.layer);
        by_trial.entry((t.config_id, t.trial)).or_default().push((
            tenths(t.decision.time_s),
            t.decision.accel_mps2,
            t.decision.situation.clone(),
        ));
    }
    assert!(traced_decisions.len() >= 3, "{} traced", traced_decisions.len());

    // Completeness: the trials run again with every request kept, each request decided
    // afresh; the hard-braking ones are exactly the traced ones, situations and all.
    for trial in 0..entries[0].trials {
        let mut spec = trial_spec(&entries[0], trial, &settings).unwrap();
        spec.trace_hard_braking = false;
        spec.record_trajectory = true;
        let mut link = Transport::InProcess.connect(PlannerConfig::default()).unwrap();
        let episode = run_episode(&spec, Driver::Planner(link.as_mut())).unwrap();
        let mut planner = Planner::new(PlannerConfig::default()).unwrap();
        let expected: Braking = episode
            .decisions
            .iter()
            .filter_map(|r| {
                let request = r.request.as_ref().expect("recorded");
                let situation = request.to_situation();
                let accel = planner.decide(&situation).unwrap().setpoint.accel_mps2;
                (accel <= HARD_BRAKING_MPS2).then_some((tenths(r.time_s), accel, situation))
            })
            .collect();
        let key = (entries[0].id, trial);
        assert_eq!(by_trial.remove(&key).unwrap_or_default(), expected, "trial {trial}");
    }
    assert!(by_trial.is_empty(), "{:?}", by_trial.keys());

    // The file's lines carry what `explain_decision` reads.
    let text = String::from_utf8(hard_braking_jsonl(&traced_decisions).unwrap()).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), traced_decisions.len());
    for (line, t) in lines.iter().zip(&traced_decisions) {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        assert!(v["where"].as_str().unwrap().contains(&format!("trial {}", t.trial)));
        assert_eq!(v["accel"].as_f64(), Some(t.decision.accel_mps2));
        let s: Situation = serde_json::from_value(v["situation"].clone()).unwrap();
        assert_eq!(s, t.decision.situation);
    }

    // The file is written with the results, and a later untraced run into the same directory
    // does not leave it behind as if it were its own.
    let out = tempfile::tempdir().unwrap();
    let file = out.path().join("campaign").join(HARD_BRAKING_FILE);
    write_campaign(out.path(), &traced).unwrap();
    assert_eq!(std::fs::read_to_string(&file).unwrap(), text);
    write_campaign(out.path(), &untraced).unwrap();
    assert!(!file.exists());
}
