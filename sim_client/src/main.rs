//! `sim_client`: runs the paper's experiments against the planner.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use decision::PlannerConfig;
use indicatif::{ProgressBar, ProgressStyle};
use sim_client::campaign::{self, CampaignSettings};
use sim_client::load::{self, LiveCounters, LoadReport, LoadSettings, ProcessMonitor};
use sim_client::{cases, report, Transport, ZenohTarget};

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
    /// Planner configuration (TOML); defaults when absent. With a remote transport it is
    /// used for the vehicle's own fallback, and passed to a planner started with
    /// `--spawn-planner`.
    #[arg(long, value_name = "FILE")]
    planner_config: Option<PathBuf>,
    /// How the planner is reached: `inproc` (same thread), `iceoryx2` (a `planner serve
    /// --iceoryx2` process on this machine) or `zenoh` (a `planner serve` process reached
    /// with `--zenoh-connect` or `--zenoh-config`).
    #[arg(long, default_value = "inproc", value_parser = parse_transport)]
    transport: Transport,
    /// Zenoh endpoint of the planner service, e.g. tcp/127.0.0.1:7447 (with `--transport zenoh`).
    #[arg(long, value_name = "ENDPOINT")]
    zenoh_connect: Option<String>,
    /// Zenoh configuration file (JSON5), e.g. deploy/zenoh/client.json5 (with `--transport zenoh`).
    #[arg(long, value_name = "FILE")]
    zenoh_config: Option<PathBuf>,
    /// iceoryx2 shared-memory prefix of the planner (with `--transport iceoryx2`).
    #[arg(long, value_name = "PREFIX")]
    iceoryx2_prefix: Option<String>,
    /// Start `planner serve` (found next to this executable) for the run and stop it at exit
    /// (with `--transport zenoh` on a free loopback port, or `--transport iceoryx2` under a
    /// prefix of its own).
    #[arg(long)]
    spawn_planner: bool,
}

/// A `planner serve` child process, stopped when dropped (also on error or panic).
struct PlannerChild(std::process::Child, Option<String>);

impl PlannerChild {
    /// Removes what iceoryx2 keeps under a prefix of our own after its last node is gone (a
    /// small management segment per prefix).
    fn remove_prefix_files(&self) {
        let Some(prefix) = &self.1 else { return };
        if let Ok(entries) = std::fs::read_dir("/dev/shm") {
            for entry in entries.flatten() {
                if entry.file_name().to_string_lossy().starts_with(prefix.as_str()) {
                    let _ = std::fs::remove_file(entry.path());
                }
            }
        }
    }
}

