//! Files: CSV, JSON and markdown writers of the experiments. The formatting functions
//! return strings/bytes; only the `write_*` functions touch the filesystem. The campaign's
//! files are in [`crate::campaign_report`], re-exported here.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::cases::{Ablation, Case1, Case2, CaseRun};
use crate::episode::{DecisionRecord, VehicleState};
use crate::error::{Result, SimClientError};
use crate::metrics::{EpisodeMetrics, SolveTimeStats};
use crate::plot;
use crate::prediction::{sv_predictions, SvPrediction};

pub use crate::campaign_report::{campaign_csv, campaign_markdown, write_campaign};

pub(crate) fn csv_bytes<T: Serialize>(rows: &[T]) -> Result<Vec<u8>> {
    let mut w = csv::Writer::from_writer(Vec::new());
    for r in rows {
        w.serialize(r)?;
    }
    w.into_inner()
        .map_err(|e| SimClientError::io("<csv buffer>", e.into_error()))
}

/// The decisions CSV (reproducible: no wall-clock column).
pub fn decisions_csv(decisions: &[DecisionRecord]) -> Result<Vec<u8>> {
    csv_bytes(decisions)
}

/// The trajectory CSV: one row per vehicle per low-level step.
pub fn trajectory_csv(states: &[VehicleState]) -> Result<Vec<u8>> {
    csv_bytes(states)
}

/// Pretty JSON with a trailing newline.
pub fn json_bytes<T: Serialize>(value: &T) -> Result<Vec<u8>> {
    let mut v = serde_json::to_vec_pretty(value)?;
    v.push(b'\n');
    Ok(v)
}

#[derive(Serialize)]
struct TimingRow {
    index: u64,
    time_s: f64,
    solve_us: u64,
}

/// Per-decision solve times and their statistics (not reproducible, hence a separate file).
pub fn timing_json(decisions: &[DecisionRecord]) -> Result<Vec<u8>> {
    #[derive(Serialize)]
    struct Timing {
        solve_time: SolveTimeStats,
        decisions: Vec<TimingRow>,
    }
    let mut us: Vec<u64> = decisions.iter().map(|d| d.solve_us).collect();
    json_bytes(&Timing {
        solve_time: SolveTimeStats::from_us(&mut us),
        decisions: decisions
            .iter()
            .map(|d| TimingRow {
                index: d.index,
                time_s: d.time_s,
                solve_us: d.solve_us,
            })
            .collect(),
    })
}

pub(crate) fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| SimClientError::io(dir, e))
}

pub(crate) fn write(path: PathBuf, bytes: &[u8]) -> Result<PathBuf> {
    std::fs::write(&path, bytes).map_err(|e| SimClientError::io(&path, e))?;
    Ok(path)
}

fn write_decision_files(dir: &Path, run: &CaseRun, suffix: &str) -> Result<Vec<PathBuf>> {
    Ok(vec![
        write(
            dir.join(format!("decisions{suffix}.csv")),
            &decisions_csv(&run.episode.decisions)?,
        )?,
        write(
            dir.join(format!("timing{suffix}.json")),
            &timing_json(&run.episode.decisions)?,
        )?,
    ])
}

/// The planner's SV predictions at the decision instants `picks`, from the situations the
/// run recorded (none when it recorded none).
pub fn predictions_at(run: &CaseRun, picks: &[usize], figure: &Path) -> Result<Vec<Vec<SvPrediction>>> {
    picks
        .iter()
        .map(
            |&k| match run.episode.decisions.get(k).and_then(|d| d.request.as_ref()) {
                None => Ok(Vec::new()),
                Some(r) => sv_predictions(&run.config, &r.to_situation()).map_err(|e| SimClientError::Plot {
                    path: figure.display().to_string(),
                    message: format!("predictions at decision {k}: {e}"),
                }),
            },
        )
        .collect()
}

/// The speed and snapshot figures of one run at the decision instants `picks`.
fn write_run_figures(dir: &Path, run: &CaseRun, label: &str, suffix: &str, picks: &[usize]) -> Result<Vec<PathBuf>> {
    let speed = dir.join(format!("speed{suffix}.svg"));
    let title = format!("Speed, {label}: ego vs. SVs (shaded: corrective mode per reference SV)");
    plot::speed_plot(&speed, &run.episode, &title, picks)?;
    let snaps = dir.join(format!("snapshots{suffix}.svg"));
    let predictions = predictions_at(run, picks, &snaps)?;
    plot::snapshots_plot(&snaps, &run.scenario, &run.episode, picks, &predictions)?;
    Ok(vec![speed, snaps])
}

