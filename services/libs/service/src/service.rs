//! The transport-free core of `planner serve`: a worker pool with a bounded queue, a deadline
//! watchdog, statistics.
//!
//! * [`Service::handle_bytes`] / [`Service::submit`] take a request and a reply callback; the
//!   callback is called **exactly once** (by a worker, by the watchdog, or at once for
//!   malformed input, rejected input and overload), never blocks the caller.
//! * Requests wait in a [`FairQueue`] (round-robin across vehicle ids, a share per vehicle)
//!   behind a per-vehicle [`RateLimiter`]: one vehicle that floods cannot starve the others.
//! * Each worker thread owns a [`decision::Planner`] (not `Send`: built on its thread).
//! * The watchdog thread answers `decision::fallback_only` marked
//!   [`protocol::Layer::WatchdogFallback`] when a deadline runs out, interrupts the running HiGHS solve
//!   and makes the worker discard its late result. It runs at a real-time priority when
//!   permitted and computes the fallback ahead of the deadline (`service/watchdog.rs`).
//! * A request already older than its deadline by its `sent_at_ns`, on arrival or when a
//!   worker takes it, gets the fallback marked [`protocol::Layer::StaleFallback`], unsolved.
//! * With a signing key every answer is signed on its way out ([`protocol::ResponseSigner`]).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use decision::{DecisionError, InterruptHandle, Planner, PlannerConfig};
use protocol::{
    unix_now_ns, InvalidRequest, Layer, PlanRequest, PlanResponse, ResponseSigner, ValidRequest, WireFormat,
    DEFAULT_DEADLINE,
};

use crate::fair_queue::{FairQueue, RateLimit, RateLimiter};

mod statistics;
mod watchdog;
use statistics::Counters;
pub use statistics::{Stats, StatsSnapshot};

/// Default queue places per worker. Solves take about a millisecond (p99 ~2 ms), so a full
/// queue still drains well inside the 400 ms deadline, while bursts of simultaneous requests
/// (many vehicles, Zenoh delivering in batches) are solved instead of answered by the
/// overload fallback. A request that waits too long still gets the watchdog's answer on time.
pub const QUEUE_PER_WORKER: usize = 32;

/// Default queue places one vehicle may hold: a vehicle asks once per 0.4 s and waits for
/// the answer, so more than a few queued requests of one id are a flood.
pub const QUEUE_PER_VEHICLE: usize = 8;

/// Default nice value of the worker threads (see [`ServiceConfig::worker_nice`]): 0, the
/// process's own. Measured under a flood (docs/hostile-peers.md), 10 did not make
/// the watchdog's answers earlier on a machine shared with the vehicles, and it starved the
/// solves of CPU there.
pub const WORKER_NICE: i32 = 0;

/// Default SCHED_FIFO priority of the watchdog thread (see
/// [`ServiceConfig::watchdog_rt_priority`]): low among real-time priorities (1..=99), above
/// every ordinary thread, below the kernel's own real-time threads.
pub const WATCHDOG_RT_PRIORITY: i32 = 10;

