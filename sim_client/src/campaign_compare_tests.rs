use super::*;
use crate::metrics::{CollisionSplit, EpisodeMetrics, LayerCounts, NominalSplit};
use crate::safety::SafetySummary;
use traffic::{SvBehaviour, TrafficConfig};

/// A trial of 30 s (750 steps of 0.04 s) with the given speed, beta switches and least TTC.
fn trial(config_id: u32, trial: u32, speed: f64, switches: u32, min_ttc: Option<f64>) -> TrialRecord {
    TrialRecord {
        driver: DriverKind::Planner,
        config_id,
        trial,
        seed: 1000 * u64::from(config_id) + u64::from(trial),
        dt_s: 0.04,
        duration_s: 30.0,
        traffic: TrafficConfig {
            lanes: 1 + config_id as u8,
            ..TrafficConfig::default()
        },
        sv: SvBehaviour::default(),
        metrics: EpisodeMetrics {
            decisions: 75,
            decisions_by_layer: LayerCounts::default(),
            nominal_split: NominalSplit::default(),
            collisions: 0,
            collision_time_s: None,
            collision_with: None,
            collision_split: CollisionSplit::default(),
            lane_changes: 0,
            beta_switches: switches,
            corrective_time_s: 0.0,
            mean_speed_mps: speed,
            simulated_s: 30.0,
            safety: SafetySummary {
                steps: 750,
                min_ttc_s: min_ttc,
                ..SafetySummary::default()
            },
        },
    }
}

/// A deterministic stand-in for standard normal noise (a sum of 12 uniforms, minus 6).
fn noise(draws: &mut Draws) -> f64 {
    (0..12).map(|_| draws.next() as f64 / u64::MAX as f64).sum::<f64>() - 6.0
}

fn run(n: u32, mut f: impl FnMut(u32, u32) -> TrialRecord) -> Vec<TrialRecord> {
    (1..=2)
        .flat_map(|c| (0..n).map(move |t| (c, t)))
        .map(|(c, t)| f(c, t))
        .collect()
}

fn figure<'a>(c: &'a Comparison, name: &str) -> &'a FigureComparison {
    c.figures.iter().find(|f| f.name == name).unwrap()
}

#[test]
fn a_run_against_itself_differs_in_nothing() {
    let mut d = Draws(5);
    let base = run(50, |c, t| {
        trial(c, t, 25.0 + noise(&mut d), t % 4, Some(3.0 + t as f64 / 10.0))
    });
    let cmp = compare(&base, &base, (DriverKind::Planner, DriverKind::Planner), 500, 0.95, 1).unwrap();
    assert_eq!(cmp.trials, 100);
    for f in &cmp.figures {
        assert_eq!(f.difference, Some(0.0), "{}", f.name);
        assert_eq!(f.interval, Some((0.0, 0.0)), "{}", f.name);
        assert_eq!(f.verdict, Verdict::NoDifference, "{}", f.name);
    }
}

#[test]
fn a_paired_shift_is_found_and_its_interval_has_the_width_normal_theory_gives() {
    // Speed: the candidate 0.2 m/s faster with unit noise per trial; 2 x 200 trials, so the
    // mean difference has a standard error of 1 / sqrt(400) = 0.05 and a 95 % interval of
    // about +-0.098 around the observed difference.
    let mut d = Draws(11);
    let base = run(200, |c, t| trial(c, t, 25.0 + noise(&mut d), 2, Some(5.0)));
    let cand: Vec<TrialRecord> = base
        .iter()
        .map(|r| {
            let mut r = r.clone();
            r.metrics.mean_speed_mps += 0.2 + noise(&mut d);
            r.metrics.beta_switches += 1;
            r
        })
        .collect();
    let cmp = compare(&base, &cand, (DriverKind::Planner, DriverKind::Planner), 2000, 0.95, 3).unwrap();
    let speed = figure(&cmp, "mean speed (m/s)");
    let diff = speed.difference.unwrap();
    let (lo, hi) = speed.interval.unwrap();
    assert!(lo < diff && diff < hi, "{speed:?}");
    let half = (hi - lo) / 2.0;
    assert!((0.08..0.12).contains(&half), "half width {half}, normal theory 0.098");
    assert!((diff - 0.2).abs() < 3.0 * 0.05, "{diff}");
    assert_eq!(speed.verdict, Verdict::Better);
    // One more switch per 30 s trial is 2 more per minute, in every resample.
    let switches = figure(&cmp, "beta switches/min");
    assert!((switches.difference.unwrap() - 2.0).abs() < 1e-9);
    assert_eq!(switches.verdict, Verdict::Worse);
    // The same inputs and seed give the same intervals; another seed other draws.
    assert_eq!(
        cmp,
        compare(&base, &cand, (DriverKind::Planner, DriverKind::Planner), 2000, 0.95, 3).unwrap()
    );
    let other = compare(&base, &cand, (DriverKind::Planner, DriverKind::Planner), 2000, 0.95, 4).unwrap();
    assert_ne!(figure(&other, "mean speed (m/s)").interval, speed.interval);
}

