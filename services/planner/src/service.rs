//! The transport-free core of `planner serve`: a worker pool with a bounded queue, a deadline
//! watchdog, statistics.
//!
//! * [`Service::handle_bytes`] / [`Service::submit`] take a request and a reply callback; the
//!   callback is called **exactly once** (by a worker, by the watchdog, or at once for
//!   malformed input, rejected input and overload), never blocks the caller.
//! * Each worker thread owns a [`decision::Planner`] (not `Send`: built on its thread).
//! * The watchdog thread answers `decision::fallback_only` marked
//!   [`Layer::WatchdogFallback`] when a deadline runs out, interrupts the running HiGHS solve
//!   and makes the worker discard its late result.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use decision::{InterruptHandle, Planner, PlannerConfig};
use hdrhistogram::Histogram;
use protocol::{
    decode_bincode, decode_json, encode_bincode, encode_json, Layer, PlanRequest, PlanResponse, RejectReason, Rejected,
    WireError, DEFAULT_DEADLINE,
};
use serde::Serialize;

/// How a request body is encoded (chosen by the transport's encoding field).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireFormat {
    Bincode,
    Json,
}

impl WireFormat {
    pub fn decode(self, bytes: &[u8]) -> Result<PlanRequest, WireError> {
        match self {
            WireFormat::Bincode => decode_bincode(bytes),
            WireFormat::Json => decode_json(bytes),
        }
    }

    pub fn encode(self, response: &PlanResponse) -> Vec<u8> {
        match self {
            WireFormat::Bincode => encode_bincode(response),
            WireFormat::Json => encode_json(response).into_bytes(),
        }
    }
}

/// Default queue places per worker. Solves take about a millisecond (p99 ~2 ms), so a full
/// queue still drains well inside the 400 ms deadline, while bursts of simultaneous requests
/// (many vehicles, Zenoh delivering in batches) are solved instead of answered by the
/// overload fallback. A request that waits too long still gets the watchdog's answer on time.
pub const QUEUE_PER_WORKER: usize = 32;

/// Settings of the service core.
#[derive(Debug, Clone)]
pub struct ServiceConfig {
    /// Worker threads, each with its own planner.
    pub workers: usize,
    /// Requests that may wait for a worker; beyond that the fallback answers at once.
    pub queue_capacity: usize,
    /// Upper bound of every deadline (a request may ask for a shorter one).
    pub max_deadline: Duration,
    /// TEST ONLY: sleep this long before every solve, to force the watchdog.
    pub inject_solve_delay: Duration,
}

impl Default for ServiceConfig {
    fn default() -> Self {
        let workers = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
        Self {
            workers,
            queue_capacity: QUEUE_PER_WORKER * workers,
            max_deadline: DEFAULT_DEADLINE,
            inject_solve_delay: Duration::ZERO,
        }
    }
}

/// The reply callback of one request.
pub type Reply = Box<dyn FnOnce(PlanResponse) + Send>;

fn micros(d: Duration) -> u32 {
    u32::try_from(d.as_micros()).unwrap_or(u32::MAX)
}

/// What the worker, the watchdog and the submitter share about one request.
struct JobState {
    request: PlanRequest,
    arrival: Instant,
    deadline: Instant,
    /// Taken by whoever answers first.
    reply: Mutex<Option<Reply>>,
    /// Set by the watchdog: the worker must stop and discard its result.
    abandoned: AtomicBool,
    /// The worker's interrupt handle and the id of its first solve for this job.
    solving: Mutex<Option<(InterruptHandle, u64)>>,
}

impl JobState {
    fn take_reply(&self) -> Option<Reply> {
        self.reply.lock().unwrap_or_else(|e| e.into_inner()).take()
    }
}

/// Counters by answering layer and latency histograms.
#[derive(Default)]
struct Counters {
    nominal: u64,
    global_relaxation: u64,
    fallback: u64,
    watchdog_fallback: u64,
    rejected: u64,
    overloaded: u64,
    late_discarded: u64,
}

