//! `sim_client`: runs the paper's experiments against the planner.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use sim_client::campaign::{self, CampaignSettings};
use sim_client::connect::BUSY_POLL_WINDOW;
use sim_client::load::{self, parse_run_length, LiveCounters, LoadReport, LoadSettings, ProcessMonitor, ProgressLines};
use sim_client::planner_process::{spawn_planner, Serve, SpawnOptions, SpawnedPlanner};
use sim_client::{cases, report, Transport, ZenohTarget};
use transport::iceoryx2::WaitMode;

mod replay_command;

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

/// The transport named on the command line (its target comes from the other flags).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum TransportKind {
    /// The planner in the same thread.
    Inproc,
    /// A `planner serve --iceoryx2` process on this machine.
    Iceoryx2,
    /// A `planner serve` process reached with `--zenoh-connect` or `--zenoh-config`.
    Zenoh,
}

#[derive(Args)]
struct Common {
    /// Output directory.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Planner configuration (TOML); defaults when absent. With a remote transport it is
    /// used for the vehicle's own fallback, and passed to a planner started with
    /// `--spawn-planner`.
    #[arg(long, value_name = "FILE")]
    planner_config: Option<PathBuf>,
    /// How the planner is reached.
    #[arg(long, value_enum, default_value = "inproc")]
    transport: TransportKind,
    /// Zenoh endpoint of the planner service, e.g. tcp/127.0.0.1:7447 (with `--transport zenoh`).
    #[arg(long, value_name = "ENDPOINT")]
    zenoh_connect: Option<String>,
    /// Zenoh configuration file (JSON5), e.g. deploy/zenoh/client.json5 (with `--transport zenoh`).
    #[arg(long, value_name = "FILE")]
    zenoh_config: Option<PathBuf>,
    /// iceoryx2 shared-memory prefix of the planner (with `--transport iceoryx2`).
    #[arg(long, value_name = "PREFIX")]
    iceoryx2_prefix: Option<String>,
    /// Latency mode (with `--transport iceoryx2`): the vehicles spin for their answers instead
    /// of sleeping on the response event; a planner started with `--spawn-planner` spins too.
    #[arg(long)]
    busy_poll: bool,
    /// Start `planner serve` (found next to this executable) for the run and stop it at exit
    /// (with `--transport zenoh` on a free loopback port, or `--transport iceoryx2` under a
    /// prefix of its own).
    #[arg(long)]
    spawn_planner: bool,
    /// Where a planner started with `--spawn-planner` writes its log (default: this stderr).
    #[arg(long, value_name = "FILE", requires = "spawn_planner")]
    planner_log: Option<PathBuf>,
}

impl Common {
    fn planner_config(&self) -> Result<decision::PlannerConfig> {
        Ok(supervise::planner_config(self.planner_config.as_deref())?)
    }