#[test]
fn a_ttc_percentile_shift_is_resampled_like_the_report_computes_it() {
    // The candidate's least TTC is 0.5 s shorter in every trial: p5 and p50 move by 0.5 in
    // every resample, so the interval is that point.
    let base = run(100, |c, t| {
        trial(c, t, 25.0, 2, Some(2.0 + (t * 7 % 100) as f64 / 10.0))
    });
    let cand: Vec<TrialRecord> = base
        .iter()
        .map(|r| {
            let mut r = r.clone();
            r.metrics.safety.min_ttc_s = r.metrics.safety.min_ttc_s.map(|t| t - 0.5);
            r
        })
        .collect();
    let cmp = compare(&base, &cand, (DriverKind::Planner, DriverKind::Planner), 300, 0.9, 1).unwrap();
    for name in ["min TTC p5 (s)", "min TTC p50 (s)"] {
        let f = figure(&cmp, name);
        let d = f.difference.unwrap();
        assert!((d + 0.5).abs() < 1e-9, "{name}: {d}");
        let (lo, hi) = f.interval.unwrap();
        assert!((lo + 0.5).abs() < 1e-9 && (hi + 0.5).abs() < 1e-9, "{name}: {lo} {hi}");
        assert_eq!(f.verdict, Verdict::Worse);
    }
    // Each configuration's trial 0 has the least TTC (2.0 s, 1.5 s in the candidate).
    let lowest = cmp.lowest_candidate_ttc(3);
    let first: Vec<_> = lowest
        .iter()
        .map(|t| (t.config_id, t.trial, t.candidate_min_ttc_s))
        .collect();
    assert_eq!(first[..2], [(1, 0, Some(1.5)), (2, 0, Some(1.5))]);
    assert!(lowest[2].candidate_min_ttc_s.unwrap() > 1.5);
    assert_eq!(lowest[0].baseline_min_ttc_s, Some(2.0));
}

