//! Latency under load: vehicle clients asking a planner process at a fixed rate, each driving
//! its own simulation (so that the snapshots are realistic and the hysteresis memory travels
//! as in a vehicle), with every request accounted for.
//!
//! Per request: the round trip, the planner's queueing and solve times (from the answer), the
//! answering layer, and whether the answer came by the deadline, late (within a grace period),
//! never (lost), or more than once (duplicated). The planner process's CPU and RSS are sampled
//! from `/proc` when its pid is known. With a recorder, every request and its answer are
//! recorded as the planner records them (docs/recording.md).

mod flood;
mod multiprocess;
mod procmon;
mod report;
mod vehicle;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use decision::PlannerConfig;

pub use flood::{run_flood, FloodReport, FloodSettings};
pub use multiprocess::{run_worker_processes, transport_flags, worker_count, worker_record_path};
pub use procmon::{ProcessMonitor, ProcessReport, ProcessSample};
pub use report::{Counts, HistogramData, LoadPart, LoadReport, TimelinePoint};
pub use vehicle::LiveCounters;

use crate::connect::Transport;
use crate::error::{Result, SimClientError};

/// What to run.
#[derive(Debug, Clone)]
pub struct LoadSettings {
    /// How the planner is reached (`inproc` measures the planner and the message conversions
    /// alone: the baseline of a transport's share).
    pub transport: Transport,
    /// Vehicle clients (threads of this process).
    pub clients: usize,
    /// Requests per second per vehicle.
    pub rate_hz: f64,
    /// Length of the run.
    pub duration: Duration,
    /// RSS growth is measured against the first sample after this.
    pub warmup: Duration,
    /// The vehicle's deadline, from sending to the answer.
    pub deadline: Duration,
    /// Part of the deadline kept for the transport (the request asks the planner for
    /// `deadline - transport_margin`).
    pub transport_margin: Duration,
    /// An answer this long after the deadline still counts as late, not lost.
    pub grace: Duration,
    /// Seed of the scenarios.
    pub seed: u64,
    /// Used for the scenarios' SV count and the vehicle's own fallback.
    pub planner: PlannerConfig,
    /// The planner's process, for CPU and RSS samples.
    pub planner_pid: Option<u32>,
    /// Vehicle ids are `vehicle_id_base + 0 .. clients`.
    pub vehicle_id_base: u64,
    /// Interval of the CPU / RSS samples and of the timeline.
    pub sample_period: Duration,
    /// Shared counters for progress reports while the run goes on.
    pub live: Option<Arc<LiveCounters>>,
    /// Records every request the vehicles send and the answer each got (`load --record`):
    /// the vehicles' side of the exchange, which `planner replay` re-decides.
    pub recorder: Option<recording::PlanRecorder>,
}

impl LoadSettings {
    /// `clients` vehicles at `rate_hz` for `duration` over `transport`, with the defaults of
    /// a vehicle (400 ms deadline, 20 ms of it for the transport, 1 s grace).
    pub fn new(transport: Transport, clients: usize, rate_hz: f64, duration: Duration) -> Self {
        Self {
            transport,
            clients,
            rate_hz,
            duration,
            warmup: Duration::from_secs(10).min(duration / 4),
            deadline: protocol::DEFAULT_DEADLINE,
            transport_margin: Duration::from_millis(20),
            grace: Duration::from_secs(1),
            seed: 7,
            planner: PlannerConfig::default(),
            planner_pid: None,
            vehicle_id_base: 1,
            sample_period: Duration::from_secs(1),
            live: None,
            recorder: None,
        }
    }

    fn validate(&self) -> Result<()> {
        let bad = |m: &str| Err(SimClientError::Config(m.into()));
        if self.clients == 0 {
            return bad("--clients must be at least 1");
        }
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0) {
            return bad("--rate must be positive");
        }
        if self.duration.is_zero() {
            return bad("--duration must be positive");
        }
        if self.transport_margin >= self.deadline {
            return bad("the transport margin must be shorter than the deadline");
        }
        Ok(())
    }
}

