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
    /// Serve decisions over Zenoh (queryable `hmdp/planner/plan`, statistics on
    /// `hmdp/planner/stats`) until SIGINT or SIGTERM. See docs/service.md.
    Serve(ServeArgs),
}

#[derive(clap::Args)]
struct ServeArgs {
    /// Planner configuration (TOML); built-in defaults when absent.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Zenoh endpoint to listen on, e.g. tcp/127.0.0.1:7447 (repeatable).
    #[arg(long = "zenoh-listen", value_name = "ENDPOINT")]
    zenoh_listen: Vec<String>,
    /// Zenoh endpoint to connect to, e.g. tcp/10.0.0.2:7447 (repeatable).
    #[arg(long = "zenoh-connect", value_name = "ENDPOINT")]
    zenoh_connect: Vec<String>,
    /// Worker threads, each with its own planner (default: available cores).
    #[arg(long)]
    workers: Option<usize>,
    /// Requests that may wait for a worker; beyond that the fallback answers at once
    /// (default: 4 per worker).
    #[arg(long)]
    queue_capacity: Option<usize>,
    /// TEST ONLY: sleep this long before every solve, to force the watchdog.
    #[arg(long, default_value_t = 0, hide_short_help = true)]
    inject_solve_delay_ms: u64,
}

fn serve(args: ServeArgs) -> Result<()> {
    use planner::service::{Service, ServiceConfig};
    use std::sync::Arc;
    use std::time::Duration;

    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,zenoh=warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    if args.zenoh_listen.is_empty() && args.zenoh_connect.is_empty() {
        anyhow::bail!("give at least one --zenoh-listen or --zenoh-connect endpoint");
    }
    let planner_config = load_config(args.config.as_ref())?;
    let mut config = ServiceConfig::default();
    if let Some(w) = args.workers {
        config.workers = w.max(1);
        config.queue_capacity = 4 * config.workers;
    }
    if let Some(q) = args.queue_capacity {
        config.queue_capacity = q.max(1);
    }
    config.inject_solve_delay = Duration::from_millis(args.inject_solve_delay_ms);
    if !config.inject_solve_delay.is_zero() {
        tracing::warn!(ms = args.inject_solve_delay_ms, "TEST ONLY: injected solve delay");
    }
    let zenoh_config = planner::zenoh_front::peer_config(&args.zenoh_listen, &args.zenoh_connect)?;
    let service = Arc::new(Service::start(planner_config, config.clone())?);
    tracing::info!(
        workers = config.workers,
        queue = config.queue_capacity,
        "service started"
    );
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("building the tokio runtime")?;
    runtime.block_on(async {
        let shutdown = async {
            let mut term = match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
                Ok(s) => s,
                Err(e) => {
                    tracing::warn!("cannot watch SIGTERM: {e}");
                    let _ = tokio::signal::ctrl_c().await;
                    return;
                }
            };
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {}
                _ = term.recv() => {}
            }
        };
        planner::zenoh_front::serve(Arc::clone(&service), zenoh_config, shutdown).await
    })?;
    drop(runtime);
    let snapshot = service.stats().snapshot();
    tracing::info!(stats = %serde_json::to_string(&snapshot).unwrap_or_default(), "final statistics");
    Ok(())
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
        Command::Serve(args) => serve(args)?,
    }
    Ok(())
}