    /// Checks that the flags fit the transport, starts the planner if asked to, and builds the
    /// transport. `workers` goes to a started planner.
    fn open(&self, workers: Option<usize>) -> Result<(Transport, Option<SpawnedPlanner>)> {
        let zenoh_flags = self.zenoh_connect.is_some() || self.zenoh_config.is_some();
        let spawn = |serve: Serve| {
            let options = SpawnOptions {
                workers,
                config: self.planner_config.clone(),
                log: self.planner_log.clone(),
            };
            spawn_planner(&serve, &options)
        };
        match self.transport {
            TransportKind::Inproc => {
                if zenoh_flags || self.iceoryx2_prefix.is_some() || self.spawn_planner || self.busy_poll {
                    anyhow::bail!(
                        "--zenoh-*, --iceoryx2-prefix, --busy-poll and --spawn-planner need --transport zenoh or iceoryx2"
                    );
                }
                Ok((Transport::InProcess, None))
            }
            TransportKind::Zenoh => {
                if self.iceoryx2_prefix.is_some() || self.busy_poll {
                    anyhow::bail!("--iceoryx2-prefix and --busy-poll need --transport iceoryx2");
                }
                let mut target = ZenohTarget {
                    endpoint: self.zenoh_connect.clone(),
                    config_file: self.zenoh_config.clone(),
                };
                let planner = match (zenoh_flags, self.spawn_planner) {
                    (true, true) => anyhow::bail!("give either --zenoh-connect / --zenoh-config or --spawn-planner"),
                    (false, false) => anyhow::bail!(
                        "--transport zenoh needs --zenoh-connect ENDPOINT, --zenoh-config FILE or --spawn-planner"
                    ),
                    (true, false) => None,
                    (false, true) => {
                        let planner = spawn(Serve::Zenoh)?;
                        target.endpoint = planner.zenoh_endpoint.clone();
                        Some(planner)
                    }
                };
                Ok((Transport::Zenoh(target), planner))
            }
            TransportKind::Iceoryx2 => {
                if zenoh_flags {
                    anyhow::bail!("--zenoh-connect / --zenoh-config need --transport zenoh");
                }
                let mut prefix = self.iceoryx2_prefix.clone();
                let planner = if self.spawn_planner {
                    let planner = spawn(Serve::Iceoryx2 {
                        prefix: prefix.clone(),
                        busy_poll: self.busy_poll,
                    })?;
                    prefix = planner.iceoryx2_prefix.clone();
                    Some(planner)
                } else {
                    None
                };
                let wait = if self.busy_poll {
                    WaitMode::BusyPoll {
                        window: BUSY_POLL_WINDOW,
                    }
                } else {
                    WaitMode::Event
                };
                Ok((Transport::Iceoryx2 { prefix, wait }, planner))
            }
        }
    }
}

/// Settings shared by `load` and `soak`.
#[derive(Args)]
struct LoadArgs {
    #[command(flatten)]
    common: Common,
    /// Vehicle clients.
    #[arg(long, default_value_t = 8)]
    clients: usize,
    /// Requests per second per vehicle.
    #[arg(long, default_value_t = 2.5)]
    rate: f64,
    /// Run length, e.g. `60s`, `10m`, `1h`; a plain number is seconds.
    #[arg(long, value_parser = parse_run_length)]
    duration: Option<Duration>,
    /// RSS growth is measured against the first sample after this (default: a quarter of the
    /// run, at most 10 s for `load`, 60 s for `soak`).
    #[arg(long, value_parser = parse_run_length)]
    warmup: Option<Duration>,
    /// The vehicles' deadline, ms.
    #[arg(long, default_value_t = 400)]
    deadline_ms: u64,
    /// Run the vehicles in this many processes (each gets its share of `--clients`) instead
    /// of threads of this process.
    #[arg(long, default_value_t = 0)]
    processes: usize,
    /// The planner's pid, to sample its CPU and RSS (known by itself with `--spawn-planner`).
    #[arg(long)]
    planner_pid: Option<u32>,
    /// Worker threads of a planner started with `--spawn-planner`.
    #[arg(long)]
    planner_workers: Option<usize>,
    /// Seed of the scenarios.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Also write the report as JSON to this file.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// Draw the latency distribution and the time series into `--out`.
    #[arg(long)]
    plot: bool,
    /// Print a progress line this often.
    #[arg(long, value_parser = parse_run_length, default_value = "10s")]
    report_every: Duration,
}

