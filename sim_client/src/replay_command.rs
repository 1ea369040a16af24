//! `sim_client replay` and `case1 --record`: the command-line side of recordings.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use sim_client::cases;
use sim_client::log_replay::{read_traffic_log, replay_log, Perturbation};
use sim_client::record::{write_trial, GroundTruth, TrialInfo};
use sim_client::Transport;

/// `sim_client replay FILE.mcap`.
#[derive(Args)]
pub struct ReplayArgs {
    /// A simulator recording (`case1 --record`) or a foreign one with `/sim/trial` and
    /// `/sim/vehicles` (docs/recording.md).
    pub file: PathBuf,
    /// Shift every SV's recorded trajectory along the road by its own seeded offset of at
    /// most this many metres.
    #[arg(long, value_name = "M")]
    pub perturb_sv_m: Option<f64>,
    /// Seed of the perturbation.
    #[arg(long, default_value_t = 1)]
    pub perturb_seed: u64,
    /// Also write the report as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

/// Runs a log replay and prints its scores.
pub fn run_replay(args: &ReplayArgs, transport: &Transport, config: &decision::PlannerConfig) -> Result<()> {
    let log = read_traffic_log(&args.file)?;
    let perturbation = args.perturb_sv_m.map(|m| Perturbation {
        seed: args.perturb_seed,
        max_offset_m: m,
    });
    let (report, _episode) = replay_log(&log, config, transport, perturbation)?;
    let d = &report.ego_deviation;
    println!(
        "replay {}: {} SVs on their recorded trajectories{}",
        args.file.display(),
        report.svs,
        perturbation.map_or(String::new(), |p| format!(
            ", shifted by up to {} m (seed {})",
            p.max_offset_m, p.seed
        ))
    );
    println!("  {}", sim_client::report::episode_summary_line(&report.metrics));
    println!(
        "  ego vs the recording over {} steps: max |dx| {:.4} m, |dy| {:.4} m, |dv| {:.4} m/s",
        d.steps, d.max_dx_m, d.max_dy_m, d.max_dv_mps
    );
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&report)?)
            .with_context(|| format!("writing {}", path.display()))?;
        println!("  wrote {}", path.display());
    }
    Ok(())
}

/// Runs case 1's planner trial while recording it to `path`.
pub fn record_case1(
    config: &decision::PlannerConfig,
    transport: &Transport,
    seed: u64,
    path: &Path,
) -> Result<cases::CaseRun> {
    let mut truth = GroundTruth::default();
    let run = cases::run_case_observed(config, transport, seed, &mut truth)?;
    let spec = cases::case1_spec(seed, config.perception.max_svs);
    let info = TrialInfo {
        label: "case1".into(),
        seed,
        lanes: spec.scenario.road.lanes,
        lane_width_m: spec.scenario.road.lane_width,
        speed_limit_mps: spec.scenario.road.speed_limit,
        ego_desired_speed_mps: spec.scenario.ego.desired_speed,
        low_level_step_s: spec.params.dt,
        max_svs: spec.max_svs,
        params: Some(spec.params),
    };
    let files = write_trial(path, &info, &truth.steps, &run.episode)?;
    for f in files {
        println!("  recorded {}", f.display());
    }
    Ok(run)
}