impl Drop for PlannerChild {
    fn drop(&mut self) {
        // SIGTERM first, so that it removes its shared memory; SIGKILL if it does not stop.
        #[cfg(unix)]
        if let Ok(pid) = i32::try_from(self.0.id()) {
            // SAFETY: signals our own child, which has not been reaped yet.
            unsafe { libc::kill(pid, libc::SIGTERM) };
            let until = Instant::now() + std::time::Duration::from_secs(5);
            while Instant::now() < until {
                if let Ok(Some(_)) = self.0.try_wait() {
                    self.remove_prefix_files();
                    return;
                }
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn spawn_planner_with(common: &Common, transport_args: &[String], workers: Option<usize>) -> Result<PlannerChild> {
    let exe = std::env::current_exe().context("locating sim_client's executable")?;
    let planner = exe.with_file_name(format!("planner{}", std::env::consts::EXE_SUFFIX));
    let mut cmd = std::process::Command::new(&planner);
    cmd.arg("serve").args(transport_args);
    if let Some(w) = workers {
        cmd.arg("--workers").arg(w.to_string());
    }
    if let Some(p) = &common.planner_config {
        cmd.arg("--config").arg(p);
    }
    // If this process dies without stopping it (a signal, SIGPIPE), the planner must not live
    // on: the kernel sends it SIGTERM when its parent goes.
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::process::CommandExt;
        // SAFETY: prctl is async-signal-safe; nothing else runs between fork and exec.
        unsafe {
            cmd.pre_exec(|| {
                libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
                Ok(())
            });
        }
    }
    let child = cmd
        .stdin(std::process::Stdio::null())
        .spawn()
        .with_context(|| format!("starting {}", planner.display()))?;
    Ok(PlannerChild(child, None))
}

/// Completes the transport from the command line, starting the planner if asked to.
fn prepare_transport(common: &mut Common) -> Result<Option<PlannerChild>> {
    prepare_transport_with(common, None)
}

/// [`prepare_transport`], giving a spawned planner `workers` worker threads.
fn prepare_transport_with(common: &mut Common, workers: Option<usize>) -> Result<Option<PlannerChild>> {
    let zenoh_flags = common.zenoh_connect.is_some() || common.zenoh_config.is_some();
    match common.transport.clone() {
        Transport::InProcess => {
            if zenoh_flags || common.iceoryx2_prefix.is_some() || common.spawn_planner {
                anyhow::bail!("--zenoh-*, --iceoryx2-prefix and --spawn-planner need --transport zenoh or iceoryx2");
            }
            Ok(None)
        }
        Transport::Zenoh(_) => {
            if common.iceoryx2_prefix.is_some() {
                anyhow::bail!("--iceoryx2-prefix needs --transport iceoryx2");
            }
            let mut target = ZenohTarget {
                endpoint: common.zenoh_connect.clone(),
                config_file: common.zenoh_config.clone(),
            };
            let child = match (zenoh_flags, common.spawn_planner) {
                (true, true) => anyhow::bail!("give either --zenoh-connect / --zenoh-config or --spawn-planner"),
                (false, false) => {
                    anyhow::bail!(
                        "--transport zenoh needs --zenoh-connect ENDPOINT, --zenoh-config FILE or --spawn-planner"
                    )
                }
                (true, false) => None,
                (false, true) => {
                    let port = std::net::TcpListener::bind("127.0.0.1:0")?.local_addr()?.port();
                    let endpoint = format!("tcp/127.0.0.1:{port}");
                    let child = spawn_planner_with(common, &["--zenoh-listen".into(), endpoint.clone()], workers)?;
                    target.endpoint = Some(endpoint);
                    Some(child)
                }
            };
            common.transport = Transport::Zenoh(target);
            Ok(child)
        }
        Transport::Iceoryx2 { .. } => {
            if zenoh_flags {
                anyhow::bail!("--zenoh-connect / --zenoh-config need --transport zenoh");
            }
            let mut prefix = common.iceoryx2_prefix.clone();
            let child = if common.spawn_planner {
                // A prefix of its own, so that it cannot meet another planner on this machine.
                let p = prefix.get_or_insert_with(|| format!("hmdp{}_", std::process::id()));
                let mut child = spawn_planner_with(
                    common,
                    &["--iceoryx2".into(), "--iceoryx2-prefix".into(), p.clone()],
                    workers,
                )?;
                // Only a prefix this run made up is ours to clean.
                if common.iceoryx2_prefix.is_none() {
                    child.1 = Some(p.clone());
                }
                Some(child)
            } else {
                None
            };
            common.transport = Transport::Iceoryx2 { prefix };
            Ok(child)
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
    /// Run length, e.g. `60s`, `10m`, `1h`.
    #[arg(long, value_parser = humantime::parse_duration)]
    duration: Option<std::time::Duration>,
    /// RSS growth is measured against the first sample after this (default: a quarter of the
    /// run, at most 10 s for `load`, 60 s for `soak`).
    #[arg(long, value_parser = humantime::parse_duration)]
    warmup: Option<std::time::Duration>,
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
    #[arg(long, value_parser = humantime::parse_duration, default_value = "10s")]
    report_every: std::time::Duration,
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
        #[arg(long, value_parser = humantime::parse_duration)]
        duration: std::time::Duration,
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
    fn config(&self) -> Result<PlannerConfig> {
        Ok(sim_client::presets::paper_literal(self.paper_config.as_deref())?)
    }
}

/// The command-line flags that reach `transport` (for `load --processes` children).
fn transport_flags(transport: &Transport) -> Vec<String> {
    let mut flags = vec!["--transport".to_string(), transport.to_string()];
    match transport {
        Transport::InProcess => {}
        Transport::Iceoryx2 { prefix } => {
            if let Some(p) = prefix {
                flags.extend(["--iceoryx2-prefix".into(), p.clone()]);
            }
        }
        Transport::Zenoh(target) => {
            if let Some(e) = &target.endpoint {
                flags.extend(["--zenoh-connect".into(), e.clone()]);
            }
            if let Some(f) = &target.config_file {
                flags.extend(["--zenoh-config".into(), f.display().to_string()]);
            }
        }
    }
    flags
}

/// Runs `load` / `soak`: the report, printed and written.
fn run_load_command(mut args: LoadArgs, default_duration: std::time::Duration, soak: bool) -> Result<LoadReport> {
    let planner = prepare_transport_with(&mut args.common, args.planner_workers)?;
    let config = planner_config(args.common.planner_config.as_deref())?;
    let duration = args.duration.unwrap_or(default_duration);
    let warmup_cap = std::time::Duration::from_secs(if soak { 60 } else { 10 });
    let mut settings = LoadSettings::new(args.common.transport.clone(), args.clients, args.rate, duration);
    settings.warmup = args.warmup.unwrap_or((duration / 4).min(warmup_cap));
    settings.deadline = std::time::Duration::from_millis(args.deadline_ms);
    settings.seed = args.seed;
    settings.planner = config;
    settings.planner_pid = args.planner_pid.or(planner.as_ref().map(|p| p.0.id()));
    let live = std::sync::Arc::new(LiveCounters::default());
    settings.live = Some(std::sync::Arc::clone(&live));
    let monitor = settings
        .planner_pid
        .map(|pid| ProcessMonitor::start(pid, settings.sample_period));
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let reporter = {
        let (done, live, every) = (
            std::sync::Arc::clone(&done),
            std::sync::Arc::clone(&live),
            args.report_every,
        );
        let started = Instant::now();
        std::thread::spawn(move || {
            let mut next = started + every;
            while !done.load(std::sync::atomic::Ordering::Relaxed) {
                std::thread::sleep(std::time::Duration::from_millis(100));
                if Instant::now() >= next {
                    next += every;
                    let [sent, in_time, late, lost, dup] = live.get();
                    eprintln!(
                        "[{:>7.1} s] sent {sent}, decided in time {in_time}, late {late}, lost {lost}, duplicated {dup}",
                        started.elapsed().as_secs_f64()
                    );
                }
            }
        })
    };
    let parts = if args.processes == 0 {
        vec![load::run_part(&settings, Instant::now())?]
    } else {
        run_worker_processes(&args, &settings)?
    };
    done.store(true, std::sync::atomic::Ordering::Relaxed);
    let _ = reporter.join();
    let report = LoadReport::merge(&settings, &parts, monitor.map(|m| m.finish(settings.warmup)));
    drop(planner);
    print_load_report(&report);
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

/// `load --processes N`: N `load-worker` children share the vehicles; their parts are merged.
fn run_worker_processes(args: &LoadArgs, settings: &LoadSettings) -> Result<Vec<load::LoadPart>> {
    let exe = std::env::current_exe().context("locating sim_client's executable")?;
    let dir = std::env::temp_dir().join(format!("hmdp-load-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let n = args.processes.min(args.clients).max(1);
    let mut children = Vec::new();
    let mut base = settings.vehicle_id_base;
    for i in 0..n {
        let clients = args.clients / n + usize::from(i < args.clients % n);
        let out = dir.join(format!("part-{i}.json"));
        let mut cmd = std::process::Command::new(&exe);
        cmd.arg("load-worker")
            .args(transport_flags(&settings.transport))
            .args([
                "--clients",
                &clients.to_string(),
                "--rate",
                &settings.rate_hz.to_string(),
            ])
            .args(["--duration", &format!("{}ms", settings.duration.as_millis())])
            .args(["--deadline-ms", &settings.deadline.as_millis().to_string()])
            .args([
                "--seed",
                &settings.seed.to_string(),
                "--vehicle-id-base",
                &base.to_string(),
            ])
            .arg("--part-out")
            .arg(&out);
        if let Some(p) = &args.common.planner_config {
            cmd.arg("--planner-config").arg(p);
        }
        children.push((cmd.spawn().context("starting a load worker")?, out));
        base += clients as u64;
    }
    let mut parts = Vec::new();
    for (mut child, out) in children {
        let status = child.wait()?;
        anyhow::ensure!(status.success(), "a load worker failed ({status})");
        let text = std::fs::read_to_string(&out).with_context(|| format!("reading {}", out.display()))?;
        parts.push(serde_json::from_str(&text)?);
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(parts)
}

fn print_load_report(r: &LoadReport) {
    let c = &r.counts;
    println!(
        "{}: {} vehicles x {} Hz for {:.1} s: sent {}, in time {}, late {}, lost {}, duplicated {}, mismatched {}; {:.1} decisions/s in time",
        r.transport, r.clients, r.rate_hz, r.duration_s, c.sent, c.in_time, c.late, c.lost, c.duplicated, c.mismatched, r.throughput_per_s
    );
    let l = &r.by_layer;
    println!(
        "  layers: nominal {}, global relaxation {}, fallback {}, watchdog fallback {}, rejected {}",
        l.nominal, l.global_relaxation, l.fallback, l.watchdog_fallback, l.rejected
    );
    println!(
        "  {:<18} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "us", "p50", "p90", "p99", "p99.9", "max"
    );
    for (name, p) in [
        ("round trip", &r.round_trip),
        ("queueing", &r.queue),
        ("solve", &r.solve),
        ("transport share", &r.transport_overhead),
    ] {
        println!(
            "  {:<18} {:>9} {:>9} {:>9} {:>9} {:>9}",
            name, p.p50_us, p.p90_us, p.p99_us, p.p999_us, p.max_us
        );
    }
    if let Some(p) = &r.planner {
        println!(
            "  planner pid {}: CPU mean {:.1} % of a core, RSS after warm-up {} KiB, max {} KiB (growth {:.2} %)",
            p.pid, p.cpu_mean_percent, p.rss_after_warmup_kib, p.rss_max_after_warmup_kib, p.rss_growth_percent
        );
    }
}

fn parse_transport(s: &str) -> Result<Transport, String> {
    // A Zenoh target comes from --zenoh-connect / --zenoh-config (see prepare_transport).
    s.parse::<Transport>().map_err(|e| e.to_string())
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
        // Colours only on a terminal: journald and log files get plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let cli = Cli::parse();
    let started = Instant::now();
    let mut exit_code = None;
    match cli.command {
        Command::Load(args) => {
            run_load_command(args, std::time::Duration::from_secs(30), false)?;
        }
        Command::Soak { load, max_rss_growth } => {
            let report = run_load_command(load, std::time::Duration::from_secs(3600), true)?;
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
            mut common,
            clients,
            rate,
            duration,
            deadline_ms,
            seed,
            vehicle_id_base,
            part_out,
        } => {
            let _none = prepare_transport(&mut common)?;
            let mut settings = LoadSettings::new(common.transport.clone(), clients, rate, duration);
            settings.deadline = std::time::Duration::from_millis(deadline_ms);
            settings.seed = seed;
            settings.vehicle_id_base = vehicle_id_base;
            settings.planner = planner_config(common.planner_config.as_deref())?;
            let part = load::run_part(&settings, Instant::now())?;
            std::fs::write(&part_out, serde_json::to_string(&part)?)
                .with_context(|| format!("writing {}", part_out.display()))?;
            return Ok(());
        }
        Command::Case1 {
            mut common,
            seed,
            paper,
        } => {
            let _planner = prepare_transport(&mut common)?;
            let config = planner_config(common.planner_config.as_deref())?;
            let case = cases::run_case1_compared(&config, Some(&paper.config()?), &common.transport, seed)?;
            let files = report::write_case1(&common.out, &case)?;
            println!("case1: {}", report::episode_summary_line(&case.planner.metrics));
            if let Some(p) = &case.paper_literal {
                println!("case1 paper_literal: {}", report::episode_summary_line(&p.metrics));
            }
            print_files(&files);
        }
        Command::Case2 {
            mut common,
            seed,
            paper,
        } => {
            if common.transport != Transport::InProcess {
                // A planner process has one configuration; the ablation needs two.
                anyhow::bail!("case2 runs the planner with and without hysteresis: use --transport inproc");
            }
            // Refuses the remote-transport flags, which mean nothing in process.
            let _none = prepare_transport(&mut common)?;
            let config = planner_config(common.planner_config.as_deref())?;
            let case = cases::run_case2(&config, Some(&paper.config()?), &common.transport, seed)?;
            let files = report::write_case2(&common.out, &case)?;
            let s = case.summary();
            for (name, a) in
                std::iter::once(("case2", &s.planner)).chain(s.paper_literal.iter().map(|a| ("case2 paper_literal", a)))
            {
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
        }
        Command::Campaign {
            mut common,
            trials_scale,
            config,
            seed,
            threads,
            baselines,
            paper,
        } => {
            if common.transport != Transport::InProcess && baselines {
                // A planner process has one configuration; the no-hysteresis baseline needs another.
                anyhow::bail!("with a remote transport, run the campaign with --baselines false");
            }
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
            settings.paper_literal = if baselines { Some(paper.config()?) } else { None };
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
        }
    }
    if let Some(code) = exit_code {
        println!("wall time {:.2} s", started.elapsed().as_secs_f64());
        std::process::exit(code);
    }
    println!("wall time {:.2} s", started.elapsed().as_secs_f64());
    Ok(())
}