#[derive(Subcommand)]
enum Command {
    /// Latency under load: vehicle clients at a fixed rate against a planner process, each
    /// driving its own simulation; HDR percentiles of round trip, queueing and solve time,
    /// answers by layer, deadline misses, lost and duplicated answers, planner CPU and RSS.
    Load(LoadArgs),
    /// `load` for a long time (default 1 h), failing (exit 1) unless every request got
    /// exactly one answer by its deadline and the planner's RSS stayed flat.
    Soak {
        #[command(flatten)]
        load: LoadArgs,
        /// Largest allowed planner RSS growth after the warm-up, %.
        #[arg(long, default_value_t = 5.0)]
        max_rss_growth: f64,
    },
    /// One process's share of `load --processes` (writes its measurements as JSON).
    #[command(hide = true)]
    LoadWorker {
        #[command(flatten)]
        common: Common,
        #[arg(long)]
        clients: usize,
        #[arg(long)]
        rate: f64,
        #[arg(long, value_parser = parse_run_length)]
        duration: Duration,
        #[arg(long)]
        deadline_ms: u64,
        #[arg(long)]
        seed: u64,
        #[arg(long)]
        vehicle_id_base: u64,
        #[arg(long)]
        part_out: PathBuf,
    },
    /// Case 1: the Table II scene for 40 s with the planner, and with the paper-literal
    /// preset (in process) beside it.
    Case1 {
        #[command(flatten)]
        common: Common,
        /// Seed of the simulator's random stream.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[command(flatten)]
        paper: PaperArgs,
        /// Record the planner's trial (ground truth, decisions, a Foxglove scene) to this
        /// MCAP file (docs/recording.md).
        #[arg(long, value_name = "FILE.mcap")]
        record: Option<PathBuf>,
    },
    /// Log replay: the SVs of a recording follow their recorded trajectories, the ego is
    /// re-planned from its recorded start; scored like a campaign trial.
    Replay {
        #[command(flatten)]
        common: Common,
        #[command(flatten)]
        replay: replay_command::ReplayArgs,
    },
    /// Case 2: Case 1 with hysteresis on and off, for the planner and the paper-literal preset.
    Case2 {
        #[command(flatten)]
        common: Common,
        /// Seed of the simulator's random stream.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[command(flatten)]
        paper: PaperArgs,
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
        /// Also run the paper-literal preset, the planner without hysteresis and the IDM +
        /// MOBIL ego.
        #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
        baselines: bool,
        #[command(flatten)]
        paper: PaperArgs,
    },
}

/// The paper-literal preset of the case and campaign commands.
#[derive(Args)]
struct PaperArgs {
    /// Planner TOML of the paper-literal preset (default: the embedded deploy/paper.toml).
    #[arg(long, value_name = "FILE")]
    paper_config: Option<PathBuf>,
}

impl PaperArgs {
    fn config(&self) -> Result<decision::PlannerConfig> {
        Ok(sim_client::presets::paper_literal(self.paper_config.as_deref())?)
    }
}

/// Runs `load` / `soak`: the report, printed and written.
fn run_load_command(args: LoadArgs, default_duration: Duration, soak: bool) -> Result<LoadReport> {
    let (transport, planner) = args.common.open(args.planner_workers)?;
    let duration = args.duration.unwrap_or(default_duration);
    let warmup_cap = Duration::from_secs(if soak { 60 } else { 10 });
    let mut settings = LoadSettings::new(transport, args.clients, args.rate, duration);
    settings.warmup = args.warmup.unwrap_or((duration / 4).min(warmup_cap));
    settings.deadline = Duration::from_millis(args.deadline_ms);
    settings.seed = args.seed;
    settings.planner = args.common.planner_config()?;
    settings.planner_pid = args.planner_pid.or(planner.as_ref().map(|p| p.process.id()));
    let live = std::sync::Arc::new(LiveCounters::default());
    settings.live = Some(std::sync::Arc::clone(&live));
    let monitor = settings
        .planner_pid
        .map(|pid| ProcessMonitor::start(pid, settings.sample_period));
    let progress = ProgressLines::start(live, args.report_every);
    let parts = if args.processes == 0 {
        vec![load::run_part(&settings, Instant::now())?]
    } else {
        load::run_worker_processes(&settings, args.processes, args.common.planner_config.as_deref())?
    };
    drop(progress);
    let report = LoadReport::merge(&settings, &parts, monitor.map(|m| m.finish(settings.warmup)));
    drop(planner);
    print!("{}", report.summary());
    if let Some(path) = &args.json {
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).with_context(|| format!("creating {}", parent.display()))?;
        }
        std::fs::write(path, serde_json::to_string_pretty(&report)?)
            .with_context(|| format!("writing {}", path.display()))?;
        println!("  wrote {}", path.display());
    }
    if args.plot {
        let dir = args.common.out.join(if soak { "soak" } else { "load" });
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        let files = [dir.join("latency.svg"), dir.join("timeline.svg")];
        sim_client::plot::latency_plot(&files[0], &report)?;
        sim_client::plot::load_timeline_plot(&files[1], &report)?;
        print_files(&files);
    }
    Ok(report)
}