#[test]
fn runs_of_other_trials_or_seeds_are_refused() {
    let base = run(5, |c, t| trial(c, t, 25.0, 1, None));
    let fewer: Vec<TrialRecord> = base.iter().take(9).cloned().collect();
    let err = compare(&base, &fewer, (DriverKind::Planner, DriverKind::Planner), 10, 0.95, 1).unwrap_err();
    assert!(err.to_string().contains("different trials"), "{err}");
    let mut reseeded = base.clone();
    reseeded[3].seed += 1;
    let err = compare(
        &base,
        &reseeded,
        (DriverKind::Planner, DriverKind::Planner),
        10,
        0.95,
        1,
    )
    .unwrap_err();
    assert!(err.to_string().contains("different seeds"), "{err}");
    let err = compare(&base, &base, (DriverKind::IdmMobil, DriverKind::IdmMobil), 10, 0.95, 1).unwrap_err();
    assert!(err.to_string().contains("no trial of idm_mobil"), "{err}");
    let mut other_traffic = base.clone();
    other_traffic.iter_mut().for_each(|r| r.traffic.sv_count += 1);
    let err = compare(
        &base,
        &other_traffic,
        (DriverKind::Planner, DriverKind::Planner),
        10,
        0.95,
        1,
    )
    .unwrap_err();
    assert!(err.to_string().contains("other traffic"), "{err}");
    // The same configurations with calmer SVs are other traffic too.
    let mut calmer = base.clone();
    calmer.iter_mut().for_each(|r| r.sv = SvBehaviour::deterministic());
    let err = compare(&base, &calmer, (DriverKind::Planner, DriverKind::Planner), 10, 0.95, 1).unwrap_err();
    assert!(err.to_string().contains("the SVs drove otherwise"), "{err}");
    let mut longer = base.clone();
    longer[0].duration_s = 60.0;
    assert!(compare(&base, &longer, (DriverKind::Planner, DriverKind::Planner), 10, 0.95, 1).is_err());
    let mut twice = base.clone();
    twice.push(base[0].clone());
    assert!(compare(&twice, &base, (DriverKind::Planner, DriverKind::Planner), 10, 0.95, 1).is_err());
    assert!(compare(&base, &base, (DriverKind::Planner, DriverKind::Planner), 0, 0.95, 1).is_err());
    assert!(compare(&base, &base, (DriverKind::Planner, DriverKind::Planner), 10, 1.0, 1).is_err());
}

#[test]
fn records_read_back_from_trials_jsonl() {
    let base = run(3, |c, t| trial(c, t, 20.0 + t as f64, t, Some(4.0)));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("campaign");
    std::fs::create_dir_all(&path).unwrap();
    std::fs::write(
        path.join("trials.jsonl"),
        crate::campaign_report::trials_jsonl(&base).unwrap(),
    )
    .unwrap();
    assert_eq!(read_trials(dir.path()).unwrap(), base);
    assert_eq!(read_trials(&path.join("trials.jsonl")).unwrap(), base);
    std::fs::write(path.join("trials.jsonl"), "{\"driver\": \"planner\"}\n").unwrap();
    let err = read_trials(dir.path()).unwrap_err();
    assert!(err.to_string().contains("line 1"), "{err}");
}

#[test]
fn two_drivers_of_one_run_are_each_aggregated_as_what_they_are() {
    // The same trials driven by the IDM + MOBIL ego: it has no layers, so NOR and FBR are
    // undefined for it, not 0.
    let planner = run(20, |c, t| trial(c, t, 25.0, 2, Some(5.0)));
    let mut both = planner.clone();
    both.extend(planner.iter().map(|r| {
        let mut r = r.clone();
        r.driver = DriverKind::IdmMobil;
        r.metrics.mean_speed_mps -= 1.0;
        r
    }));
    let cmp = compare(&both, &both, (DriverKind::IdmMobil, DriverKind::Planner), 200, 0.95, 1).unwrap();
    assert_eq!(cmp.trials, 40);
    assert!((figure(&cmp, "mean speed (m/s)").difference.unwrap() - 1.0).abs() < 1e-9);
    for name in ["NOR (%)", "FBR (%)"] {
        let f = figure(&cmp, name);
        assert_eq!((f.baseline, f.verdict), (None, Verdict::Undefined), "{name}");
    }
    assert!(comparison_table(&cmp).starts_with("planner against idm_mobil:"));
}

#[test]
fn a_trial_written_before_the_sv_behaviour_was_recorded_reads_as_the_default() {
    let mut line = serde_json::to_value(trial(1, 0, 25.0, 3, Some(4.0))).unwrap();
    line.as_object_mut()
        .unwrap()
        .remove("sv")
        .expect("the record has the field");
    let read: TrialRecord = serde_json::from_value(line).unwrap();
    assert_eq!(read.sv, SvBehaviour::default());
    let mut calm = trial(1, 0, 25.0, 3, Some(4.0));
    calm.sv = SvBehaviour::deterministic();
    let round_trip: TrialRecord = serde_json::from_str(&serde_json::to_string(&calm).unwrap()).unwrap();
    assert_eq!(round_trip.sv, SvBehaviour::deterministic());
}
