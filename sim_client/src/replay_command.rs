//! `sim_client replay`: the command-line side of log replay.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use sim_client::log_replay::{read_traffic_log, replay_log, Perturbation};
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