struct StatsInner {
    counters: Counters,
    /// Arrival to answer, µs.
    latency: Histogram<u64>,
    /// Worker decision time, µs.
    solve: Histogram<u64>,
}

/// Statistics of the service, shared by every thread.
pub struct Stats {
    started: Instant,
    inner: Mutex<StatsInner>,
}

/// Percentiles of a histogram, µs.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Percentiles {
    pub count: u64,
    pub p50_us: u64,
    pub p90_us: u64,
    pub p99_us: u64,
    pub max_us: u64,
}

impl Percentiles {
    fn of(h: &Histogram<u64>) -> Self {
        Self {
            count: h.len(),
            p50_us: h.value_at_quantile(0.5),
            p90_us: h.value_at_quantile(0.9),
            p99_us: h.value_at_quantile(0.99),
            max_us: h.max(),
        }
    }
}

/// Answers by layer (rejections and overload answers counted apart).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct LayerCounts {
    pub nominal: u64,
    pub global_relaxation: u64,
    pub fallback: u64,
    pub watchdog_fallback: u64,
    pub rejected: u64,
}

/// The JSON statistics document (published on `hmdp/planner/stats`).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct StatsSnapshot {
    pub uptime_s: f64,
    pub answered: u64,
    pub by_layer: LayerCounts,
    /// Fallback answers given because the queue was full (also counted in `watchdog_fallback`).
    pub overloaded: u64,
    /// Worker results that arrived after the watchdog had answered.
    pub late_discarded: u64,
    /// Arrival to answer.
    pub latency: Percentiles,
    /// Worker decision time (excludes queueing).
    pub solve: Percentiles,
}

