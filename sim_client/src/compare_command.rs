//! `sim_client compare`: two campaign runs of the same seed, paired trial by trial.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use sim_client::campaign::DriverKind;
use sim_client::campaign_compare::{compare, comparison_table, read_trials};

/// A driver of a campaign run, as `compare` names it.
#[derive(Clone, Copy, ValueEnum)]
pub enum CompareDriver {
    Planner,
    PlannerNoHysteresis,
    PaperLiteral,
    IdmMobil,
}

impl From<CompareDriver> for DriverKind {
    fn from(d: CompareDriver) -> Self {
        match d {
            CompareDriver::Planner => DriverKind::Planner,
            CompareDriver::PlannerNoHysteresis => DriverKind::PlannerNoHysteresis,
            CompareDriver::PaperLiteral => DriverKind::PaperLiteral,
            CompareDriver::IdmMobil => DriverKind::IdmMobil,
        }
    }
}

/// `sim_client compare`.
#[derive(Args)]
pub struct CompareArgs {
    /// The baseline run: its output directory (`--out` of `campaign`) or its trials.jsonl.
    baseline: PathBuf,
    /// The candidate run, likewise; it must have run the same configurations and seed.
    candidate: PathBuf,
    /// The driver compared.
    #[arg(long, value_enum, default_value = "planner")]
    driver: CompareDriver,
    /// The candidate run's driver, if another than the baseline's (e.g. the planner against
    /// `idm-mobil` of the same run).
    #[arg(long, value_enum)]
    candidate_driver: Option<CompareDriver>,
    /// Bootstrap resamples.
    #[arg(long, default_value_t = 2000)]
    resamples: usize,
    /// Confidence of the intervals.
    #[arg(long, default_value_t = 0.95)]
    confidence: f64,
    /// Seed of the resampling.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Also list this many trials with the candidate's shortest least TTC, with the
    /// baseline's in the same trial (to look at with `diagnose`).
    #[arg(long, default_value_t = 0, value_name = "N")]
    lowest_ttc: usize,
    /// Also write the comparison as JSON to this file.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
}

pub fn run_compare(args: &CompareArgs) -> Result<()> {
    let driver = DriverKind::from(args.driver);
    let candidate_driver = args.candidate_driver.map_or(driver, DriverKind::from);
    let baseline = read_trials(&args.baseline)?;
    let candidate = read_trials(&args.candidate)?;
    let c = compare(
        &baseline,
        &candidate,
        (driver, candidate_driver),
        args.resamples,
        args.confidence,
        args.seed,
    )?;
    print!("{}", comparison_table(&c));
    if args.lowest_ttc > 0 {
        println!("lowest least TTC of the candidate (configuration, trial, seed: candidate / baseline s):");
        let cell = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
        for t in c.lowest_candidate_ttc(args.lowest_ttc) {
            println!(
                "  {:>3} {:>4} {:>20}: {} / {}",
                t.config_id,
                t.trial,
                t.seed,
                cell(t.candidate_min_ttc_s),
                cell(t.baseline_min_ttc_s)
            );
        }
    }
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_vec_pretty(&c)?).with_context(|| format!("writing {}", path.display()))?;
        println!("  wrote {}", path.display());
    }
    Ok(())
}
