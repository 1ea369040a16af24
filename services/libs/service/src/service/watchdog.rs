//! The deadline watchdog: answers the fallback marked [`Layer::WatchdogFallback`] for every
//! queued request still unanswered at its deadline, and interrupts its solve.
//!
//! What makes its answers late, and what it does against each (docs/hostile-peers.md, "The
//! watchdog under a flood"):
//! * waiting for a core behind the solver threads and the transports when it wakes: it can
//!   run in the SCHED_FIFO class ([`ServiceConfig::watchdog_rt_priority`]);
//! * computing the fallback at the deadline, once per expired request, the last of a burst
//!   late by the sum: it computes each request's fallback while it waits (between deadlines,
//!   one at a time), so that at the deadline it only sends.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use decision::PlannerConfig;
use protocol::{Layer, PlanResponse};

use super::{JobState, Stats};

/// How long the watchdog sleeps with nothing to wait for. Short enough that a request
/// with an ordinary deadline (0.4 s) arrives while the watchdog will wake before that
/// request's fallback is due, so handing it over wakes nobody ([`Inbox::send`]).
const IDLE: Duration = Duration::from_millis(100);

/// How long before its deadline the watchdog computes a request's fallback: long enough for
/// a burst of deadlines (a fallback takes about 60 us), short enough that most requests are
/// solved before and cost no fallback (at a real-time priority, each one takes a core from
/// the solver threads).
pub(super) const PREPARE_LEAD: Duration = Duration::from_millis(2);

/// Where the submitters hand requests to the watchdog. A mutex and a condition variable, not
/// a channel: std's channel receiver spins (yielding) while a sender is halfway through a
/// send, and a real-time receiver that spins keeps a preempted ordinary sender off the core.
/// A request is left for the watchdog to collect when it wakes anyway before it would act on
/// that request: waking a real-time thread on every request takes a core from the request's
/// own path (the front's thread, the worker) on a small machine.
pub(super) struct Inbox {
    state: Mutex<InboxState>,
    arrived: Condvar,
}

#[derive(Default)]
struct InboxState {
    jobs: Vec<Arc<JobState>>,
    /// No more requests come.
    closed: bool,
    /// While the watchdog sleeps: when it wakes at the latest.
    sleeping_until: Option<Instant>,
}

impl Inbox {
    pub(super) fn new() -> Self {
        Self {
            state: Mutex::new(InboxState::default()),
            arrived: Condvar::new(),
        }
    }

    pub(super) fn send(&self, job: Arc<JobState>) {
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let wake = needs_wake(state.sleeping_until, job.deadline);
        state.jobs.push(job);
        drop(state);
        if wake {
            self.arrived.notify_one();
        }
    }

    /// The watchdog answers what it holds and stops.
    pub(super) fn close(&self) {
        self.state.lock().unwrap_or_else(|e| e.into_inner()).closed = true;
        self.arrived.notify_one();
    }

    /// Moves what arrived into `into`, first waiting up to `wait` for something when nothing
    /// is there; whether more may come.
    fn receive(&self, wait: Duration, into: &mut Vec<Arc<JobState>>) -> bool {
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        if state.jobs.is_empty() && !state.closed && !wait.is_zero() {
            state.sleeping_until = Some(Instant::now() + wait);
            state = self
                .arrived
                .wait_timeout(state, wait)
                .unwrap_or_else(|e| e.into_inner())
                .0;
            state.sleeping_until = None;
        }
        into.append(&mut state.jobs);
        !state.closed
    }
}

/// Whether a request due at `deadline` must wake the watchdog, asleep until `sleeping_until`
/// (`None`: awake, it looks into the inbox before it sleeps again): only if it would wake too
/// late to prepare the request's fallback.
fn needs_wake(sleeping_until: Option<Instant>, deadline: Instant) -> bool {
    let prepare_at = deadline.checked_sub(PREPARE_LEAD).unwrap_or(deadline);
    sleeping_until.is_some_and(|until| prepare_at < until)
}

