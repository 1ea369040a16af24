//! `planner`: the decision service's command-line entry point.

mod bench;
mod keygen;
mod replay;
mod scaling;
mod serve;

use std::path::PathBuf;

use anyhow::Result;
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
        /// Sweep horizon x action set x SV count on the 4-lane highway class instead
        /// (`--per-class` situations per cell).
        #[arg(long)]
        scaling: bool,
        /// Horizons of the sweep.
        #[arg(long, value_delimiter = ',', default_value = "3,4,5,6")]
        horizons: Vec<usize>,
        /// Action sets of the sweep.
        #[arg(long, value_delimiter = ',', default_value = "single,combined")]
        actions: Vec<ActionSet>,
        /// SV counts of the sweep.
        #[arg(long, value_delimiter = ',', default_value = "10")]
        svs: Vec<usize>,
        /// The sweep skips enumeration where there are more action sequences than this.
        #[arg(long, default_value_t = 20_000)]
        max_sequences: usize,
    },
    /// Print the default planner configuration as TOML.
    DefaultConfig,
    /// Serve decisions over iceoryx2 (shared memory, this machine) and/or Zenoh (queryable
    /// `hmdp/planner/plan`, statistics on `hmdp/planner/stats`) until SIGINT or SIGTERM.
    /// See docs/service.md.
    Serve(Box<serve::ServeArgs>),
    /// Make an Ed25519 key pair for signed answers: OUT (the secret seed, mode 0600, for
    /// `serve --signing-key` or `[service] signing_key`) and OUT.pub (the public key, for the
    /// vehicles). Refuses to overwrite. See docs/deploy.md.
    Keygen {
        /// The secret key file to write, e.g. /etc/hmdp/planner.key.
        out: PathBuf,
    },
    /// Re-decide every request of a recording (`serve --record`) and compare with the recorded
    /// answers; exit code 1 on any difference. See docs/recording.md.
    Replay {
        /// The recording; the files of a rotated recording in order.
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// Planner configuration (TOML) to decide with; built-in defaults when absent.
        #[arg(long)]
        config: Option<PathBuf>,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
}

/// Which ego action set a benchmark sweeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum ActionSet {
    /// A lateral or a longitudinal action per step.
    Single,
    /// Both at once (9 per step).
    Combined,
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    supervise::init_process(&match cli.command {
        Command::Serve(_) => format!("info,zenoh=warn,{}", hmdp_ros2::QUIET_LOG_DIRECTIVES),
        _ => "warn".to_owned(),
    });
    if matches!(cli.command, Command::Serve(_)) {
        // A vehicle that hangs up mid-answer must not kill the service.
        supervise::ignore_sigpipe();
    }
    match cli.command {
        Command::Bench {
            json,
            per_class,
            seed,
            config,
            scaling: true,
            horizons,
            actions,
            svs,
            max_sequences,
        } => {
            let config = planner_service::config_file::planner_config(config.as_deref())?;
            let spec = scaling::ScalingSpec {
                horizons,
                combined: actions.iter().map(|a| *a == ActionSet::Combined).collect(),
                svs,
                per_cell: per_class,
                seed,
                max_sequences,
            };
            let report = scaling::run(&config, &spec)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                print!("{}", scaling::render(&report));
            }
        }
        Command::Bench {
            json,
            per_class,
            seed,
            config,
            ..
        } => {
            let config = planner_service::config_file::planner_config(config.as_deref())?;
            let report = bench::run(&config, per_class, seed)?;
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
        Command::Keygen { out } => keygen::run(&out)?,
        Command::Serve(args) => serve::run(*args)?,
        Command::Replay { files, config, json } => {
            let code = replay::run(&files, config.as_deref(), json)?;
            if code != 0 {
                std::process::exit(code);
            }
        }
    }
    Ok(())
}
