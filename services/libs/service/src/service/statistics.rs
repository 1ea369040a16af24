//! The service's statistics: answers by layer, the service's own counters and the latency
//! histograms, shared by every thread behind one lock.

use std::sync::Mutex;
use std::time::{Duration, Instant};

use hdrhistogram::Histogram;
use protocol::PlanResponse;
use serde::Serialize;
use stats::{LayerCounts, Percentiles};

/// Counters of the service apart from the answers by layer.
#[derive(Default, Clone, Copy)]
pub(super) struct Counters {
    pub(super) probes: u64,
    pub(super) overloaded: u64,
    pub(super) rate_limited: u64,
    pub(super) stale_in_queue: u64,
    pub(super) late_discarded: u64,
    pub(super) forwarded: u64,
    pub(super) taken_back: u64,
}

pub(super) struct StatsInner {
    pub(super) by_layer: LayerCounts,
    pub(super) counters: Counters,
    /// Arrival to answer, µs.
    pub(super) latency: Histogram<u64>,
    /// Worker decision time, µs.
    pub(super) solve: Histogram<u64>,
}

/// Statistics of the service, shared by every thread.
pub struct Stats {
    started: Instant,
    inner: Mutex<StatsInner>,
}

/// The JSON statistics document (published on `hmdp/planner/stats`).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct StatsSnapshot {
    pub uptime_s: f64,
    /// Answers to requests (probes excluded).
    pub answered: u64,
    pub by_layer: LayerCounts,
    /// Readiness probes answered (not counted in `answered` nor as rejections).
    pub probes: u64,
    /// Fallback answers given because the queue, or the vehicle's share of it, was full
    /// (also counted in `watchdog_fallback`).
    pub overloaded: u64,
    /// Fallback answers given because the vehicle exceeded its rate limit (also counted in
    /// `watchdog_fallback`).
    pub rate_limited: u64,
    /// Of the `stale_fallback` answers, those given when a worker took a request that had
    /// become stale in the queue (the others: stale on arrival).
    pub stale_in_queue: u64,
    /// Worker results that arrived after the watchdog had answered.
    pub late_discarded: u64,
    /// Plain-key requests sent on to the instance that serves their vehicle, its answer
    /// relayed (not counted in `answered`: that instance counts it).
    pub forwarded: u64,
    /// Forwarded requests that instance left unanswered for the retry time: served here
    /// (counted in `answered` too).
    pub taken_back: u64,
    /// Arrival to answer.
    pub latency: Percentiles,
    /// Worker decision time (excludes queueing).
    pub solve: Percentiles,
}

impl Stats {
    pub(super) fn new() -> Self {
        Self {
            started: Instant::now(),
            inner: Mutex::new(StatsInner {
                by_layer: LayerCounts::default(),
                counters: Counters::default(),
                latency: stats::histogram(),
                solve: stats::histogram(),
            }),
        }
    }

    pub(super) fn lock(&self) -> std::sync::MutexGuard<'_, StatsInner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub(super) fn record_answer(&self, response: &PlanResponse, arrival: Instant) {
        let mut s = self.lock();
        s.by_layer.add_response(response);
        stats::record(&mut s.latency, arrival.elapsed());
    }

    /// A plain-key request forwarded to another instance: relayed, or `taken_back`.
    pub fn count_forward(&self, taken_back: bool) {
        let mut s = self.lock();
        if taken_back {
            s.counters.taken_back += 1;
        } else {
            s.counters.forwarded += 1;
        }
    }

    pub(super) fn record_solve(&self, took: Duration) {
        stats::record(&mut self.lock().solve, took);
    }

    /// The current statistics. The histograms are copied under the lock and read outside
    /// it: reading percentiles walks every bucket, and the watchdog, at a real-time priority,
    /// must not wait that long (nor for a preempted reader) to count its answer.
    pub fn snapshot(&self) -> StatsSnapshot {
        let (by_layer, c, latency, solve) = {
            let s = self.lock();
            (s.by_layer, s.counters, s.latency.clone(), s.solve.clone())
        };
        StatsSnapshot {
            uptime_s: self.started.elapsed().as_secs_f64(),
            answered: by_layer.total(),
            by_layer,
            probes: c.probes,
            overloaded: c.overloaded,
            rate_limited: c.rate_limited,
            stale_in_queue: c.stale_in_queue,
            late_discarded: c.late_discarded,
            forwarded: c.forwarded,
            taken_back: c.taken_back,
            latency: Percentiles::of_histogram(&latency),
            solve: Percentiles::of_histogram(&solve),
        }
    }
}
