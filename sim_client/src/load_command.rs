//! `sim_client load`, `soak` and `load-worker`: the command-line side of [`sim_client::load`].

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::Args;
use recording::{PlanRecorder, RecorderOptions, RecordingSummary};
use sim_client::load::{
    self, parse_run_length, FloodSettings, LiveCounters, LoadReport, LoadSettings, ProcessMonitor, ProgressLines,
};

use super::Common;

/// Settings shared by `load` and `soak`.
#[derive(Args)]
pub struct LoadArgs {
    #[command(flatten)]
    pub common: Common,
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
    /// Beside the vehicles, flood the planner as one vehicle (`--flood-vehicle-id`) from this
    /// many Zenoh sessions, each sending `--flood-rate` requests a second of a fixed scene
    /// without waiting for the answers (`--transport zenoh` only). The flood's own answers
    /// are reported apart.
    #[arg(long, default_value_t = 0)]
    flood_sessions: usize,
    /// Requests per second per flood session.
    #[arg(long, default_value_t = 500.0)]
    flood_rate: f64,
    /// The flooding vehicle's id.
    #[arg(long, default_value_t = 666)]
    flood_vehicle_id: u64,
    /// Record every request the vehicles send and the answer each got (the vehicles' side,
    /// late answers included) to this MCAP file, as `planner serve --record` does; with
    /// `--processes N` each process writes `FILE.worker<i>.mcap`. docs/recording.md.
    #[arg(long, value_name = "FILE.mcap")]
    record: Option<PathBuf>,
}

/// `load-worker`: one process's share of `load --processes`.
#[derive(Args)]
pub struct LoadWorkerArgs {
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
    #[arg(long)]
    record: Option<PathBuf>,
}

/// Runs `load` / `soak`: the report, printed and written.
pub fn run_load_command(args: LoadArgs, default_duration: Duration, soak: bool) -> Result<LoadReport> {
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
    // In processes mode the children record, each its own vehicles.
    let recorder = match &args.record {
        Some(path) if args.processes == 0 => Some(start_recorder(path)?),
        _ => None,
    };
    settings.recorder = recorder.clone();
    let flood = match (&settings.transport, args.flood_sessions) {
        (_, 0) => None,
        (sim_client::link::Transport::Zenoh(target), sessions) => Some((
            target.clone(),
            FloodSettings {
                sessions,
                rate_hz: args.flood_rate,
                vehicle_id: args.flood_vehicle_id,
                deadline: settings.deadline - settings.transport_margin,
            },
        )),
        _ => anyhow::bail!("--flood-sessions needs --transport zenoh"),
    };
    let progress = ProgressLines::start(live, args.report_every);
    let started = Instant::now();
    let (parts, flood) = std::thread::scope(|scope| -> Result<_> {
        let flood = flood.map(|(target, f)| {
            let end = started + settings.duration;
            scope.spawn(move || load::run_flood(&target, f, end))
        });
        let parts = if args.processes == 0 {
            vec![load::run_part(&settings, started)?]
        } else {
            load::run_worker_processes(
                &settings,
                args.processes,
                args.common.planner_config.as_deref(),
                args.record.as_deref(),
            )?
        };
        let flood = match flood {
            Some(f) => Some(f.join().map_err(|_| anyhow::anyhow!("the flood thread panicked"))??),
            None => None,
        };
        Ok((parts, flood))
    })?;
    drop(progress);
    let mut report = LoadReport::merge(&settings, &parts, monitor.map(|m| m.finish(settings.warmup)));
    report.flood = flood;
    drop(planner);
    print!("{}", report.summary());
    if let Some(recorder) = recorder {
        print_recording(&recorder.finish()?);
    } else if let Some(base) = &args.record {
        for i in 0..load::worker_count(args.clients, args.processes) {
            println!("  recorded {}", load::worker_record_path(base, i).display());
        }
    }
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
        super::print_files(&files);
    }
    Ok(report)
}

fn start_recorder(path: &Path) -> Result<PlanRecorder> {
    PlanRecorder::start(&RecorderOptions::new(path)).with_context(|| format!("recording to {}", path.display()))
}

fn print_recording(summary: &RecordingSummary) {
    for f in &summary.files {
        println!(
            "  recorded {} ({} messages, {} dropped)",
            f.display(),
            summary.messages,
            summary.dropped
        );
    }
}

/// Runs one `load-worker` process and writes its part.
pub fn run_load_worker(args: LoadWorkerArgs) -> Result<()> {
    let (transport, _none) = args.common.open(None)?;
    let mut settings = LoadSettings::new(transport, args.clients, args.rate, args.duration);
    settings.deadline = Duration::from_millis(args.deadline_ms);
    settings.seed = args.seed;
    settings.vehicle_id_base = args.vehicle_id_base;
    settings.planner = args.common.planner_config()?;
    settings.recorder = args.record.as_deref().map(start_recorder).transpose()?;
    let part = load::run_part(&settings, Instant::now())?;
    if let Some(recorder) = &settings.recorder {
        let summary = recorder.finish()?;
        if summary.dropped > 0 {
            eprintln!("load worker: {} records dropped from the recording", summary.dropped);
        }
    }
    std::fs::write(&args.part_out, serde_json::to_string(&part)?)
        .with_context(|| format!("writing {}", args.part_out.display()))?;
    Ok(())
}
