//! Latency under load: vehicle clients asking a planner process at a fixed rate, each driving
//! its own simulation (so that the snapshots are realistic and the hysteresis memory travels
//! as in a vehicle), with every request accounted for.
//!
//! Per request: the round trip, the planner's queueing and solve times (from the answer), the
//! answering layer, and whether the answer came by the deadline, late (within a grace period),
//! never (lost), or more than once (duplicated). The planner process's CPU and RSS are sampled
//! from `/proc` when its pid is known.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use decision::{Decision, PlannerConfig, Situation};
use hdrhistogram::Histogram;
use protocol::{Layer, OutcomeRef, PlanRequest};
use serde::{Deserialize, Serialize};

use crate::campaign::{paper_entries, trial_spec, CampaignSettings};
use crate::episode::{run_episode, Driver};
use crate::error::{Result, SimClientError};
use crate::link::{decision_from_response, LinkError, LinkOptions, PlanChannel, PlannerLink, Transport};

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

/// Histogram of microseconds, 1 µs .. 60 s at 3 significant digits.
fn histogram() -> Histogram<u64> {
    Histogram::new_with_bounds(1, 60_000_000, 3).expect("valid histogram bounds")
}

/// A histogram as (value, count) pairs: exact to merge across processes.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct HistogramData(pub Vec<(u64, u64)>);

impl HistogramData {
    fn of(h: &Histogram<u64>) -> Self {
        Self(
            h.iter_recorded()
                .map(|v| (v.value_iterated_to(), v.count_at_value()))
                .collect(),
        )
    }

    fn add_to(&self, h: &mut Histogram<u64>) {
        for &(value, count) in &self.0 {
            h.saturating_record_n(value, count);
        }
    }
}

/// Percentiles of a latency, µs.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Percentiles {
    /// Samples.
    pub count: u64,
    /// Mean.
    pub mean_us: f64,
    /// Median.
    pub p50_us: u64,
    /// 90th percentile.
    pub p90_us: u64,
    /// 99th percentile.
    pub p99_us: u64,
    /// 99.9th percentile.
    pub p999_us: u64,
    /// Largest.
    pub max_us: u64,
}

impl Percentiles {
    fn of(h: &Histogram<u64>) -> Self {
        if h.is_empty() {
            return Self::default();
        }
        Self {
            count: h.len(),
            mean_us: h.mean(),
            p50_us: h.value_at_quantile(0.5),
            p90_us: h.value_at_quantile(0.9),
            p99_us: h.value_at_quantile(0.99),
            p999_us: h.value_at_quantile(0.999),
            max_us: h.max(),
        }
    }
}

/// Answers by layer.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize, PartialEq, Eq)]
pub struct LayerCounts {
    /// The nominal MILP.
    pub nominal: u64,
    /// Layer A, the bounded global relaxation.
    pub global_relaxation: u64,
    /// Layer B, the deterministic fallback.
    pub fallback: u64,
    /// The planner's watchdog (deadline) or overload fallback.
    pub watchdog_fallback: u64,
    /// Rejections (invalid request).
    pub rejected: u64,
}

impl LayerCounts {
    fn add(&mut self, o: &LayerCounts) {
        self.nominal += o.nominal;
        self.global_relaxation += o.global_relaxation;
        self.fallback += o.fallback;
        self.watchdog_fallback += o.watchdog_fallback;
        self.rejected += o.rejected;
    }
}

/// Request accounting.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize, PartialEq, Eq)]
pub struct Counts {
    /// Requests sent.
    pub sent: u64,
    /// Answered by the deadline.
    pub in_time: u64,
    /// Answered after the deadline but within the grace period.
    pub late: u64,
    /// Never answered (nothing within deadline + grace).
    pub lost: u64,
    /// Answers beyond the first to one request.
    pub duplicated: u64,
    /// Answers whose vehicle id or sequence did not match the request.
    pub mismatched: u64,
}

impl Counts {
    fn add(&mut self, o: &Counts) {
        self.sent += o.sent;
        self.in_time += o.in_time;
        self.late += o.late;
        self.lost += o.lost;
        self.duplicated += o.duplicated;
        self.mismatched += o.mismatched;
    }