/// Settings of the service core.
#[derive(Debug, Clone)]
pub struct ServiceConfig {
    /// Worker threads, each with its own planner.
    pub workers: usize,
    /// Requests that may wait for a worker; beyond that the fallback answers at once.
    pub queue_capacity: usize,
    /// Queue places one vehicle id may hold; beyond that its requests get the fallback at once.
    pub per_vehicle_queue: usize,
    /// Requests per second (and burst) one vehicle id may send; beyond that the fallback
    /// answers at once. `None`: no limit.
    pub rate_limit: Option<RateLimit>,
    /// Upper bound of every deadline (a request may ask for a shorter one).
    pub max_deadline: Duration,
    /// A request older than its deadline plus this (by its `sent_at_ns` against this
    /// host's clock) is answered as stale.
    pub clock_skew_tolerance: Duration,
    /// Signs every answer; `None`: answers are unsigned.
    pub signer: Option<ResponseSigner>,
    /// Nice value of the worker threads (0: the process's own); above 0 the watchdog and the
    /// transports take the CPU before a solve does.
    pub worker_nice: i32,
    /// SCHED_FIFO priority of the watchdog thread (`None`: an ordinary thread). At a real-time
    /// priority it answers a deadline as soon as it wakes, instead of waiting for a core
    /// behind the solver threads, the transports and other processes; where the process may
    /// not (no CAP_SYS_NICE, RLIMIT_RTPRIO too low) it stays ordinary, with a warning.
    pub watchdog_rt_priority: Option<i32>,
    /// TEST ONLY: sleep this long before every solve, to force the watchdog.
    pub inject_solve_delay: Duration,
    /// See every decoded request (not the readiness probes) and its answer: the recorder
    /// (`planner serve --record`), the live view (`--foxglove`). Called on the answer path;
    /// each returns at once (recording::PlanObserver).
    pub observers: recording::Observers,
}

impl Default for ServiceConfig {
    fn default() -> Self {
        let workers = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
        Self {
            workers,
            queue_capacity: QUEUE_PER_WORKER * workers,
            per_vehicle_queue: QUEUE_PER_VEHICLE,
            // Off by default: simulations ask faster than real time (docs/service.md).
            rate_limit: None,
            max_deadline: DEFAULT_DEADLINE,
            clock_skew_tolerance: protocol::DEFAULT_CLOCK_SKEW_TOLERANCE,
            signer: None,
            worker_nice: WORKER_NICE,
            watchdog_rt_priority: Some(WATCHDOG_RT_PRIORITY),
            inject_solve_delay: Duration::ZERO,
            observers: recording::Observers::default(),
        }
    }
}

