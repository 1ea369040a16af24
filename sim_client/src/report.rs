//! Files: CSV, JSON and markdown writers of the experiments. The formatting functions
//! return strings/bytes; only the `write_*` functions touch the filesystem.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::campaign::{CampaignResults, DriverKind, GroupResult};
use crate::cases::{Case2, CaseRun};
use crate::episode::{DecisionRecord, VehicleState};
use crate::error::{Result, SimClientError};
use crate::metrics::SolveTimeStats;
use crate::paper::{paper_row_for, PAPER_OVERALL};
use crate::plot;

fn csv_bytes<T: Serialize>(rows: &[T]) -> Result<Vec<u8>> {
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

fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| SimClientError::io(dir, e))
}

fn write(path: PathBuf, bytes: &[u8]) -> Result<PathBuf> {
    std::fs::write(&path, bytes).map_err(|e| SimClientError::io(&path, e))?;
    Ok(path)
}

/// Writes `DIR/case1/`: trajectory.csv, decisions.csv, summary.json, timing.json and the
/// plots speed.svg, beta.svg, snapshots.svg. Returns the files written.
pub fn write_case1(out: &Path, run: &CaseRun) -> Result<Vec<PathBuf>> {
    let dir = out.join("case1");
    create_dir(&dir)?;
    let mut files = vec![
        write(dir.join("trajectory.csv"), &trajectory_csv(&run.episode.trajectory)?)?,
        write(dir.join("decisions.csv"), &decisions_csv(&run.episode.decisions)?)?,
        write(dir.join("summary.json"), &json_bytes(&run.metrics)?)?,
        write(dir.join("timing.json"), &timing_json(&run.episode.decisions)?)?,
    ];
    let speed = dir.join("speed.svg");
    plot::speed_plot(&speed, &run.episode)?;
    let beta = dir.join("beta.svg");
    plot::beta_plot(&beta, &run.episode)?;
    let snaps = dir.join("snapshots.svg");
    plot::snapshots_plot(&snaps, &run.scenario, &run.episode)?;
    files.extend([speed, beta, snaps]);
    Ok(files)
}

/// Writes `DIR/case2/`: summary.json, both runs' decisions CSVs and ablation.svg.
pub fn write_case2(out: &Path, case: &Case2) -> Result<Vec<PathBuf>> {
    let dir = out.join("case2");
    create_dir(&dir)?;
    let mut files = vec![
        write(dir.join("summary.json"), &json_bytes(&case.summary())?)?,
        write(
            dir.join("decisions_with_hysteresis.csv"),
            &decisions_csv(&case.with.episode.decisions)?,
        )?,
        write(
            dir.join("decisions_without_hysteresis.csv"),
            &decisions_csv(&case.without.episode.decisions)?,
        )?,
    ];
    let ablation = dir.join("ablation.svg");
    plot::ablation_plot(&ablation, &case.with.episode, &case.without.episode)?;
    files.push(ablation);
    Ok(files)
}

fn opt_pct(x: Option<f64>) -> String {
    x.map_or_else(|| "-".to_string(), |v| format!("{:.2}%", 100.0 * v))
}

fn pct(x: f64) -> String {
    format!("{:.2}%", 100.0 * x)
}

fn range(r: Option<(f64, f64)>) -> String {
    r.map_or_else(|| "-".into(), |(a, b)| format!("[{a}, {b}]"))
}

/// One flat row of results.csv.
#[derive(Serialize)]
struct CsvRow {
    config_id: String,
    driver: &'static str,
    lanes: String,
    sv_count: String,
    speed_lo: String,
    speed_hi: String,
    trials: u64,
    decisions: u64,
    nominal: u64,
    global_relaxation: u64,
    fallback: u64,
    collisions: u64,
    collision_rate: f64,
    nor: String,
    gsrr: String,
    fbr: String,
    solve_mean_ms: f64,
    solve_p99_ms: f64,
    solve_max_ms: f64,
    mean_speed_mps: f64,
    lane_changes_per_min: f64,
    beta_switches_per_min: f64,
}

fn csv_row(g: &GroupResult) -> CsvRow {
    let opt = |x: Option<f64>| x.map_or_else(String::new, |v| format!("{v}"));
    CsvRow {
        config_id: g.config_id.map_or_else(|| "overall".into(), |i| i.to_string()),
        driver: g.driver.name(),
        lanes: g.lanes.map_or_else(String::new, |l| l.to_string()),
        sv_count: g.sv_count.map_or_else(String::new, |l| l.to_string()),
        speed_lo: opt(g.speed_range.map(|r| r.0)),
        speed_hi: opt(g.speed_range.map(|r| r.1)),
        trials: g.trials,
        decisions: g.decisions,
        nominal: g.decisions_by_layer.nominal,
        global_relaxation: g.decisions_by_layer.global_relaxation,
        fallback: g.decisions_by_layer.fallback,
        collisions: g.collisions,
        collision_rate: g.collision_rate,
        nor: opt(g.nor),
        gsrr: opt(g.gsrr),
        fbr: opt(g.fbr),
        solve_mean_ms: g.solve_time.mean_ms,
        solve_p99_ms: g.solve_time.p99_ms,
        solve_max_ms: g.solve_time.max_ms,
        mean_speed_mps: g.mean_speed_mps,
        lane_changes_per_min: g.lane_changes_per_min,
        beta_switches_per_min: g.beta_switches_per_min,
    }
}