    /// Requests not answered by their deadline (late or lost).
    pub fn deadline_misses(&self) -> u64 {
        self.late + self.lost
    }
}

/// One interval of the run.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize, PartialEq)]
pub struct TimelinePoint {
    /// End of the interval, s since the start.
    pub t_s: f64,
    /// Requests sent in the interval.
    pub sent: u64,
    /// Answers by the deadline in the interval.
    pub in_time: u64,
    /// Deadline misses in the interval.
    pub misses: u64,
    /// Largest round trip in the interval, µs.
    pub max_round_trip_us: u64,
}

/// Adds `from` interval by interval into `into` (same period, both starting at 0).
fn add_timeline(into: &mut Vec<TimelinePoint>, from: &[TimelinePoint]) {
    for (i, p) in from.iter().enumerate() {
        if into.len() <= i {
            into.push(TimelinePoint {
                t_s: p.t_s,
                ..Default::default()
            });
        }
        let t = &mut into[i];
        t.sent += p.sent;
        t.in_time += p.in_time;
        t.misses += p.misses;
        t.max_round_trip_us = t.max_round_trip_us.max(p.max_round_trip_us);
    }
}

/// The measurements of some vehicles (one process): mergeable.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct LoadPart {
    /// Vehicles.
    pub clients: usize,
    /// Wall time of the part, s.
    pub elapsed_s: f64,
    /// Request accounting.
    pub counts: Counts,
    /// Answers by layer.
    pub by_layer: LayerCounts,
    /// Send to answer, µs.
    pub round_trip: HistogramData,
    /// The planner's queueing time, µs.
    pub queue: HistogramData,
    /// The planner's solve time, µs.
    pub solve: HistogramData,
    /// Round trip minus the planner's queueing and solve time, µs.
    pub transport: HistogramData,
    /// Per sample period.
    pub timeline: Vec<TimelinePoint>,
}

/// One sample of the planner process.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct ProcessSample {
    /// Time since the start, s.
    pub t_s: f64,
    /// CPU use since the previous sample, % of one core.
    pub cpu_percent: f64,
    /// Resident set size, KiB.
    pub rss_kib: u64,
}

/// The planner process over the run.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct ProcessReport {
    /// Process id.
    pub pid: u32,
    /// The samples.
    pub samples: Vec<ProcessSample>,
    /// RSS at the first sample after the warm-up.
    pub rss_after_warmup_kib: u64,
    /// Largest RSS after the warm-up.
    pub rss_max_after_warmup_kib: u64,
    /// `(rss_max_after_warmup - rss_after_warmup) / rss_after_warmup`, %.
    pub rss_growth_percent: f64,
    /// Mean CPU use over the run, % of one core.
    pub cpu_mean_percent: f64,
}

/// The result of a load or soak run.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct LoadReport {
    /// `inproc`, `iceoryx2` or `zenoh`.
    pub transport: String,
    /// Vehicles.
    pub clients: usize,
    /// Requests per second per vehicle.
    pub rate_hz: f64,
    /// Wall time, s.
    pub duration_s: f64,
    /// The vehicles' deadline, ms.
    pub deadline_ms: f64,
    /// Request accounting.
    pub counts: Counts,
    /// Late + lost.
    pub deadline_misses: u64,
    /// Answers by layer.
    pub by_layer: LayerCounts,
    /// Answers by the deadline per second of the run.
    pub throughput_per_s: f64,
    /// Send to answer.
    pub round_trip: Percentiles,
    /// The planner's queueing time.
    pub queue: Percentiles,
    /// The planner's solve time.
    pub solve: Percentiles,
    /// Round trip minus queueing and solve time: the transport's share.
    pub transport_overhead: Percentiles,
    /// Round trip at quantiles `1 - 10^-k`, k = 0, 0.1, .., 5: (k, µs), for the latency plot.
    pub round_trip_spectrum: Vec<(f64, u64)>,
    /// Per sample period.
    pub timeline: Vec<TimelinePoint>,
    /// The planner process's CPU and RSS, when its pid was known.
    pub planner: Option<ProcessReport>,
}