/// A request the watchdog waits on, and its fallback once computed.
struct Waiting {
    job: Arc<JobState>,
    fallback: Option<PlanResponse>,
}

/// What the watchdog does next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Step {
    /// Answer the requests whose deadline has come.
    Answer,
    /// Compute one waiting request's fallback now (the earliest deadline is later).
    Prepare,
    /// Sleep until a request arrives or this long passes.
    Wait(Duration),
}

/// The next [`Step`] at `now`, given the earliest deadline waited on and the earliest
/// deadline of a request whose fallback is not computed yet. A fallback is computed
/// [`PREPARE_LEAD`] before its deadline, only while no deadline has come and one at a time, so
/// that a deadline waits for at most one fallback computation.
pub(super) fn next_step(now: Instant, earliest: Option<Instant>, unprepared: Option<Instant>) -> Step {
    let prepare_at = unprepared.map(|deadline| deadline.checked_sub(PREPARE_LEAD).unwrap_or(deadline));
    match (earliest, prepare_at) {
        (Some(deadline), _) if deadline <= now => Step::Answer,
        (_, Some(at)) if at <= now => Step::Prepare,
        (Some(deadline), at) => Step::Wait(
            at.map_or(deadline, |at| at.min(deadline))
                .saturating_duration_since(now),
        ),
        (None, Some(at)) => Step::Wait(at.saturating_duration_since(now)),
        (None, None) => Step::Wait(IDLE),
    }
}

/// The requests the watchdog waits on.
#[derive(Default)]
struct Pending {
    /// Min-heap of deadlines; the sequence number breaks ties.
    deadlines: BinaryHeap<Reverse<(Instant, u64)>>,
    /// The same requests by deadline while their fallback is not computed yet (entries of
    /// requests answered meanwhile find nothing in `waiting` when they come up).
    unprepared: BinaryHeap<Reverse<(Instant, u64)>>,
    waiting: HashMap<u64, Waiting>,
    next_id: u64,
}

impl Pending {
    fn add(&mut self, job: Arc<JobState>) {
        let (deadline, id) = (job.deadline, self.next_id);
        self.next_id += 1;
        self.deadlines.push(Reverse((deadline, id)));
        self.unprepared.push(Reverse((deadline, id)));
        self.waiting.insert(id, Waiting { job, fallback: None });
    }

    fn earliest(heap: &BinaryHeap<Reverse<(Instant, u64)>>) -> Option<Instant> {
        heap.peek().map(|Reverse((deadline, _))| *deadline)
    }
}

pub(super) fn run(config: &PlannerConfig, inbox: &Inbox, stats: &Stats) {
    let mut p = Pending::default();
    let mut arrived = Vec::new();
    let mut last_log = Instant::now();
    let mut open = true;
    while open || !p.deadlines.is_empty() {
        // Everything that arrived, without blocking: its deadline may be the earliest.
        if open {
            open = inbox.receive(Duration::ZERO, &mut arrived);
            arrived.drain(..).for_each(|job| p.add(job));
        }
        let (earliest, unprepared) = (Pending::earliest(&p.deadlines), Pending::earliest(&p.unprepared));
        match next_step(Instant::now(), earliest, unprepared) {
            Step::Answer => {
                let now = Instant::now();
                while let Some(Reverse((deadline, id))) = p.deadlines.peek().copied() {
                    if deadline > now {
                        break;
                    }
                    p.deadlines.pop();
                    if let Some(w) = p.waiting.remove(&id) {
                        expire(config, w, stats);
                    }
                }
            }
            Step::Prepare => {
                let Some(Reverse((_, id))) = p.unprepared.pop() else {
                    continue;
                };
                // Skipped when a worker has answered already.
                if let Some(w) = p.waiting.get_mut(&id) {
                    if !w.job.answered() {
                        w.fallback = Some(protocol::fallback_answer(
                            config,
                            &w.job.request,
                            Layer::WatchdogFallback,
                        ));
                    }
                }
            }
            Step::Wait(timeout) if open => {
                open = inbox.receive(timeout, &mut arrived);
                arrived.drain(..).for_each(|job| p.add(job));
            }
            Step::Wait(timeout) => std::thread::sleep(timeout),
        }
        if last_log.elapsed() >= Duration::from_secs(10) {
            last_log = Instant::now();
            log_stats(stats);
        }
    }
}