impl Stats {
    fn new() -> Self {
        let hist = || Histogram::new_with_bounds(1, 60_000_000, 3).unwrap_or_else(|_| Histogram::new(3).unwrap());
        Self {
            started: Instant::now(),
            inner: Mutex::new(StatsInner {
                counters: Counters::default(),
                latency: hist(),
                solve: hist(),
            }),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, StatsInner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn record_answer(&self, response: &PlanResponse, arrival: Instant) {
        let mut s = self.lock();
        match response.outcome.as_decided().and_then(|d| d.layer().ok()) {
            Some(Layer::Nominal) => s.counters.nominal += 1,
            Some(Layer::GlobalRelaxation) => s.counters.global_relaxation += 1,
            Some(Layer::Fallback) => s.counters.fallback += 1,
            Some(Layer::WatchdogFallback) => s.counters.watchdog_fallback += 1,
            None => s.counters.rejected += 1,
        }
        let us = u64::try_from(arrival.elapsed().as_micros()).unwrap_or(u64::MAX).max(1);
        s.latency.saturating_record(us);
    }

    fn record_solve(&self, us: u64) {
        self.lock().solve.saturating_record(us.max(1));
    }

    /// The current statistics.
    pub fn snapshot(&self) -> StatsSnapshot {
        let s = self.lock();
        let c = &s.counters;
        StatsSnapshot {
            uptime_s: self.started.elapsed().as_secs_f64(),
            answered: c.nominal + c.global_relaxation + c.fallback + c.watchdog_fallback + c.rejected,
            by_layer: LayerCounts {
                nominal: c.nominal,
                global_relaxation: c.global_relaxation,
                fallback: c.fallback,
                watchdog_fallback: c.watchdog_fallback,
                rejected: c.rejected,
            },
            overloaded: c.overloaded,
            late_discarded: c.late_discarded,
            latency: Percentiles::of(&s.latency),
            solve: Percentiles::of(&s.solve),
        }
    }
}

/// The service core. Dropping it (or [`Service::shutdown`]) stops the threads.
pub struct Service {
    planner_config: Arc<PlannerConfig>,
    config: ServiceConfig,
    queue: Option<SyncSender<Arc<JobState>>>,
    watchdog: Option<mpsc::Sender<Arc<JobState>>>,
    stats: Arc<Stats>,
    threads: Vec<JoinHandle<()>>,
}

impl Service {
    /// Starts the workers (each builds its planner; fails if one cannot) and the watchdog.
    pub fn start(planner_config: PlannerConfig, config: ServiceConfig) -> anyhow::Result<Self> {
        let planner_config = Arc::new(planner_config);
        let stats = Arc::new(Stats::new());
        let workers = config.workers.max(1);
        let (queue_tx, queue_rx) = mpsc::sync_channel::<Arc<JobState>>(config.queue_capacity.max(1));
        let queue_rx = Arc::new(Mutex::new(queue_rx));
        let mut threads = Vec::new();
        let (ready_tx, ready_rx) = mpsc::channel::<Result<(), String>>();
        for i in 0..workers {
            let rx = Arc::clone(&queue_rx);
            let cfg = Arc::clone(&planner_config);
            let stats = Arc::clone(&stats);
            let ready = ready_tx.clone();
            let delay = config.inject_solve_delay;
            threads.push(
                std::thread::Builder::new()
                    .name(format!("planner-worker-{i}"))
                    .spawn(move || worker(&cfg, &rx, &stats, delay, &ready))?,
            );
        }
        drop(ready_tx);
        for _ in 0..workers {
            match ready_rx.recv() {
                Ok(Ok(())) => {}
                Ok(Err(e)) => anyhow::bail!("a worker could not build its planner: {e}"),
                Err(_) => anyhow::bail!("a worker died while starting"),
            }
        }
        let (wd_tx, wd_rx) = mpsc::channel::<Arc<JobState>>();
        {
            let cfg = Arc::clone(&planner_config);
            let stats = Arc::clone(&stats);
            threads.push(
                std::thread::Builder::new()
                    .name("planner-watchdog".into())
                    .spawn(move || watchdog(&cfg, &wd_rx, &stats))?,
            );
        }
        Ok(Self {
            planner_config,
            config,
            queue: Some(queue_tx),
            watchdog: Some(wd_tx),
            stats,
            threads,
        })
    }

    /// The statistics (shared; read [`Stats::snapshot`]).
    pub fn stats(&self) -> Arc<Stats> {
        Arc::clone(&self.stats)
    }

    /// Decodes `bytes` and submits the request; undecodable bytes are answered at once with a
    /// `malformed` / `unsupported_version` / `capacity_exceeded` rejection.
    pub fn handle_bytes(&self, bytes: &[u8], format: WireFormat, arrival: Instant, reply: Reply) {
        match format.decode(bytes) {
            Ok(request) => self.submit(request, arrival, reply),
            Err(e) => {
                let (vehicle_id, sequence) = peek_ids(bytes, format);
                let rejected = match &e {
                    WireError::UnsupportedVersion { .. } => Rejected::new(RejectReason::UnsupportedVersion, "version"),
                    WireError::CapacityExceeded(_) => Rejected::new(
                        RejectReason::CapacityExceeded,
                        protocol::request_over_capacity_field(bytes, format == WireFormat::Json).unwrap_or(""),
                    ),
                    _ => Rejected::new(RejectReason::Malformed, ""),
                };
                tracing::debug!(error = %e, "undecodable request");
                let response = PlanResponse::rejected(vehicle_id, sequence, rejected, micros(arrival.elapsed()));
                self.stats.record_answer(&response, arrival);
                reply(response);
            }
        }
    }

    /// Submits a decoded request. The reply is called exactly once.
    pub fn submit(&self, request: PlanRequest, arrival: Instant, reply: Reply) {
        // Wire-level checks the decoder does not make (enum ranges, ...).
        if let Err(rejected) = request.validate() {
            let response = PlanResponse::rejected(
                request.vehicle_id,
                request.sequence,
                rejected,
                micros(arrival.elapsed()),
            );
            self.stats.record_answer(&response, arrival);
            reply(response);
            return;
        }
        let deadline = arrival + request.deadline().min(self.config.max_deadline);
        let job = Arc::new(JobState {
            request,
            arrival,
            deadline,
            reply: Mutex::new(Some(reply)),
            abandoned: AtomicBool::new(false),
            solving: Mutex::new(None),
        });
        let Some(queue) = &self.queue else {
            answer_fallback(&self.planner_config, &job, &self.stats);
            return;
        };
        match queue.try_send(Arc::clone(&job)) {
            Ok(()) => {
                if let Some(wd) = &self.watchdog {
                    let _ = wd.send(job);
                }
            }
            Err(TrySendError::Full(job)) | Err(TrySendError::Disconnected(job)) => {
                self.stats.lock().counters.overloaded += 1;
                job.abandoned.store(true, Ordering::SeqCst);
                answer_fallback(&self.planner_config, &job, &self.stats);
            }
        }
    }

    /// Stops accepting work and joins the threads (queued jobs are still answered).
    pub fn shutdown(&mut self) {
        self.queue = None;
        self.watchdog = None;
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

impl Drop for Service {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Vehicle id and sequence of an undecodable message, when they can be read.
fn peek_ids(bytes: &[u8], format: WireFormat) -> (u64, u64) {
    match format {
        WireFormat::Bincode if bytes.len() >= 18 => {
            let id = u64::from_le_bytes(bytes[2..10].try_into().unwrap_or([0; 8]));
            let seq = u64::from_le_bytes(bytes[10..18].try_into().unwrap_or([0; 8]));
            (id, seq)
        }
        WireFormat::Json if bytes.len() > protocol::MAX_MESSAGE_BYTES => (0, 0),
        WireFormat::Json => match serde_json::from_slice::<serde_json::Value>(bytes) {
            Ok(v) => (
                v.get("vehicle_id").and_then(|x| x.as_u64()).unwrap_or(0),
                v.get("sequence").and_then(|x| x.as_u64()).unwrap_or(0),
            ),
            Err(_) => (0, 0),
        },
        _ => (0, 0),
    }
}

/// Answers `job` with the fallback marked `WatchdogFallback`, if nobody answered yet.
fn answer_fallback(config: &PlannerConfig, job: &JobState, stats: &Stats) -> bool {
    let Some(reply) = job.take_reply() else {
        return false;
    };
    let request = &job.request;
    let queue_us = micros(job.arrival.elapsed());
    let response = match decision::fallback_only(config, &request.to_situation()) {
        Ok(decision) => match protocol::Decided::try_from(&decision) {
            Ok(mut decided) => {
                decided.set_layer(Layer::WatchdogFallback);
                PlanResponse::decided(request.vehicle_id, request.sequence, decided, 0, queue_us)
            }
            Err(_) => rejected_internal(request, queue_us),
        },
        Err(e) => PlanResponse::rejected(request.vehicle_id, request.sequence, Rejected::from(&e), queue_us),
    };
    stats.record_answer(&response, job.arrival);
    reply(response);
    true
}

fn rejected_internal(request: &PlanRequest, queue_us: u32) -> PlanResponse {
    PlanResponse::rejected(
        request.vehicle_id,
        request.sequence,
        Rejected::new(RejectReason::InternalError, "solver"),
        queue_us,
    )
}

fn worker(
    config: &PlannerConfig,
    queue: &Mutex<Receiver<Arc<JobState>>>,
    stats: &Stats,
    inject_delay: Duration,
    ready: &mpsc::Sender<Result<(), String>>,
) {
    let mut planner = match Planner::new(config.clone()) {
        Ok(p) => {
            let _ = ready.send(Ok(()));
            p
        }
        Err(e) => {
            let _ = ready.send(Err(e.to_string()));
            return;
        }
    };
    let handle = planner.interrupt_handle();
    loop {
        let job = {
            let rx = queue.lock().unwrap_or_else(|e| e.into_inner());
            match rx.recv() {
                Ok(job) => job,
                Err(_) => return,
            }
        };
        if job.abandoned.load(Ordering::SeqCst) {
            continue;
        }
        let started = Instant::now();
        if let (Some(h), Some(id)) = (&handle, planner.next_solve_id()) {
            *job.solving.lock().unwrap_or_else(|e| e.into_inner()) = Some((h.clone(), id));
        }
        if !inject_delay.is_zero() {
            // Test only: sleep in slices so that an abandoned job frees the worker early.
            let until = started + inject_delay;
            while Instant::now() < until && !job.abandoned.load(Ordering::SeqCst) {
                std::thread::sleep(Duration::from_millis(2).min(until.saturating_duration_since(Instant::now())));
            }
            if job.abandoned.load(Ordering::SeqCst) {
                stats.lock().counters.late_discarded += 1;
                continue;
            }
        }
        let queue_us = micros(started.duration_since(job.arrival));
        let result = planner.decide(&job.request.to_situation());
        *job.solving.lock().unwrap_or_else(|e| e.into_inner()) = None;
        stats.record_solve(u64::try_from(started.elapsed().as_micros()).unwrap_or(u64::MAX));
        let request = &job.request;
        let response = match &result {
            Ok(decision) => PlanResponse::from_decision(request, decision, queue_us)
                .unwrap_or_else(|_| rejected_internal(request, queue_us)),
            Err(e) => PlanResponse::rejected(request.vehicle_id, request.sequence, Rejected::from(e), queue_us),
        };
        match job.take_reply() {
            Some(reply) => {
                stats.record_answer(&response, job.arrival);
                reply(response);
            }
            None => stats.lock().counters.late_discarded += 1,
        }
    }
}

fn watchdog(config: &PlannerConfig, jobs: &Receiver<Arc<JobState>>, stats: &Stats) {
    // Min-heap of deadlines; the sequence number breaks ties.
    let mut heap: BinaryHeap<Reverse<(Instant, u64)>> = BinaryHeap::new();
    let mut pending: std::collections::HashMap<u64, Arc<JobState>> = std::collections::HashMap::new();
    let next = AtomicU64::new(0);
    let mut last_log = Instant::now();
    let mut open = true;
    while open || !heap.is_empty() {
        let timeout = match heap.peek() {
            Some(Reverse((deadline, _))) => deadline.saturating_duration_since(Instant::now()),
            None => Duration::from_millis(1000),
        };
        let received = if open {
            jobs.recv_timeout(timeout)
        } else {
            std::thread::sleep(timeout);
            Err(RecvTimeoutError::Timeout)
        };
        match received {
            Ok(job) => {
                let n = next.fetch_add(1, Ordering::Relaxed);
                heap.push(Reverse((job.deadline, n)));
                pending.insert(n, job);
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => open = false,
        }
        let now = Instant::now();
        while let Some(Reverse((deadline, n))) = heap.peek().copied() {
            if deadline > now {
                break;
            }
            heap.pop();
            let Some(job) = pending.remove(&n) else { continue };
            if job.reply.lock().unwrap_or_else(|e| e.into_inner()).is_none() {
                continue; // already answered
            }
            job.abandoned.store(true, Ordering::SeqCst);
            if let Some((handle, first_id)) = job.solving.lock().unwrap_or_else(|e| e.into_inner()).clone() {
                match handle.running() {
                    Some(id) if id >= first_id => handle.interrupt(id),
                    _ => handle.interrupt(first_id),
                }
            }
            if answer_fallback(config, &job, stats) {
                tracing::debug!(
                    vehicle = job.request.vehicle_id,
                    sequence = job.request.sequence,
                    "deadline ran out: watchdog fallback"
                );
            }
        }
        // Drop finished jobs lazily: answered jobs leave the map when their deadline passes.
        if last_log.elapsed() >= Duration::from_secs(10) {
            last_log = Instant::now();
            let s = stats.snapshot();
            tracing::info!(
                answered = s.answered,
                nominal = s.by_layer.nominal,
                global_relaxation = s.by_layer.global_relaxation,
                fallback = s.by_layer.fallback,
                watchdog_fallback = s.by_layer.watchdog_fallback,
                rejected = s.by_layer.rejected,
                overloaded = s.overloaded,
                p50_us = s.latency.p50_us,
                p99_us = s.latency.p99_us,
                max_us = s.latency.max_us,
                "planner stats"
            );
        }
    }
}
