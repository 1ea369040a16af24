//! `sim_client`: runs the paper's experiments against the planner.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use decision::PlannerConfig;
use indicatif::{ProgressBar, ProgressStyle};
use sim_client::campaign::{self, CampaignSettings};
use sim_client::{cases, report, Transport};

#[derive(Parser)]
#[command(
    name = "sim_client",
    version,
    about = "Closed-loop experiments of the HMDP-MPC planner (paper section IV)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Args)]
struct Common {
    /// Output directory.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Planner configuration (TOML); defaults when absent.
    #[arg(long, value_name = "FILE")]
    planner_config: Option<PathBuf>,
    /// How the planner is reached: `inproc` (same thread) or `zenoh` (a `planner serve`
    /// process; give `--zenoh-connect` or `--spawn-planner`).
    #[arg(long, default_value = "inproc", value_parser = parse_transport)]
    transport: Transport,
    /// Zenoh endpoint of the planner service, e.g. tcp/127.0.0.1:7447 (with `--transport zenoh`).
    #[arg(long, value_name = "ENDPOINT")]
    zenoh_connect: Option<String>,
    /// Start `planner serve` (found next to this executable) on a free loopback port for the
    /// run, and stop it at exit (with `--transport zenoh`).
    #[arg(long)]
    spawn_planner: bool,
}

/// A `planner serve` child process, killed when dropped (also on error or panic).
struct PlannerChild(std::process::Child);

