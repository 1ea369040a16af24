//! The campaign's files: results.csv, results.md, results.json, trials.jsonl (and
//! hard-braking.jsonl).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::campaign::{CampaignResults, DriverKind, GroupResult, TracedHardBraking, TrialRecord};
use crate::campaign_aggregate::ratio;
use crate::error::{Result, SimClientError};
use crate::paper::{paper_row_for, PaperRow, PAPER_OVERALL};
use crate::report::{create_dir, csv_bytes, json_bytes, pct, ttc_cell, write};

fn opt_pct(x: Option<f64>) -> String {
    x.map_or_else(|| "-".to_string(), |v| format!("{:.2}%", 100.0 * v))
}

fn range(r: Option<(f64, f64)>) -> String {
    r.map_or_else(|| "-".into(), |(a, b)| format!("[{a}, {b}]"))
}

/// One flat row of results.csv. A minimum TTC of `inf` means the ego never closed in.
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
    collisions_ego_at_fault: u64,
    collisions_ego_hit_in_lane: u64,
    sv_sv_collisions: u64,
    collision_rate: f64,
    nor: String,
    plain_nor: String,
    nominal_plain: u64,
    nominal_relaxed_by_choice: u64,
    nominal_needed_allowance: u64,
    nominal_needed_soft_band: u64,
    nominal_needed_either: u64,
    gsrr: String,
    fbr: String,
    solve_mean_ms: f64,
    solve_p99_ms: f64,
    solve_max_ms: f64,
    mean_speed_mps: f64,
    min_speed_mps: f64,
    lane_changes_per_min: f64,
    beta_switches_per_min: f64,
    hard_braking_events: u64,
    hard_braking_per_hour: f64,
    min_ttc_min_s: String,
    min_ttc_p5_s: String,
    min_ttc_p50_s: String,
    ttc_below_3s_share: f64,
    headway_below_1s_share: f64,
    max_drac_mps2: f64,
    jerk_rms_mps3: f64,
    jerk_max_abs_mps3: f64,
}

fn csv_row(g: &GroupResult) -> CsvRow {
    let opt = |x: Option<f64>| x.map_or_else(String::new, |v| format!("{v}"));
    let ttc = |x: Option<f64>| x.map_or_else(|| "inf".into(), |v| format!("{v}"));
    let s = &g.safety;
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
        collisions_ego_at_fault: g.collision_split.ego_at_fault,
        collisions_ego_hit_in_lane: g.collision_split.ego_hit_in_lane,
        sv_sv_collisions: g.collision_split.sv_sv,
        collision_rate: g.collision_rate,
        nor: opt(g.nor),
        plain_nor: opt(g.plain_nor),
        nominal_plain: g.nominal_split.plain,
        nominal_relaxed_by_choice: g.nominal_split.relaxed_by_choice,
        nominal_needed_allowance: g.nominal_split.needed_allowance,
        nominal_needed_soft_band: g.nominal_split.needed_soft_band,
        nominal_needed_either: g.nominal_split.needed_either,
        gsrr: opt(g.gsrr),
        fbr: opt(g.fbr),
        solve_mean_ms: g.solve_time.mean_ms,
        solve_p99_ms: g.solve_time.p99_ms,
        solve_max_ms: g.solve_time.max_ms,
        mean_speed_mps: g.mean_speed_mps,
        min_speed_mps: s.min_speed_mps,
        lane_changes_per_min: g.lane_changes_per_min,
        beta_switches_per_min: g.beta_switches_per_min,
        hard_braking_events: s.hard_braking_events,
        hard_braking_per_hour: s.hard_braking_per_hour,
        min_ttc_min_s: ttc(s.min_ttc_min_s),
        min_ttc_p5_s: ttc(s.min_ttc_p5_s),
        min_ttc_p50_s: ttc(s.min_ttc_p50_s),
        ttc_below_3s_share: s.ttc_below_3s_share,
        headway_below_1s_share: s.headway_below_1s_share,
        max_drac_mps2: s.max_drac_mps2,
        jerk_rms_mps3: s.jerk_rms_mps3,
        jerk_max_abs_mps3: s.jerk_max_abs_mps3,
    }
}

/// results.csv: one row per configuration and driver, then one overall row per driver.
pub fn campaign_csv(r: &CampaignResults) -> Result<Vec<u8>> {
    let rows: Vec<CsvRow> = r.groups.iter().chain(&r.overall).map(csv_row).collect();
    csv_bytes(&rows)
}

