//! `planner`: the decision service's command-line entry point.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use decision::PlannerConfig;

#[derive(Parser)]
#[command(name = "planner", version, about = "HMDP-MPC decision planner")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Solve a seeded corpus per Table I traffic class with the MILP and the exact oracle;
    /// report decision-time percentiles and the agreement rate.
    Bench {
        /// Print the full report as JSON.
        #[arg(long)]
        json: bool,
        /// Situations per traffic class (18 classes).
        #[arg(long, default_value_t = 600)]
        per_class: usize,
        #[arg(long, default_value_t = 2024)]
        seed: u64,
        /// Planner configuration (TOML); defaults apply to missing fields.
        #[arg(long)]
        config: Option<PathBuf>,
    },
    /// Print the default planner configuration as TOML.
    DefaultConfig,
}

fn load_config(path: Option<&PathBuf>) -> Result<PlannerConfig> {
    match path {
        None => Ok(PlannerConfig::default()),
        Some(p) => {
            let text = std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            PlannerConfig::from_toml_str(&text).with_context(|| format!("parsing {}", p.display()))
        }
    }
}

fn main() -> Result<()> {
    // Die quietly on a closed stdout (`... | head`), as command-line tools do, instead of
    // panicking in `println!`. SAFETY: resets a disposition before any thread exists.
    #[cfg(unix)]
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL)
    };
    let cli = Cli::parse();
    match cli.command {
        Command::Bench {
            json,
            per_class,
            seed,
            config,
        } => {
            let config = load_config(config.as_ref())?;
            let report = planner::bench::run(&config, per_class, seed)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                println!(
                    "{} situations, agreement {:.4} ({} of {})",
                    report.situations, report.agreement.rate, report.agreement.agreed, report.agreement.checked
                );
                for (name, t) in [
                    ("milp", &report.backends.milp),
                    ("enumeration", &report.backends.enumeration),
                ] {
                    println!(
                        "{name:>12}: p50 {} us, p99 {} us, max {} us, mean {:.0} us",
                        t.p50_us, t.p99_us, t.max_us, t.mean_us
                    );
                }
                let t = &report.target_class.milp;
                println!(
                    "class 18 (4 lanes, 10 SVs, highway) milp: p50 {} us, p99 {} us, max {} us",
                    t.p50_us, t.p99_us, t.max_us
                );
            }
        }
        Command::DefaultConfig => print!("{}", PlannerConfig::default().to_toml_string()),
    }
    Ok(())
}