impl Drop for PlannerChild {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Resolves `--transport zenoh` into an endpoint, starting the planner if asked to.
fn prepare_transport(common: &mut Common) -> Result<Option<PlannerChild>> {
    if !matches!(common.transport, Transport::Zenoh { .. }) {
        if common.zenoh_connect.is_some() || common.spawn_planner {
            anyhow::bail!("--zenoh-connect and --spawn-planner need --transport zenoh");
        }
        return Ok(None);
    }
    let (endpoint, child) = match (&common.zenoh_connect, common.spawn_planner) {
        (Some(_), true) => anyhow::bail!("give either --zenoh-connect or --spawn-planner, not both"),
        (None, false) => anyhow::bail!("--transport zenoh needs --zenoh-connect ENDPOINT or --spawn-planner"),
        (Some(e), false) => (e.clone(), None),
        (None, true) => {
            let port = std::net::TcpListener::bind("127.0.0.1:0")?.local_addr()?.port();
            let endpoint = format!("tcp/127.0.0.1:{port}");
            let exe = std::env::current_exe().context("locating sim_client's executable")?;
            let planner = exe.with_file_name(format!("planner{}", std::env::consts::EXE_SUFFIX));
            let mut cmd = std::process::Command::new(&planner);
            cmd.args(["serve", "--zenoh-listen", &endpoint]);
            if let Some(p) = &common.planner_config {
                cmd.arg("--config").arg(p);
            }
            let child = cmd
                .stdin(std::process::Stdio::null())
                .spawn()
                .with_context(|| format!("starting {}", planner.display()))?;
            (endpoint, Some(PlannerChild(child)))
        }
    };
    // The endpoint lives for the whole run; leaking it keeps `Transport` `Copy`.
    common.transport = Transport::Zenoh {
        connect: Box::leak(endpoint.into_boxed_str()),
    };
    Ok(child)
}

#[derive(Subcommand)]
enum Command {
    /// Case 1: the Table II scene for 40 s with the planner.
    Case1 {
        #[command(flatten)]
        common: Common,
        /// Seed of the simulator's random stream.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Case 2: Case 1 with hysteresis on and off.
    Case2 {
        #[command(flatten)]
        common: Common,
        /// Seed of the simulator's random stream.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Case 3: the randomized campaign of Table I.
    Campaign {
        #[command(flatten)]
        common: Common,
        /// Multiply every trial count by this (at least 1 trial per configuration).
        #[arg(long, default_value_t = 1.0)]
        trials_scale: f64,
        /// Custom configurations (TOML `[[config]]` tables or a JSON list) instead of Table I.
        #[arg(long, value_name = "FILE")]
        config: Option<PathBuf>,
        /// Base seed.
        #[arg(long, default_value_t = 2026)]
        seed: u64,
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Also run the planner without hysteresis and the IDM + MOBIL ego.
        #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
        baselines: bool,
    },
}

fn parse_transport(s: &str) -> Result<Transport, String> {
    match s {
        // The endpoint comes from --zenoh-connect / --spawn-planner (see prepare_transport).
        "zenoh" => Ok(Transport::Zenoh { connect: "" }),
        _ => s.parse::<Transport>().map_err(|e| e.to_string()),
    }
}

fn planner_config(path: Option<&Path>) -> Result<PlannerConfig> {
    match path {
        None => Ok(PlannerConfig::default()),
        Some(p) => {
            let text = std::fs::read_to_string(p).with_context(|| format!("reading planner config {}", p.display()))?;
            PlannerConfig::from_toml_str(&text).with_context(|| format!("planner config {}", p.display()))
        }
    }
}

fn print_files(files: &[PathBuf]) {
    for f in files {
        println!("  wrote {}", f.display());
    }
}

fn main() -> Result<()> {
    // Die quietly on a closed stdout (`... | head`), as command-line tools do, instead of
    // panicking in `println!`. SAFETY: resets a disposition before any thread exists.
    #[cfg(unix)]
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL)
    };
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let started = Instant::now();
    match cli.command {
        Command::Case1 { mut common, seed } => {
            let _planner = prepare_transport(&mut common)?;
            let config = planner_config(common.planner_config.as_deref())?;
            let run = cases::run_case1(&config, common.transport, seed)?;
            let files = report::write_case1(&common.out, &run)?;
            let m = &run.metrics;
            println!(
                "case1: {} decisions (nominal {}, relaxation {}, fallback {}), collisions {}, lane changes {}, beta switches {}, corrective {:.1} s, mean speed {:.2} m/s",
                m.decisions,
                m.decisions_by_layer.nominal,
                m.decisions_by_layer.global_relaxation,
                m.decisions_by_layer.fallback,
                m.collisions,
                m.lane_changes,
                m.beta_switches,
                m.corrective_time_s,
                m.mean_speed_mps
            );
            print_files(&files);
        }
        Command::Case2 { mut common, seed } => {
            let _planner = prepare_transport(&mut common)?;
            let config = planner_config(common.planner_config.as_deref())?;
            let case = cases::run_case2(&config, common.transport, seed)?;
            let files = report::write_case2(&common.out, &case)?;
            let s = case.summary();
            println!(
                "case2: beta switches with hysteresis {}, without {} (paper: 1 vs 33); collisions {} / {}",
                s.beta_switches_with,
                s.beta_switches_without,
                s.with_hysteresis.collisions,
                s.without_hysteresis.collisions
            );
            print_files(&files);
        }
        Command::Campaign {
            mut common,
            trials_scale,
            config,
            seed,
            threads,
            baselines,
        } => {
            let _planner = prepare_transport(&mut common)?;
            let planner = planner_config(common.planner_config.as_deref())?;
            let entries = match &config {
                Some(p) => campaign::load_entries(p)?,
                None => campaign::paper_entries(),
            };
            let entries = campaign::scale_trials(&entries, trials_scale)?;
            let threads = threads
                .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
                .max(1);
            let mut settings = CampaignSettings::new(entries, seed, threads);
            settings.baselines = baselines;
            settings.planner = planner;
            settings.transport = common.transport;
            let total = settings.episode_count() as u64;
            let bar = if std::io::stderr().is_terminal() {
                ProgressBar::new(total)
            } else {
                ProgressBar::hidden()
            };
            bar.set_style(
                ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} episodes, eta {eta}")
                    .expect("valid template"),
            );
            let results = campaign::run_campaign(&settings, &|| bar.inc(1))?;
            bar.finish_and_clear();
            let files = report::write_campaign(&common.out, &results)?;
            for g in &results.overall {
                println!(
                    "{:<22} trials {:>5}  decisions {:>7}  collision rate {:.2}%  NOR {}  GSRR {}  FBR {}  solve mean {:.3} ms p99 {:.3} ms max {:.3} ms",
                    g.driver.name(),
                    g.trials,
                    g.decisions,
                    100.0 * g.collision_rate,
                    g.nor.map_or("-".into(), |v| format!("{:.2}%", 100.0 * v)),
                    g.gsrr.map_or("-".into(), |v| format!("{:.2}%", 100.0 * v)),
                    g.fbr.map_or("-".into(), |v| format!("{:.2}%", 100.0 * v)),
                    g.solve_time.mean_ms,
                    g.solve_time.p99_ms,
                    g.solve_time.max_ms,
                );
            }
            print_files(&files);
        }
    }
    println!("wall time {:.2} s", started.elapsed().as_secs_f64());
    Ok(())
}