/// The paper's row for a group: the matching Table I row, or its overall row.
fn paper_row(g: &GroupResult) -> Option<&'static PaperRow> {
    match (g.lanes, g.sv_count, g.speed_range) {
        (Some(l), Some(s), Some(v)) => paper_row_for(l, s, v),
        _ => Some(&PAPER_OVERALL),
    }
}

fn paper_cells(g: &GroupResult) -> [String; 5] {
    match paper_row(g) {
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

const DRIVER_HEADER: &str =
    "| Driver | Trials | Collisions (at fault / hit in lane / SV-SV) | NOR | NOR, plain MPC | GSRR | FBR | \
     Mean speed (m/s) | Beta switches/min | Lane changes/min | Hard brakes/h | Min TTC p5 / p50 (s) | \
     TTC < 3 s | Headway < 1 s | Max DRAC (m/s^2) |";
const DRIVER_RULE: &str = "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|";

/// A group as a row of the driver tables.
fn driver_row(g: &GroupResult) -> String {
    let c = &g.collision_split;
    let s = &g.safety;
    format!(
        "| {} | {} | {} ({} / {} / {}) | {} | {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.1} | {} / {} | {} | {} | {:.2} |",
        g.driver.name(),
        g.trials,
        pct(g.collision_rate),
        c.ego_at_fault,
        c.ego_hit_in_lane,
        c.sv_sv,
        opt_pct(g.nor),
        opt_pct(g.plain_nor),
        opt_pct(g.gsrr),
        opt_pct(g.fbr),
        g.mean_speed_mps,
        g.beta_switches_per_min,
        g.lane_changes_per_min,
        s.hard_braking_per_hour,
        ttc_cell(s.min_ttc_p5_s),
        ttc_cell(s.min_ttc_p50_s),
        pct(s.ttc_below_3s_share),
        pct(s.headway_below_1s_share),
        s.max_drac_mps2,
    )
}

/// The paper's Table I figures in the driver table's columns (it reports nothing else).
fn paper_driver_row(p: &PaperRow) -> String {
    format!(
        "| paper (Table I) | {} | {:.2}% | {:.2}% | {:.2}% | {:.2}% | {:.2}% | - | - | - | - | - | - | - | - |",
        p.trials, p.collision_pct, p.nor_pct, p.nor_pct, p.gsrr_pct, p.fbr_pct
    )
}

/// results.md: Table I (paper beside ours, planner driver), every driver overall beside the
/// paper's overall row, and every driver per configuration beside the paper's row.
pub fn campaign_markdown(r: &CampaignResults) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Case 3: randomized campaign\n");
    let _ = writeln!(
        s,
        "Seed {}, episodes of {} s, {} configuration(s), wall time {:.1} s on {} thread(s). \
         SVs keep their longitudinal maneuver with probability {} and try a random lane change \
         with probability {} per decision instant; in their slowdown mode they brake at {} m/s^2.\n",
        r.seed,
        r.duration_s,
        r.entries.len(),
        r.wall_time_s,
        r.threads,
        r.sv.p_keep_long,
        r.sv.p_random_lane_change,
        r.sv.gentle_decel,
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
    let _ = writeln!(s, "\n## Baselines and safety (same scenarios and seeds)\n");
    let _ = writeln!(s, "{DRIVER_HEADER}");
    let _ = writeln!(s, "{DRIVER_RULE}");
    let _ = writeln!(s, "{}", paper_driver_row(&PAPER_OVERALL));
    for g in &r.overall {
        let _ = writeln!(s, "{}", driver_row(g));
    }
    nominal_table(&mut s, &r.overall);
    let _ = writeln!(
        s,
        "\n| Driver | Solve mean / p99 / max (ms) | Jerk RMS / max (m/s^3) | Min speed (m/s) |"
    );
    let _ = writeln!(s, "|---|---|---|---|");
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
            "| {} | {solve} | {:.2} / {:.2} | {:.2} |",
            g.driver.name(),
            g.safety.jerk_rms_mps3,
            g.safety.jerk_max_abs_mps3,
            g.safety.min_speed_mps
        );
    }
    let _ = writeln!(s, "\n## Per configuration\n");
    for e in &r.entries {
        let _ = writeln!(
            s,
            "### Configuration {}: {} lanes, {} SVs, speeds {}\n",
            e.id,
            e.traffic.lanes,
            e.traffic.sv_count,
            range(Some(e.traffic.speed_range))
        );
        let _ = writeln!(s, "{DRIVER_HEADER}");
        let _ = writeln!(s, "{DRIVER_RULE}");
        if let Some(p) = paper_row_for(e.traffic.lanes, e.traffic.sv_count, e.traffic.speed_range) {
            let _ = writeln!(s, "{}", paper_driver_row(p));
        }
        for g in r.groups.iter().filter(|g| g.config_id == Some(e.id)) {
            let _ = writeln!(s, "{}", driver_row(g));
        }
        s.push('\n');
    }
    let _ = writeln!(
        s,
        "Collisions: ego collisions (rate over trials), split by cause; SV-SV contacts are counted \
         until the ego's first contact ends the episode. TTC and headway: the ego behind its \
         leader, TTC also of the ego's follower; min TTC percentiles over episodes, `inf` when \
         the ego never closed in. Definitions: docs/safety-metrics.md. The IDM + MOBIL ego's \
         beta is the sign of its acceleration (dead band 0.3 m/s^2)."
    );
    s
}