/// Writes one Case 1 run into `dir`: trajectory.csv, decisions.csv, summary.json,
/// timing.json, speed.svg, beta.svg, snapshots.svg.
fn write_case1_run(dir: &Path, run: &CaseRun, label: &str) -> Result<Vec<PathBuf>> {
    create_dir(dir)?;
    let mut files = vec![
        write(dir.join("trajectory.csv"), &trajectory_csv(&run.episode.trajectory)?)?,
        write(dir.join("summary.json"), &json_bytes(&run.metrics)?)?,
    ];
    files.extend(write_decision_files(dir, run, "")?);
    let picks = plot::snapshot_instants(&run.episode);
    files.extend(write_run_figures(dir, run, label, "", &picks)?);
    let beta = dir.join("beta.svg");
    plot::beta_plot(&beta, &run.episode)?;
    files.push(beta);
    Ok(files)
}

/// Writes `DIR/case1/`: the planner's run (trajectory.csv, decisions.csv, summary.json,
/// timing.json, speed.svg, beta.svg, snapshots.svg), the preset's in `case1/paper_literal/`,
/// and comparison.md with both summaries side by side. Returns the files written.
pub fn write_case1(out: &Path, case: &Case1) -> Result<Vec<PathBuf>> {
    let dir = out.join("case1");
    let mut files = write_case1_run(&dir, &case.planner, "planner")?;
    let mut columns = vec![("planner", &case.planner.metrics)];
    if let Some(paper) = &case.paper_literal {
        files.extend(write_case1_run(
            &dir.join("paper_literal"),
            paper,
            "paper-literal preset",
        )?);
        columns.push(("paper_literal", &paper.metrics));
    }
    let md = metrics_comparison_markdown("Case 1: the Table II scene, 40 s", &columns);
    files.push(write(dir.join("comparison.md"), md.as_bytes())?);
    Ok(files)
}

/// Writes one ablation into `dir`: both runs' decisions, speed and snapshot figures (at the
/// same instants, chosen on the run with hysteresis) and ablation.svg (beta over time).
fn write_ablation(dir: &Path, ablation: &Ablation, label: &str) -> Result<Vec<PathBuf>> {
    create_dir(dir)?;
    let picks = plot::snapshot_instants(&ablation.with.episode);
    let mut files = Vec::new();
    for (run, which, suffix) in [
        (&ablation.with, "with hysteresis", "_with_hysteresis"),
        (&ablation.without, "without hysteresis", "_without_hysteresis"),
    ] {
        files.extend(write_decision_files(dir, run, suffix)?);
        files.extend(write_run_figures(
            dir,
            run,
            &format!("{label} {which}"),
            suffix,
            &picks,
        )?);
    }
    let beta = dir.join("ablation.svg");
    plot::ablation_plot(&beta, &ablation.with.episode, &ablation.without.episode)?;
    files.push(beta);
    Ok(files)
}

/// Writes `DIR/case2/`: summary.json, comparison.md, the planner's ablation (decisions,
/// speed_*.svg, snapshots_*.svg, ablation.svg) and the preset's in `case2/paper_literal/`.
pub fn write_case2(out: &Path, case: &Case2) -> Result<Vec<PathBuf>> {
    let dir = out.join("case2");
    let mut files = write_ablation(&dir, &case.planner, "planner")?;
    files.push(write(dir.join("summary.json"), &json_bytes(&case.summary())?)?);
    let mut columns = vec![
        ("planner, hysteresis", &case.planner.with.metrics),
        ("planner, no hysteresis", &case.planner.without.metrics),
    ];
    if let Some(paper) = &case.paper_literal {
        files.extend(write_ablation(&dir.join("paper_literal"), paper, "paper-literal")?);
        columns.push(("paper_literal, hysteresis", &paper.with.metrics));
        columns.push(("paper_literal, no hysteresis", &paper.without.metrics));
    }
    let md = metrics_comparison_markdown("Case 2: hysteresis on and off", &columns);
    files.push(write(dir.join("comparison.md"), md.as_bytes())?);
    Ok(files)
}