fn run_campaign(
    common: &Common,
    scale: f64,
    config: Option<PathBuf>,
    seed: u64,
    threads: Option<usize>,
    baselines: bool,
    paper: &PaperArgs,
) -> Result<()> {
    if common.transport != TransportKind::Inproc && baselines {
        // A planner process has one configuration; the no-hysteresis baseline needs another.
        anyhow::bail!("with a remote transport, run the campaign with --baselines false");
    }
    let (transport, _planner) = common.open(None)?;
    let entries = match &config {
        Some(p) => campaign::load_entries(p)?,
        None => campaign::paper_entries(),
    };
    let entries = campaign::scale_trials(&entries, scale)?;
    let threads = threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .max(1);
    let mut settings = CampaignSettings::new(entries, seed, threads);
    settings.baselines = baselines;
    settings.planner = common.planner_config()?;
    settings.paper_literal = if baselines { Some(paper.config()?) } else { None };
    settings.transport = transport;
    let bar = if std::io::stderr().is_terminal() {
        ProgressBar::new(settings.episode_count() as u64)
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
        let share = |v: Option<f64>| v.map_or("-".into(), |v| format!("{:.2}%", 100.0 * v));
        println!(
            "{:<22} trials {:>5}  decisions {:>7}  collision rate {:.2}%  NOR {}  GSRR {}  FBR {}  solve mean {:.3} ms p99 {:.3} ms max {:.3} ms",
            g.driver.name(),
            g.trials,
            g.decisions,
            100.0 * g.collision_rate,
            share(g.nor),
            share(g.gsrr),
            share(g.fbr),
            g.solve_time.mean_ms,
            g.solve_time.p99_ms,
            g.solve_time.max_ms,
        );
        let s = &g.safety;
        println!(
            "{:<22} collisions at fault {} / hit in lane {} / SV-SV {}  hard brakes {:.1}/h  min TTC p5 {} p50 {} s  TTC<3s {:.2}%  headway<1s {:.2}%  max DRAC {:.2} m/s^2",
            "",
            g.collision_split.ego_at_fault,
            g.collision_split.ego_hit_in_lane,
            g.collision_split.sv_sv,
            s.hard_braking_per_hour,
            s.min_ttc_p5_s.map_or("inf".into(), |v| format!("{v:.2}")),
            s.min_ttc_p50_s.map_or("inf".into(), |v| format!("{v:.2}")),
            100.0 * s.ttc_below_3s_share,
            100.0 * s.headway_below_1s_share,
            s.max_drac_mps2,
        );
    }
    println!(
        "campaign wall time {:.1} s on {} thread(s)",
        results.wall_time_s, results.threads
    );
    print_files(&files);
    Ok(())
}

fn run_case1(common: &Common, seed: u64, paper: &PaperArgs, record: Option<&std::path::Path>) -> Result<()> {
    let (transport, _planner) = common.open(None)?;
    let config = common.planner_config()?;
    let case = match record {
        Some(path) => cases::Case1 {
            planner: replay_command::record_case1(&config, &transport, seed, path)?,
            paper_literal: Some(cases::run_case(&paper.config()?, &Transport::InProcess, seed)?),
        },
        None => cases::run_case1_compared(&config, Some(&paper.config()?), &transport, seed)?,
    };
    let files = report::write_case1(&common.out, &case)?;
    println!("case1: {}", report::episode_summary_line(&case.planner.metrics));
    if let Some(p) = &case.paper_literal {
        println!("case1 paper_literal: {}", report::episode_summary_line(&p.metrics));
    }
    print_files(&files);
    Ok(())
}