/// A run length: a plain number is seconds (`20`, `0.5`), else a duration (`20s`, `10m`,
/// `1h`).
pub fn parse_run_length(s: &str) -> std::result::Result<Duration, String> {
    match s.parse::<f64>() {
        Ok(secs) if secs.is_finite() && secs >= 0.0 => Ok(Duration::from_secs_f64(secs)),
        Ok(_) => Err(format!("`{s}` is not a length of time")),
        Err(_) => humantime::parse_duration(s).map_err(|e| e.to_string()),
    }
}

/// Runs `settings.clients` vehicles (threads) until the duration is over; returns their
/// merged measurements.
pub fn run_part(settings: &LoadSettings, start: Instant) -> Result<LoadPart> {
    settings.validate()?;
    let end = start + settings.duration;
    let results: Vec<Result<vehicle::VehicleStats>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..settings.clients)
            .map(|i| scope.spawn(move || vehicle::run_vehicle(settings, i, start, end)))
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|_| Err(SimClientError::Config("a vehicle thread panicked".into())))
            })
            .collect()
    });
    let mut part = LoadPart {
        clients: settings.clients,
        elapsed_s: start.elapsed().as_secs_f64(),
        ..Default::default()
    };
    let [mut rt, mut q, mut s, mut tr, mut wp, mut wr] = [(); 6].map(|_| stats::histogram());
    for r in results {
        let v = r?;
        part.counts.add(&v.counts);
        part.by_layer.merge(&v.by_layer);
        for (into, from) in [
            (&mut rt, &v.round_trip),
            (&mut q, &v.queue),
            (&mut s, &v.solve),
            (&mut tr, &v.transport),
            (&mut wp, &v.watchdog_late_planner),
            (&mut wr, &v.watchdog_late_received),
        ] {
            into.add(from)
                .map_err(|e| SimClientError::Config(format!("histogram: {e}")))?;
        }
        report::add_timeline(&mut part.timeline, &v.timeline);
    }
    part.round_trip = HistogramData::of(&rt);
    part.queue = HistogramData::of(&q);
    part.solve = HistogramData::of(&s);
    part.transport = HistogramData::of(&tr);
    part.watchdog_late_planner = HistogramData::of(&wp);
    part.watchdog_late_received = HistogramData::of(&wr);
    Ok(part)
}

/// Runs the load in this process and reports (with the planner's samples when its pid is
/// known).
pub fn run_load(settings: &LoadSettings) -> Result<LoadReport> {
    settings.validate()?;
    let monitor = settings
        .planner_pid
        .map(|pid| ProcessMonitor::start(pid, settings.sample_period));
    let part = run_part(settings, Instant::now())?;
    let planner = monitor.map(|m| m.finish(settings.warmup));
    Ok(LoadReport::merge(settings, &[part], planner))
}

/// A thread printing the live counters to stderr every `every` until dropped.
pub struct ProgressLines {
    done: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl ProgressLines {
    /// Starts printing `live`.
    pub fn start(live: Arc<LiveCounters>, every: Duration) -> Self {
        let done = Arc::new(AtomicBool::new(false));
        let stop = Arc::clone(&done);
        let started = Instant::now();
        let thread = std::thread::spawn(move || {
            let mut next = started + every;
            while !stop.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(100));
                if Instant::now() >= next {
                    next += every;
                    let [sent, in_time, late, lost, dup] = live.get();
                    eprintln!(
                        "[{:>7.1} s] sent {sent}, decided in time {in_time}, late {late}, lost {lost}, duplicated {dup}",
                        started.elapsed().as_secs_f64()
                    );
                }
            }
        });
        Self {
            done,
            thread: Some(thread),
        }
    }
}

impl Drop for ProgressLines {
    fn drop(&mut self) {
        self.done.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_lengths_are_seconds_or_durations() {
        assert_eq!(parse_run_length("20"), Ok(Duration::from_secs(20)));
        assert_eq!(parse_run_length("0.5"), Ok(Duration::from_millis(500)));
        assert_eq!(parse_run_length("20s"), Ok(Duration::from_secs(20)));
        assert_eq!(parse_run_length("10m"), Ok(Duration::from_secs(600)));
        assert_eq!(parse_run_length("1500ms"), Ok(Duration::from_millis(1500)));
        assert!(parse_run_length("-3").is_err());
        assert!(parse_run_length("soon").is_err());
    }
}