pub(crate) fn ttc_cell(t: Option<f64>) -> String {
    t.map_or_else(|| "inf".into(), |v| format!("{v:.2}"))
}

/// Episode metrics side by side, one column per run.
pub fn metrics_comparison_markdown(title: &str, runs: &[(&str, &EpisodeMetrics)]) -> String {
    type Row = (&'static str, fn(&EpisodeMetrics) -> String);
    let rows: [Row; 16] = [
        ("decisions", |m| m.decisions.to_string()),
        ("nominal / relaxation / fallback", |m| {
            let l = &m.decisions_by_layer;
            format!("{} / {} / {}", l.nominal, l.global_relaxation, l.fallback)
        }),
        ("collisions (ego at fault / ego hit in lane / SV-SV)", |m| {
            let c = &m.collision_split;
            format!(
                "{} ({} / {} / {})",
                m.collisions, c.ego_at_fault, c.ego_hit_in_lane, c.sv_sv
            )
        }),
        ("lane changes", |m| m.lane_changes.to_string()),
        ("beta switches", |m| m.beta_switches.to_string()),
        ("corrective time (s)", |m| format!("{:.1}", m.corrective_time_s)),
        ("mean speed (m/s)", |m| format!("{:.2}", m.mean_speed_mps)),
        ("min speed (m/s)", |m| format!("{:.2}", m.safety.min_speed_mps)),
        ("min TTC (s)", |m| ttc_cell(m.safety.min_ttc_s)),
        ("time with TTC < 3 s", |m| pct(m.safety.ttc_below_3s_share)),
        ("time with headway < 1 s", |m| pct(m.safety.headway_below_1s_share)),
        ("max DRAC (m/s^2)", |m| format!("{:.2}", m.safety.max_drac_mps2)),
        ("hard-braking events", |m| m.safety.hard_braking_events.to_string()),
        ("hard-braking events per hour", |m| {
            let hours = m.simulated_s / 3600.0;
            format!(
                "{:.1}",
                if hours > 0.0 {
                    f64::from(m.safety.hard_braking_events) / hours
                } else {
                    0.0
                }
            )
        }),
        ("jerk RMS (m/s^3)", |m| format!("{:.3}", m.safety.jerk_rms_mps3)),
        ("max abs jerk (m/s^3)", |m| format!("{:.3}", m.safety.jerk_max_abs_mps3)),
    ];
    let mut s = format!("# {title}\n\n| metric |");
    for (name, _) in runs {
        let _ = write!(s, " {name} |");
    }
    s.push_str("\n|---|");
    s.push_str(&"---|".repeat(runs.len()));
    s.push('\n');
    for (label, cell) in rows {
        let _ = write!(s, "| {label} |");
        for (_, m) in runs {
            let _ = write!(s, " {} |", cell(m));
        }
        s.push('\n');
    }
    s
}

pub(crate) fn pct(x: f64) -> String {
    format!("{:.2}%", 100.0 * x)
}

/// One line summing up an episode (the case commands print it).
pub fn episode_summary_line(m: &EpisodeMetrics) -> String {
    let c = &m.collision_split;
    let s = &m.safety;
    format!(
        "{} decisions (nominal {}, relaxation {}, fallback {}), collisions {} (ego at fault {}, ego hit in lane {}, SV-SV {}), \
         lane changes {}, beta switches {}, corrective {:.1} s, mean speed {:.2} m/s, min speed {:.2} m/s, \
         min TTC {} s, TTC < 3 s {}, headway < 1 s {}, max DRAC {:.2} m/s^2, hard brakes {}, jerk RMS {:.2} max {:.2} m/s^3",
        m.decisions,
        m.decisions_by_layer.nominal,
        m.decisions_by_layer.global_relaxation,
        m.decisions_by_layer.fallback,
        m.collisions,
        c.ego_at_fault,
        c.ego_hit_in_lane,
        c.sv_sv,
        m.lane_changes,
        m.beta_switches,
        m.corrective_time_s,
        m.mean_speed_mps,
        s.min_speed_mps,
        ttc_cell(s.min_ttc_s),
        pct(s.ttc_below_3s_share),
        pct(s.headway_below_1s_share),
        s.max_drac_mps2,
        s.hard_braking_events,
        s.jerk_rms_mps3,
        s.jerk_max_abs_mps3,
    )
}