fn run_case2(common: &Common, seed: u64, paper: &PaperArgs) -> Result<()> {
    if common.transport != TransportKind::Inproc {
        // A planner process has one configuration; the ablation needs two.
        anyhow::bail!("case2 runs the planner with and without hysteresis: use --transport inproc");
    }
    // Refuses the remote-transport flags, which mean nothing in process.
    let (transport, _none) = common.open(None)?;
    let case = cases::run_case2(&common.planner_config()?, Some(&paper.config()?), &transport, seed)?;
    let files = report::write_case2(&common.out, &case)?;
    let s = case.summary();
    let runs = std::iter::once(("case2", &s.planner)).chain(s.paper_literal.iter().map(|a| ("case2 paper_literal", a)));
    for (name, a) in runs {
        println!(
            "{name}: beta switches with hysteresis {}, without {} (paper: 1 vs 33); collisions {} / {}",
            a.beta_switches_with,
            a.beta_switches_without,
            a.with_hysteresis.collisions,
            a.without_hysteresis.collisions
        );
        println!(
            "  with hysteresis: {}",
            report::episode_summary_line(&a.with_hysteresis)
        );
        println!(
            "  without hysteresis: {}",
            report::episode_summary_line(&a.without_hysteresis)
        );
    }
    print_files(&files);
    Ok(())
}

fn print_files(files: &[PathBuf]) {
    for f in files {
        println!("  wrote {}", f.display());
    }
}

fn main() -> Result<()> {
    supervise::init_process("warn");
    let cli = Cli::parse();
    let started = Instant::now();
    let mut exit_code = None;
    match cli.command {
        Command::Load(args) => {
            run_load_command(args, Duration::from_secs(30), false)?;
        }
        Command::Soak { load, max_rss_growth } => {
            let report = run_load_command(load, Duration::from_secs(3600), true)?;
            let violations = report.soak_violations(max_rss_growth);
            if violations.is_empty() {
                println!("soak: PASS (every request answered exactly once by its deadline; planner RSS flat)");
            } else {
                for v in &violations {
                    println!("soak: FAIL: {v}");
                }
                exit_code = Some(1);
            }
        }
        Command::LoadWorker {
            common,
            clients,
            rate,
            duration,
            deadline_ms,
            seed,
            vehicle_id_base,
            part_out,
        } => {
            let (transport, _none) = common.open(None)?;
            let mut settings = LoadSettings::new(transport, clients, rate, duration);
            settings.deadline = Duration::from_millis(deadline_ms);
            settings.seed = seed;
            settings.vehicle_id_base = vehicle_id_base;
            settings.planner = common.planner_config()?;
            let part = load::run_part(&settings, Instant::now())?;
            std::fs::write(&part_out, serde_json::to_string(&part)?)
                .with_context(|| format!("writing {}", part_out.display()))?;
            return Ok(());
        }
        Command::Case1 {
            common,
            seed,
            paper,
            record,
        } => run_case1(&common, seed, &paper, record.as_deref())?,
        Command::Replay { common, replay } => {
            let (transport, _planner) = common.open(None)?;
            replay_command::run_replay(&replay, &transport, &common.planner_config()?)?;
        }
        Command::Case2 { common, seed, paper } => run_case2(&common, seed, &paper)?,
        Command::Campaign {
            common,
            trials_scale,
            config,
            seed,
            threads,
            baselines,
            paper,
        } => run_campaign(&common, trials_scale, config, seed, threads, baselines, &paper)?,
    }
    println!("wall time {:.2} s", started.elapsed().as_secs_f64());
    if let Some(code) = exit_code {
        std::process::exit(code);
    }
    Ok(())
}