/// How the nominal decisions of each planner driver stand against the plain MPC (the paper's:
/// no violation allowance, band slack within `d_HS`), as shares of all its decisions.
fn nominal_table(s: &mut String, groups: &[GroupResult]) {
    let _ = writeln!(
        s,
        "\nNominal decisions against the plain MPC (the paper's MPC: no violation allowance, band slack \
         within d_HS), shares of all decisions. `NOR, plain MPC` = plain + relaxed by choice: the \
         figure that compares with the paper's NOR.\n"
    );
    let _ = writeln!(
        s,
        "| Driver | NOR | plain | relaxed by choice | needed the allowance | needed the soft band | needed either |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for g in groups.iter().filter(|g| g.driver != DriverKind::IdmMobil) {
        let share = |n: u64| pct(ratio(n, g.decisions_by_layer.total()));
        let n = &g.nominal_split;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} |",
            g.driver.name(),
            opt_pct(g.nor),
            share(n.plain),
            share(n.relaxed_by_choice),
            share(n.needed_allowance),
            share(n.needed_soft_band),
            share(n.needed_either)
        );
    }
}

/// Writes `DIR/campaign/`: results.json, results.csv, results.md, trials.jsonl.
pub fn write_campaign(out: &Path, r: &CampaignResults) -> Result<Vec<PathBuf>> {
    let dir = out.join("campaign");
    create_dir(&dir)?;
    let mut files = vec![
        write(dir.join("results.json"), &json_bytes(r)?)?,
        write(dir.join("results.csv"), &campaign_csv(r)?)?,
        write(dir.join("results.md"), campaign_markdown(r).as_bytes())?,
        write(dir.join(TRIALS_FILE), &trials_jsonl(&r.trials)?)?,
    ];
    let trace = dir.join(HARD_BRAKING_FILE);
    match &r.hard_braking {
        Some(traced) => files.push(write(trace, &hard_braking_jsonl(traced)?)?),
        // A file of an earlier run would pass for this one's.
        None if trace.exists() => std::fs::remove_file(&trace).map_err(|e| SimClientError::io(&trace, e))?,
        None => {}
    }
    Ok(files)
}

/// Where a campaign writes its trials, in its `campaign/` directory.
pub const TRIALS_FILE: &str = "trials.jsonl";

/// trials.jsonl: one [`TrialRecord`] per line, every driver's every trial.
pub fn trials_jsonl(trials: &[TrialRecord]) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    for t in trials {
        serde_json::to_writer(&mut out, t)?;
        out.push(b'\n');
    }
    Ok(out)
}

/// One line of hard-braking.jsonl: `where` and `accel` as `explain_decision` reads them.
#[derive(Serialize)]
struct HardBrakingLine<'a> {
    #[serde(rename = "where")]
    place: String,
    accel: f64,
    #[serde(flatten)]
    traced: &'a TracedHardBraking,
}

/// Where a traced campaign writes its hard-braking decisions, in its `campaign/` directory.
pub const HARD_BRAKING_FILE: &str = "hard-braking.jsonl";

/// hard-braking.jsonl: every traced hard-braking decision, one JSON object per line, in the
/// form `decision`'s `explain_decision` example reads (`where`, `accel`, `situation`), with
/// the driver, configuration, trial, trial seed, time and layer.
pub fn hard_braking_jsonl(traced: &[TracedHardBraking]) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    for t in traced {
        let line = HardBrakingLine {
            place: format!(
                "{} config {} trial {} t {:.1}",
                t.driver.name(),
                t.config_id,
                t.trial,
                t.decision.time_s
            ),
            accel: t.decision.accel_mps2,
            traced: t,
        };
        serde_json::to_writer(&mut out, &line)?;
        out.push(b'\n');
    }
    Ok(out)
}