impl LoadReport {
    /// Builds the report from the parts of every process and the planner samples.
    pub fn merge(settings: &LoadSettings, parts: &[LoadPart], planner: Option<ProcessReport>) -> Self {
        let mut counts = Counts::default();
        let mut by_layer = LayerCounts::default();
        let (mut rt, mut q, mut s, mut tr) = (histogram(), histogram(), histogram(), histogram());
        let mut timeline: Vec<TimelinePoint> = Vec::new();
        let mut elapsed: f64 = 0.0;
        let mut clients = 0;
        for p in parts {
            clients += p.clients;
            counts.add(&p.counts);
            by_layer.add(&p.by_layer);
            p.round_trip.add_to(&mut rt);
            p.queue.add_to(&mut q);
            p.solve.add_to(&mut s);
            p.transport.add_to(&mut tr);
            elapsed = elapsed.max(p.elapsed_s);
            add_timeline(&mut timeline, &p.timeline);
        }
        Self {
            transport: settings.transport.to_string(),
            clients,
            rate_hz: settings.rate_hz,
            duration_s: elapsed,
            deadline_ms: settings.deadline.as_secs_f64() * 1e3,
            counts,
            deadline_misses: counts.deadline_misses(),
            by_layer,
            throughput_per_s: if elapsed > 0.0 {
                counts.in_time as f64 / elapsed
            } else {
                0.0
            },
            round_trip: Percentiles::of(&rt),
            queue: Percentiles::of(&q),
            solve: Percentiles::of(&s),
            transport_overhead: Percentiles::of(&tr),
            round_trip_spectrum: if rt.is_empty() {
                Vec::new()
            } else {
                (0..=50)
                    .map(|i| {
                        let nines = f64::from(i) / 10.0;
                        (nines, rt.value_at_quantile(1.0 - 10f64.powf(-nines)))
                    })
                    .collect()
            },
            timeline,
            planner,
        }
    }

    /// What a soak run must satisfy: every request answered exactly once, by its deadline,
    /// and the planner's memory flat after the warm-up. The list of violations.
    pub fn soak_violations(&self, max_rss_growth_percent: f64) -> Vec<String> {
        let mut v = Vec::new();
        let c = &self.counts;
        if c.sent == 0 {
            v.push("no request was sent".into());
        }
        for (n, what) in [
            (c.lost, "lost"),
            (c.late, "late (deadline misses)"),
            (c.duplicated, "duplicated"),
            (c.mismatched, "mismatched"),
        ] {
            if n > 0 {
                v.push(format!("{n} answers {what}"));
            }
        }
        if c.in_time + c.late + c.lost != c.sent {
            v.push(format!(
                "accounting: {} in time + {} late + {} lost != {} sent",
                c.in_time, c.late, c.lost, c.sent
            ));
        }
        if let Some(p) = &self.planner {
            if p.rss_growth_percent > max_rss_growth_percent {
                v.push(format!(
                    "planner RSS grew {:.1} % after the warm-up ({} -> {} KiB)",
                    p.rss_growth_percent, p.rss_after_warmup_kib, p.rss_max_after_warmup_kib
                ));
            }
        }
        v
    }
}

/// What one vehicle thread measures.
struct VehicleStats {
    counts: Counts,
    by_layer: LayerCounts,
    round_trip: Histogram<u64>,
    queue: Histogram<u64>,
    solve: Histogram<u64>,
    transport: Histogram<u64>,
    timeline: Vec<TimelinePoint>,
}

impl VehicleStats {
    fn new() -> Self {
        Self {
            counts: Counts::default(),
            by_layer: LayerCounts::default(),
            round_trip: histogram(),
            queue: histogram(),
            solve: histogram(),
            transport: histogram(),
            timeline: Vec::new(),
        }
    }

    fn point(&mut self, start: Instant, period: Duration, at: Instant) -> &mut TimelinePoint {
        let i = (at.saturating_duration_since(start).as_secs_f64() / period.as_secs_f64()) as usize;
        while self.timeline.len() <= i {
            let t_s = (self.timeline.len() + 1) as f64 * period.as_secs_f64();
            self.timeline.push(TimelinePoint {
                t_s,
                ..Default::default()
            });
        }
        &mut self.timeline[i]
    }
}