/// results.csv: one row per configuration and driver, then one overall row per driver.
pub fn campaign_csv(r: &CampaignResults) -> Result<Vec<u8>> {
    let rows: Vec<CsvRow> = r.groups.iter().chain(&r.overall).map(csv_row).collect();
    csv_bytes(&rows)
}

fn paper_cells(g: &GroupResult) -> [String; 5] {
    let row = match (g.lanes, g.sv_count, g.speed_range) {
        (Some(l), Some(s), Some(v)) => paper_row_for(l, s, v),
        _ => Some(&PAPER_OVERALL),
    };
    match row {
        Some(p) => [
            p.trials.to_string(),
            format!("{:.2}%", p.collision_pct),
            format!("{:.2}%", p.nor_pct),
            format!("{:.2}%", p.gsrr_pct),
            format!("{:.2}%", p.fbr_pct),
        ],
        None => std::array::from_fn(|_| "-".to_string()),
    }
}

/// results.md: Table I (paper beside ours, planner driver) and the baseline comparison.
pub fn campaign_markdown(r: &CampaignResults) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Case 3: randomized campaign\n");
    let _ = writeln!(
        s,
        "Seed {}, episodes of {} s, {} configuration(s), wall time {:.1} s on {} thread(s).\n",
        r.seed,
        r.duration_s,
        r.entries.len(),
        r.wall_time_s,
        r.threads
    );
    let _ = writeln!(
        s,
        "## Table I: paper vs. this planner\n\nEach cell: paper / ours. The paper's values are \
         shown for configurations matching one of its 18 rows.\n"
    );
    let _ = writeln!(
        s,
        "| ID | Lanes | Speed (m/s) | SVs | N | Decisions | Collision rate | NOR | GSRR | FBR |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|");
    let planner_rows = r
        .groups
        .iter()
        .filter(|g| g.driver == DriverKind::Planner)
        .chain(r.overall_for(DriverKind::Planner));
    for g in planner_rows {
        let p = paper_cells(g);
        let id = g.config_id.map_or_else(|| "**Overall**".into(), |i| i.to_string());
        let _ = writeln!(
            s,
            "| {id} | {} | {} | {} | {} / {} | {} | {} / {} | {} / {} | {} / {} | {} / {} |",
            g.lanes.map_or_else(|| "-".into(), |l| l.to_string()),
            range(g.speed_range),
            g.sv_count.map_or_else(|| "-".into(), |l| l.to_string()),
            p[0],
            g.trials,
            g.decisions,
            p[1],
            pct(g.collision_rate),
            p[2],
            opt_pct(g.nor),
            p[3],
            opt_pct(g.gsrr),
            p[4],
            opt_pct(g.fbr),
        );
    }
    let _ = writeln!(s, "\n## Baselines (same scenarios and seeds)\n");
    let _ = writeln!(
        s,
        "| Driver | Trials | Decisions | Collision rate | NOR | GSRR | FBR | Mean speed (m/s) | \
         Lane changes/min | Beta switches/min | Solve mean / p99 / max (ms) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|");
    for g in &r.overall {
        let solve = if g.solve_time.samples > 0 {
            format!(
                "{:.3} / {:.3} / {:.3}",
                g.solve_time.mean_ms, g.solve_time.p99_ms, g.solve_time.max_ms
            )
        } else {
            "-".into()
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {:.2} | {:.2} | {:.2} | {solve} |",
            g.driver.name(),
            g.trials,
            g.decisions,
            pct(g.collision_rate),
            opt_pct(g.nor),
            opt_pct(g.gsrr),
            opt_pct(g.fbr),
            g.mean_speed_mps,
            g.lane_changes_per_min,
            g.beta_switches_per_min,
        );
    }
    let _ = writeln!(
        s,
        "\nThe IDM + MOBIL ego's beta is the sign of its acceleration (dead band 0.3 m/s^2)."
    );
    s
}

/// Writes `DIR/campaign/`: results.json, results.csv, results.md.
pub fn write_campaign(out: &Path, r: &CampaignResults) -> Result<Vec<PathBuf>> {
    let dir = out.join("campaign");
    create_dir(&dir)?;
    Ok(vec![
        write(dir.join("results.json"), &json_bytes(r)?)?,
        write(dir.join("results.csv"), &campaign_csv(r)?)?,
        write(dir.join("results.md"), campaign_markdown(r).as_bytes())?,
    ])
}