/// Why the service could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServiceError {
    /// A worker could not build its planner (an invalid configuration, HiGHS).
    #[error("a worker could not build its planner")]
    Planner(#[source] DecisionError),
    /// A worker thread ended while starting.
    #[error("a worker died while starting")]
    WorkerDied,
    /// A thread could not be spawned.
    #[error("spawning a service thread")]
    Spawn(#[from] std::io::Error),
}

/// The reply callback of one request.
pub type Reply = Box<dyn FnOnce(PlanResponse) + Send>;

fn micros(d: Duration) -> u32 {
    u32::try_from(d.as_micros()).unwrap_or(u32::MAX)
}

/// What the worker, the watchdog and the submitter share about one request.
struct JobState {
    request: ValidRequest,
    arrival: Instant,
    deadline: Instant,
    /// The deadline as a duration (what staleness is measured against).
    allowed: Duration,
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

    fn vehicle_id(&self) -> u64 {
        self.request.request().vehicle_id
    }

    fn sequence(&self) -> u64 {
        self.request.request().sequence
    }

    /// Older than its deadline by its send time, now.
    fn is_stale(&self, tolerance: Duration) -> bool {
        self.request
            .request()
            .is_stale_at(unix_now_ns(), self.allowed, tolerance)
    }

    /// Answers with the fallback marked `layer`, if nobody answered yet, computed now; see
    /// [`JobState::answer_fallback_with`].
    fn answer_fallback(
        &self,
        config: &PlannerConfig,
        stats: &Stats,
        layer: Layer,
        count: Option<fn(&mut Counters)>,
    ) -> bool {
        self.answer_fallback_with(stats, || protocol::fallback_answer(config, &self.request, layer), count)
    }

    /// Answers with the fallback `fallback` gives (computed only if the job is still
    /// unanswered: the watchdog may hold one computed ahead), its queue time set now,
    /// counted with `count` before it leaves (a client that reads the statistics once it
    /// has its answer finds it counted); whether it was this answer.
    fn answer_fallback_with(
        &self,
        stats: &Stats,
        fallback: impl FnOnce() -> PlanResponse,
        count: Option<fn(&mut Counters)>,
    ) -> bool {
        let Some(reply) = self.take_reply() else {
            return false;
        };
        let mut response = fallback();
        response.queue_us = micros(self.arrival.elapsed());
        stats.record_answer(&response, self.arrival);
        if let Some(count) = count {
            count(&mut stats.lock().counters);
        }
        reply(response);
        true
    }

    /// Someone (a worker, the watchdog, the stale path) has answered.
    fn answered(&self) -> bool {
        self.reply.lock().unwrap_or_else(|e| e.into_inner()).is_none()
    }
}

/// The requests waiting for a worker, shared by the submitters and the workers.
struct WorkQueue {
    state: Mutex<QueueState>,
    /// Signalled when a job is queued or the queue closes.
    ready: Condvar,
}

struct QueueState {
    jobs: FairQueue<Arc<JobState>>,
    /// No more jobs come; workers drain what is queued and stop.
    closed: bool,
}

impl WorkQueue {
    fn lock(&self) -> std::sync::MutexGuard<'_, QueueState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The next job, waiting for one; `None` once closed and drained.
    fn next(&self) -> Option<Arc<JobState>> {
        let mut state = self.lock();
        loop {
            if let Some(job) = state.jobs.pop() {
                return Some(job);
            }
            if state.closed {
                return None;
            }
            state = self.ready.wait(state).unwrap_or_else(|e| e.into_inner());
        }
    }

    fn close(&self) {
        self.lock().closed = true;
        self.ready.notify_all();
    }
}

/// The service core. Dropping it (or [`Service::shutdown`]) stops the threads.
pub struct Service {
    planner_config: Arc<PlannerConfig>,
    config: ServiceConfig,
    queue: Arc<WorkQueue>,
    limiter: Option<Mutex<RateLimiter>>,
    watchdog: Option<Arc<watchdog::Inbox>>,
    stats: Arc<Stats>,
    threads: Vec<JoinHandle<()>>,
}

impl Service {
    /// Starts the workers (each builds its planner; fails if one cannot) and the watchdog.
    pub fn start(planner_config: PlannerConfig, config: ServiceConfig) -> Result<Self, ServiceError> {
        let planner_config = Arc::new(planner_config);
        let stats = Arc::new(Stats::new());
        let workers = config.workers.max(1);
        let queue = Arc::new(WorkQueue {
            state: Mutex::new(QueueState {
                jobs: FairQueue::new(config.queue_capacity, config.per_vehicle_queue),
                closed: false,
            }),
            ready: Condvar::new(),
        });
        let mut threads = Vec::new();
        let (ready_tx, ready_rx) = mpsc::channel::<Result<(), DecisionError>>();
        for i in 0..workers {
            let rx = Arc::clone(&queue);
            let cfg = Arc::clone(&planner_config);
            let stats = Arc::clone(&stats);
            let ready = ready_tx.clone();
            let delay = config.inject_solve_delay;
            let tolerance = config.clock_skew_tolerance;
            let nice = config.worker_nice;
            threads.push(
                std::thread::Builder::new()
                    .name(format!("planner-worker-{i}"))
                    .spawn(move || {
                        if nice != 0 {
                            if let Err(e) = supervise::set_thread_nice(nice) {
                                tracing::warn!("worker thread priority (nice {nice}): {e}");
                            }
                        }
                        worker(&cfg, &rx, &stats, (delay, tolerance), &ready)
                    })?,
            );
        }
        drop(ready_tx);
        for _ in 0..workers {
            match ready_rx.recv() {
                Ok(Ok(())) => {}
                Ok(Err(e)) => return Err(ServiceError::Planner(e)),
                Err(_) => return Err(ServiceError::WorkerDied),
            }
        }
        let inbox = Arc::new(watchdog::Inbox::new());
        {
            let cfg = Arc::clone(&planner_config);
            let stats = Arc::clone(&stats);
            let priority = config.watchdog_rt_priority;
            let inbox = Arc::clone(&inbox);
            threads.push(
                std::thread::Builder::new()
                    .name("planner-watchdog".into())
                    .spawn(move || {
                        if let Some(priority) = priority {
                            match supervise::set_thread_realtime(priority) {
                                Ok(()) => tracing::debug!(priority, "watchdog thread at SCHED_FIFO"),
                                Err(e) => tracing::warn!("watchdog thread stays an ordinary thread: {e}"),
                            }
                        }
                        watchdog::run(&cfg, &inbox, &stats)
                    })?,
            );
        }
        Ok(Self {
            planner_config,
            limiter: config.rate_limit.map(|limit| Mutex::new(RateLimiter::new(limit))),
            config,
            queue,
            watchdog: Some(inbox),
            stats,
            threads,
        })
    }

    /// The public key of the service's signing key, if it signs.
    pub fn verifier(&self) -> Option<protocol::ResponseVerifier> {
        self.config.signer.as_ref().map(ResponseSigner::verifier)
    }

    /// The statistics (shared; read [`Stats::snapshot`]).
    pub fn stats(&self) -> Arc<Stats> {
        Arc::clone(&self.stats)
    }

    /// Decodes `bytes` and submits the request; undecodable bytes are answered at once with a
    /// `malformed` / `unsupported_version` / `capacity_exceeded` rejection (the empty message,
    /// a readiness probe, is not counted as one).
    pub fn handle_bytes(&self, bytes: &[u8], format: WireFormat, arrival: Instant, reply: Reply) {
        match format.decode_request(bytes) {
            Ok(request) => self.submit(request, arrival, reply),
            Err((rejected, (vehicle_id, sequence), e)) => {
                tracing::debug!(error = %e, "undecodable request");
                let invalid = InvalidRequest {
                    vehicle_id,
                    sequence,
                    rejected,
                };
                self.refuse(invalid, arrival, bytes.is_empty(), reply);
            }
        }
    }

    /// Answers a request a front end could not turn into a [`PlanRequest`] with its
    /// rejection, at once (`probe`: a readiness probe, not counted as a rejection).
    pub fn refuse(&self, invalid: InvalidRequest, arrival: Instant, probe: bool, reply: Reply) {
        let mut response = invalid.response();
        response.queue_us = micros(arrival.elapsed());
        self.answer_now(response, arrival, probe, self.signed(reply));
    }

    /// `reply`, signing the response first when the service has a key.
    fn signed(&self, reply: Reply) -> Reply {
        match &self.config.signer {
            Some(signer) => {
                let signer = signer.clone();
                Box::new(move |mut response| {
                    signer.sign(&mut response);
                    reply(response);
                })
            }
            None => reply,
        }
    }

    /// Submits a decoded request. The reply is called exactly once.
    pub fn submit(&self, request: PlanRequest, arrival: Instant, reply: Reply) {
        let probe = request.is_probe();
        let reply: Reply = if probe || self.config.observers.is_empty() {
            reply
        } else {
            self.config.observers.wrap_reply(&request, arrival, reply)
        };
        // Signed before the observers see it: the recording holds what was sent.
        let reply = self.signed(reply);
        // Every check, once; a probe fails the first (its version).
        let request = match request.validate(&self.planner_config) {
            Ok(request) => request,
            Err(invalid) => {
                let mut response = invalid.response();
                response.queue_us = micros(arrival.elapsed());
                self.answer_now(response, arrival, probe, reply);
                return;
            }
        };
        let allowed = request.request().deadline().min(self.config.max_deadline);
        let job = Arc::new(JobState {
            request,
            arrival,
            deadline: arrival + allowed,
            allowed,
            reply: Mutex::new(Some(reply)),
            abandoned: AtomicBool::new(false),
            solving: Mutex::new(None),
        });
        // Before the rate limit and the queue: an old scene costs neither a solve nor a place.
        if job.is_stale(self.config.clock_skew_tolerance) {
            tracing::debug!(
                vehicle = job.vehicle_id(),
                sequence = job.sequence(),
                "stale on arrival"
            );
            job.answer_fallback(&self.planner_config, &self.stats, Layer::StaleFallback, None);
            return;
        }
        let vehicle = job.vehicle_id();
        if let Some(limiter) = &self.limiter {
            if !limiter
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .allow(vehicle, arrival)
            {
                let count: fn(&mut Counters) = |c| c.rate_limited += 1;
                job.answer_fallback(&self.planner_config, &self.stats, Layer::WatchdogFallback, Some(count));
                return;
            }
        }
        let queued = {
            let mut state = self.queue.lock();
            !state.closed && state.jobs.push(vehicle, Arc::clone(&job)).is_ok()
        };
        if queued {
            // The watchdog first: waking a worker may hand it this core (wake-up preemption)
            // for a whole solve, and the watchdog must know the deadline before that (it is
            // woken only if it would otherwise wake too late for this request).
            if let Some(wd) = &self.watchdog {
                wd.send(Arc::clone(&job));
            }
            self.queue.ready.notify_one();
        } else {
            job.abandoned.store(true, Ordering::SeqCst);
            let count: fn(&mut Counters) = |c| c.overloaded += 1;
            job.answer_fallback(&self.planner_config, &self.stats, Layer::WatchdogFallback, Some(count));
        }
    }

    /// Answers at once, counting the answer unless it answers a probe.
    fn answer_now(&self, response: PlanResponse, arrival: Instant, probe: bool, reply: Reply) {
        if probe {
            self.stats.lock().counters.probes += 1;
        } else {
            self.stats.record_answer(&response, arrival);
        }
        reply(response);
    }

    /// Stops accepting work and joins the threads (queued jobs are still answered).
    pub fn shutdown(&mut self) {
        self.queue.close();
        if let Some(inbox) = self.watchdog.take() {
            inbox.close();
        }
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

/// `(inject_delay, clock_skew_tolerance)`: see [`ServiceConfig`].
fn worker(
    config: &PlannerConfig,
    queue: &WorkQueue,
    stats: &Stats,
    (inject_delay, tolerance): (Duration, Duration),
    ready: &mpsc::Sender<Result<(), DecisionError>>,
) {
    let mut planner = match Planner::new(config.clone()) {
        Ok(p) => {
            let _ = ready.send(Ok(()));
            p
        }
        Err(e) => {
            let _ = ready.send(Err(e));
            return;
        }
    };
    let handle = planner.interrupt_handle();
    let mut last_trim = Instant::now();
    loop {
        let Some(job) = queue.next() else { return };
        // At most once a second: RSS follows what is live (a model larger than any before
        // grows HiGHS's buffers; they are freed, but glibc keeps the pages).
        if last_trim.elapsed() >= Duration::from_secs(1) {
            supervise::release_free_memory();
            last_trim = Instant::now();
        }
        if job.abandoned.load(Ordering::SeqCst) {
            continue;
        }
        // The request may have become stale while it waited in the queue.
        if job.is_stale(tolerance) {
            let count: fn(&mut Counters) = |c| c.stale_in_queue += 1;
            job.answer_fallback(config, stats, Layer::StaleFallback, Some(count));
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
        let mut response = protocol::answer(&mut planner, &job.request);
        response.queue_us = queue_us;
        *job.solving.lock().unwrap_or_else(|e| e.into_inner()) = None;
        stats.record_solve(started.elapsed());
        match job.take_reply() {
            Some(reply) => {
                stats.record_answer(&response, job.arrival);
                reply(response);
            }
            None => stats.lock().counters.late_discarded += 1,
        }
    }
}