/// How one request ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum AnswerKind {
    InTime,
    Late,
    Lost,
}

/// Counters shared by every vehicle thread, for progress lines while the run goes on.
#[derive(Debug, Default)]
pub struct LiveCounters {
    /// Requests sent.
    pub sent: std::sync::atomic::AtomicU64,
    /// Decided by the deadline.
    pub in_time: std::sync::atomic::AtomicU64,
    /// Answered after the deadline.
    pub late: std::sync::atomic::AtomicU64,
    /// Never answered.
    pub lost: std::sync::atomic::AtomicU64,
    /// Extra answers.
    pub duplicated: std::sync::atomic::AtomicU64,
}

impl LiveCounters {
    fn record(&self, decided_in_time: bool, kind: AnswerKind) {
        self.sent.fetch_add(1, Ordering::Relaxed);
        if decided_in_time {
            self.in_time.fetch_add(1, Ordering::Relaxed);
        }
        match kind {
            AnswerKind::Late => self.late.fetch_add(1, Ordering::Relaxed),
            AnswerKind::Lost => self.lost.fetch_add(1, Ordering::Relaxed),
            AnswerKind::InTime => 0,
        };
    }

    /// (sent, in time, late, lost, duplicated) so far.
    pub fn get(&self) -> [u64; 5] {
        [&self.sent, &self.in_time, &self.late, &self.lost, &self.duplicated].map(|a| a.load(Ordering::Relaxed))
    }
}

/// A [`PlannerLink`] that sends at the vehicle's rate and measures; the simulation sees the
/// planner's decision when it came in time, else the vehicle's own fallback.
struct PacedLink<'a> {
    channel: Box<dyn PlanChannel>,
    settings: &'a LoadSettings,
    vehicle_id: u64,
    sequence: u64,
    start: Instant,
    next_send: Instant,
    end: Instant,
    stats: VehicleStats,
    live: Option<Arc<LiveCounters>>,
}