/// The deadline of `w` has come: interrupts its solve and answers the fallback, unless a
/// worker answered first.
fn expire(config: &PlannerConfig, w: Waiting, stats: &Stats) {
    let job = &w.job;
    if job.answered() {
        return;
    }
    job.abandoned.store(true, Ordering::SeqCst);
    if let Some((handle, first_id)) = job.solving.lock().unwrap_or_else(|e| e.into_inner()).clone() {
        match handle.running() {
            Some(id) if id >= first_id => handle.interrupt(id),
            _ => handle.interrupt(first_id),
        }
    }
    let prepared = w.fallback;
    let fallback =
        || prepared.unwrap_or_else(|| protocol::fallback_answer(config, &job.request, Layer::WatchdogFallback));
    if !job.answer_fallback_with(stats, fallback, None) {
        return;
    }
    tracing::debug!(
        vehicle = job.vehicle_id(),
        sequence = job.sequence(),
        "deadline ran out: watchdog fallback"
    );
}

fn log_stats(stats: &Stats) {
    let s = stats.snapshot();
    tracing::info!(
        answered = s.answered,
        nominal = s.by_layer.nominal,
        global_relaxation = s.by_layer.global_relaxation,
        fallback = s.by_layer.fallback,
        watchdog_fallback = s.by_layer.watchdog_fallback,
        stale_fallback = s.by_layer.stale_fallback,
        rejected = s.by_layer.rejected,
        overloaded = s.overloaded,
        p50_us = s.latency.p50_us,
        p99_us = s.latency.p99_us,
        max_us = s.latency.max_us,
        "planner stats"
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_first_then_prepares_then_waits() {
        let now = Instant::now();
        let ms = Duration::from_millis;
        // A deadline that has come goes before any fallback left to compute.
        assert_eq!(next_step(now, Some(now), Some(now)), Step::Answer);
        assert_eq!(next_step(now, Some(now - ms(1)), None), Step::Answer);
        // Within the lead of its deadline a fallback is computed ahead of time ...
        assert_eq!(next_step(now, Some(now + ms(1)), Some(now + ms(1))), Step::Prepare);
        assert_eq!(
            next_step(now, Some(now + ms(1)), Some(now + PREPARE_LEAD)),
            Step::Prepare
        );
        // ... before it, the watchdog sleeps until the lead or the deadline, whichever first.
        assert_eq!(
            next_step(now, Some(now + ms(50)), Some(now + ms(50))),
            Step::Wait(ms(50) - PREPARE_LEAD)
        );
        assert_eq!(
            next_step(now, Some(now + ms(5)), Some(now + ms(400))),
            Step::Wait(ms(5))
        );
        assert_eq!(next_step(now, Some(now + ms(5)), None), Step::Wait(ms(5)));
        assert_eq!(next_step(now, None, None), Step::Wait(IDLE));
    }

    #[test]
    fn wakes_the_watchdog_only_when_it_would_be_late() {
        let now = Instant::now();
        let ms = Duration::from_millis;
        // Awake: it collects the request before it sleeps again.
        assert!(!needs_wake(None, now + ms(1)));
        // Asleep for the idle period: a request due in 0.4 s waits for it, one due sooner
        // than the period (plus the lead) wakes it.
        assert!(!needs_wake(Some(now + IDLE), now + ms(400)));
        assert!(needs_wake(Some(now + IDLE), now + IDLE));
        assert!(needs_wake(Some(now + IDLE), now + ms(50)));
        // Asleep until an earlier request's fallback is due: only an earlier one wakes it.
        assert!(!needs_wake(Some(now + ms(398)), now + ms(401)));
        assert!(needs_wake(Some(now + ms(398)), now + ms(399)));
    }
}