impl PlannerLink for PacedLink<'_> {
    fn decide(&mut self, situation: &Situation) -> std::result::Result<Decision, LinkError> {
        let now = Instant::now();
        if self.next_send > now {
            std::thread::sleep(self.next_send - now);
        }
        // Behind schedule (a late answer): send now rather than in a burst.
        self.next_send = self.next_send.max(Instant::now()) + Duration::from_secs_f64(1.0 / self.settings.rate_hz);
        if Instant::now() >= self.end {
            return Err(LinkError::Stopped);
        }
        self.sequence += 1;
        let sent = Instant::now();
        let timestamp_ns = u64::try_from(sent.duration_since(self.start).as_nanos()).unwrap_or(u64::MAX);
        let mut request = PlanRequest::from_situation(self.vehicle_id, self.sequence, timestamp_ns, situation)
            .map_err(|e| LinkError::Transport(format!("encoding the request: {e}")))?;
        let server_deadline = self.settings.deadline - self.settings.transport_margin;
        request.deadline_us = u32::try_from(server_deadline.as_micros()).unwrap_or(u32::MAX).max(1);
        let answer = self
            .channel
            .exchange(request, self.settings.deadline + self.settings.grace)
            .unwrap_or_else(|e| {
                tracing::warn!(vehicle = self.vehicle_id, "request failed: {e}");
                Default::default()
            });
        // Until the first answer: a channel may go on listening for duplicates.
        let round_trip = answer
            .answered_at
            .unwrap_or_else(Instant::now)
            .saturating_duration_since(sent);
        let stats = &mut self.stats;
        stats.counts.sent += 1;
        stats.counts.duplicated += answer.extra_responses as u64;
        let in_time = round_trip <= self.settings.deadline;
        let mut decision = None;
        let answer_kind = match (&answer.response, in_time) {
            (None, _) => AnswerKind::Lost,
            (Some(_), true) => AnswerKind::InTime,
            (Some(_), false) => AnswerKind::Late,
        };
        if let Some(live) = &self.live {
            live.duplicated
                .fetch_add(answer.extra_responses as u64, Ordering::Relaxed);
        }
        match answer_kind {
            AnswerKind::InTime => stats.counts.in_time += 1,
            AnswerKind::Late => stats.counts.late += 1,
            AnswerKind::Lost => stats.counts.lost += 1,
        }
        if let Some(response) = answer.response {
            let matches = (response.vehicle_id, response.sequence) == (self.vehicle_id, self.sequence);
            if !matches {
                stats.counts.mismatched += 1;
            }
            let rt_us = u64::try_from(round_trip.as_micros()).unwrap_or(u64::MAX).max(1);
            let server_us = u64::from(response.queue_us) + u64::from(response.solve_us);
            stats.round_trip.saturating_record(rt_us);
            stats.queue.saturating_record(u64::from(response.queue_us).max(1));
            stats.solve.saturating_record(u64::from(response.solve_us).max(1));
            stats
                .transport
                .saturating_record(rt_us.saturating_sub(server_us).max(1));
            match response.outcome.get() {
                Ok(OutcomeRef::Decided(d)) => match d.layer() {
                    Ok(Layer::Nominal) => stats.by_layer.nominal += 1,
                    Ok(Layer::GlobalRelaxation) => stats.by_layer.global_relaxation += 1,
                    Ok(Layer::Fallback) => stats.by_layer.fallback += 1,
                    Ok(Layer::WatchdogFallback) => stats.by_layer.watchdog_fallback += 1,
                    Err(_) => stats.by_layer.rejected += 1,
                },
                _ => stats.by_layer.rejected += 1,
            }
            // A rejection or a late answer: the vehicle decides by itself.
            if in_time && matches {
                decision = decision_from_response(&self.settings.planner, &response).ok();
            }
        }
        let answered_in_time = in_time && decision.is_some();
        if let Some(live) = &self.live {
            live.record(answered_in_time, answer_kind);
        }
        let (start, period) = (self.start, self.settings.sample_period);
        let point = stats.point(start, period, sent);
        point.sent += 1;
        if answered_in_time {
            point.in_time += 1;
        } else {
            point.misses += 1;
        }
        point.max_round_trip_us = point
            .max_round_trip_us
            .max(u64::try_from(round_trip.as_micros()).unwrap_or(u64::MAX));
        match decision {
            Some(d) => Ok(d),
            // What the vehicle does without an answer in time.
            None => Ok(decision::fallback_only(&self.settings.planner, situation)?),
        }
    }
}

/// One vehicle: simulations one after another (Table I classes in turn), until the end.
fn run_vehicle(settings: &LoadSettings, index: usize, start: Instant, end: Instant) -> Result<VehicleStats> {
    let vehicle_id = settings.vehicle_id_base + index as u64;
    let options = LinkOptions {
        deadline: settings.deadline,
        transport_margin: settings.transport_margin,
        ready_timeout: Duration::from_secs(60),
        answer_grace: settings.grace,
        vehicle_id,
    };
    let channel = settings.transport.open_channel(&settings.planner, &options)?;
    // Spread the vehicles over the period, so that the load is even.
    let phase = Duration::from_secs_f64(index as f64 / (settings.clients as f64 * settings.rate_hz));
    let mut link = PacedLink {
        channel,
        settings,
        vehicle_id,
        sequence: 0,
        start,
        next_send: start + phase,
        end,
        stats: VehicleStats::new(),
        live: settings.live.clone(),
    };
    let entries = paper_entries();
    let mut campaign = CampaignSettings::new(entries.clone(), settings.seed ^ vehicle_id, 1);
    campaign.planner = settings.planner.clone();
    for episode in 0u32.. {
        let entry = &entries[(index + episode as usize) % entries.len()];
        let spec = trial_spec(entry, episode, &campaign)?;
        match run_episode(&spec, Driver::Planner(&mut link)) {
            Ok(_) => {}
            Err(SimClientError::Link(LinkError::Stopped)) => break,
            Err(e) => return Err(e),
        }
    }
    Ok(link.stats)
}

/// Runs `settings.clients` vehicles (threads) until the duration is over; returns their
/// merged measurements.
pub fn run_part(settings: &LoadSettings, start: Instant) -> Result<LoadPart> {
    settings.validate()?;
    let end = start + settings.duration;
    let results: Vec<Result<VehicleStats>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..settings.clients)
            .map(|i| scope.spawn(move || run_vehicle(settings, i, start, end)))
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
    let (mut rt, mut q, mut s, mut tr) = (histogram(), histogram(), histogram(), histogram());
    for r in results {
        let v = r?;
        part.counts.add(&v.counts);
        part.by_layer.add(&v.by_layer);
        for (into, from) in [
            (&mut rt, &v.round_trip),
            (&mut q, &v.queue),
            (&mut s, &v.solve),
            (&mut tr, &v.transport),
        ] {
            into.add(from)
                .map_err(|e| SimClientError::Config(format!("histogram: {e}")))?;
        }
        add_timeline(&mut part.timeline, &v.timeline);
    }
    part.round_trip = HistogramData::of(&rt);
    part.queue = HistogramData::of(&q);
    part.solve = HistogramData::of(&s);
    part.transport = HistogramData::of(&tr);
    Ok(part)
}

/// Samples a process's CPU and RSS from `/proc` every `period` until stopped.
pub struct ProcessMonitor {
    stop: Arc<AtomicBool>,
    samples: Arc<Mutex<Vec<ProcessSample>>>,
    thread: Option<std::thread::JoinHandle<()>>,
    pid: u32,
}

/// (utime + stime in clock ticks, RSS in KiB) of `pid`.
fn read_proc(pid: u32) -> Option<(u64, u64)> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name may contain spaces; fields count from after its closing parenthesis.
    let rest = stat.get(stat.rfind(')')? + 2..)?;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let utime: u64 = fields.get(11)?.parse().ok()?;
    let stime: u64 = fields.get(12)?.parse().ok()?;
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let rss = status
        .lines()
        .find(|l| l.starts_with("VmRSS:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()?;
    Some((utime + stime, rss))
}

impl ProcessMonitor {
    /// Starts sampling `pid`.
    pub fn start(pid: u32, period: Duration) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let samples = Arc::new(Mutex::new(Vec::new()));
        let (s, out) = (Arc::clone(&stop), Arc::clone(&samples));
        // SAFETY: sysconf has no preconditions.
        let ticks_per_s = unsafe { libc::sysconf(libc::_SC_CLK_TCK) }.max(1) as f64;
        let thread = std::thread::spawn(move || {
            let start = Instant::now();
            let mut last = read_proc(pid).map(|(cpu, _)| (Instant::now(), cpu));
            while !s.load(Ordering::Relaxed) {
                std::thread::sleep(period);
                let Some((cpu, rss)) = read_proc(pid) else { break };
                let now = Instant::now();
                let cpu_percent = match last {
                    Some((t, c)) => 100.0 * (cpu.saturating_sub(c) as f64 / ticks_per_s) / (now - t).as_secs_f64(),
                    None => 0.0,
                };
                last = Some((now, cpu));
                out.lock().unwrap_or_else(|e| e.into_inner()).push(ProcessSample {
                    t_s: start.elapsed().as_secs_f64(),
                    cpu_percent,
                    rss_kib: rss,
                });
            }
        });
        Self {
            stop,
            samples,
            thread: Some(thread),
            pid,
        }
    }

    /// Stops sampling; the report, with RSS growth measured after `warmup`.
    pub fn finish(mut self, warmup: Duration) -> ProcessReport {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        let samples = std::mem::take(&mut *self.samples.lock().unwrap_or_else(|e| e.into_inner()));
        let after: Vec<&ProcessSample> = samples.iter().filter(|s| s.t_s >= warmup.as_secs_f64()).collect();
        let base = after.first().map_or(0, |s| s.rss_kib);
        let max = after.iter().map(|s| s.rss_kib).max().unwrap_or(0);
        let cpu_mean_percent = if samples.is_empty() {
            0.0
        } else {
            samples.iter().map(|s| s.cpu_percent).sum::<f64>() / samples.len() as f64
        };
        ProcessReport {
            pid: self.pid,
            rss_after_warmup_kib: base,
            rss_max_after_warmup_kib: max,
            rss_growth_percent: if base > 0 {
                100.0 * (max.saturating_sub(base)) as f64 / base as f64
            } else {
                0.0
            },
            cpu_mean_percent,
            samples,
        }
    }
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
