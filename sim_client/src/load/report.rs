//! What a load run reports: per-process parts that merge exactly, and the merged report.

use hdrhistogram::Histogram;
use serde::{Deserialize, Serialize};
use stats::{LayerCounts, Percentiles};

use super::procmon::ProcessReport;
use super::LoadSettings;

/// A histogram as (value, count) pairs: exact to merge across processes.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct HistogramData(pub Vec<(u64, u64)>);

impl HistogramData {
    /// The recorded values of `h`.
    pub fn of(h: &Histogram<u64>) -> Self {
        Self(
            h.iter_recorded()
                .map(|v| (v.value_iterated_to(), v.count_at_value()))
                .collect(),
        )
    }

    /// Records these values into `h`.
    pub fn add_to(&self, h: &mut Histogram<u64>) {
        for &(value, count) in &self.0 {
            h.saturating_record_n(value, count);
        }
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
    /// Answers refused because they did not verify with the planner's key (`--planner-key`):
    /// forged, altered or unsigned. Absent in reports written before signed answers.
    #[serde(default)]
    pub refused: u64,
    /// Requests sent again to another planner instance after 150 ms without an answer
    /// (Zenoh, several instances; docs/deploy.md, "Scaling out"). Not a violation.
    #[serde(default)]
    pub retried: u64,
    /// Answers the channel received for another request (another vehicle id or sequence;
    /// over iceoryx2 also tagged for another client or exchange) and discarded, never
    /// taken: 0 with a correct planner.
    #[serde(default)]
    pub discarded: u64,
}

impl Counts {
    /// Adds another tally.
    pub fn add(&mut self, o: &Counts) {
        self.sent += o.sent;
        self.in_time += o.in_time;
        self.late += o.late;
        self.lost += o.lost;
        self.duplicated += o.duplicated;
        self.mismatched += o.mismatched;
        self.refused += o.refused;
        self.retried += o.retried;
        self.discarded += o.discarded;
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
pub fn add_timeline(into: &mut Vec<TimelinePoint>, from: &[TimelinePoint]) {
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
    /// Watchdog answers at the deadline: the planner's answer time minus the deadline, µs.
    #[serde(default)]
    pub watchdog_late_planner: HistogramData,
    /// The same answers as received: round trip minus the deadline asked for, µs.
    #[serde(default)]
    pub watchdog_late_received: HistogramData,
    /// Per sample period.
    pub timeline: Vec<TimelinePoint>,
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
    /// Watchdog answers given at the deadline (not at once for overload or the rate limit):
    /// the planner's answer time minus the deadline (the answer's `queue_us`).
    #[serde(default)]
    pub watchdog_late_planner: Percentiles,
    /// The same answers as the vehicles received them: round trip minus the deadline the
    /// request asked for (the transport both ways included).
    #[serde(default)]
    pub watchdog_late_received: Percentiles,
    /// The flood beside the vehicles (`--flood-sessions`), if any.
    #[serde(default)]
    pub flood: Option<super::flood::FloodReport>,
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
        let [mut rt, mut q, mut s, mut tr, mut wp, mut wr] = [(); 6].map(|_| stats::histogram());
        let mut timeline: Vec<TimelinePoint> = Vec::new();
        let mut elapsed: f64 = 0.0;
        let mut clients = 0;
        for p in parts {
            clients += p.clients;
            counts.add(&p.counts);
            by_layer.merge(&p.by_layer);
            p.round_trip.add_to(&mut rt);
            p.queue.add_to(&mut q);
            p.solve.add_to(&mut s);
            p.transport.add_to(&mut tr);
            p.watchdog_late_planner.add_to(&mut wp);
            p.watchdog_late_received.add_to(&mut wr);
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
            round_trip: Percentiles::of_histogram(&rt),
            queue: Percentiles::of_histogram(&q),
            solve: Percentiles::of_histogram(&s),
            transport_overhead: Percentiles::of_histogram(&tr),
            watchdog_late_planner: Percentiles::of_histogram(&wp),
            watchdog_late_received: Percentiles::of_histogram(&wr),
            flood: None,
            round_trip_spectrum: spectrum(&rt),
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
            (c.refused, "refused (signature)"),
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
                    "planner RSS grew {:.1} % after the warm-up (median {} -> {} KiB)",
                    p.rss_growth_percent, p.rss_after_warmup_kib, p.rss_end_kib
                ));
            }
        }
        v
    }

    /// The report as text, as the command prints it.
    pub fn summary(&self) -> String {
        let c = &self.counts;
        let l = &self.by_layer;
        let mut out = format!(
            "{}: {} vehicles x {} Hz for {:.1} s: sent {}, in time {}, late {}, lost {}, duplicated {}, mismatched {}, discarded {}, refused {}, retried {}; {:.1} decisions/s in time\n",
            self.transport, self.clients, self.rate_hz, self.duration_s, c.sent, c.in_time, c.late, c.lost, c.duplicated, c.mismatched, c.discarded, c.refused, c.retried, self.throughput_per_s
        );
        out += &format!(
            "  layers: nominal {}, global relaxation {}, fallback {}, watchdog fallback {}, stale fallback {}, rejected {}\n",
            l.nominal, l.global_relaxation, l.fallback, l.watchdog_fallback, l.stale_fallback, l.rejected
        );
        out += &format!(
            "  {:<18} {:>9} {:>9} {:>9} {:>9} {:>9}\n",
            "us", "p50", "p90", "p99", "p99.9", "max"
        );
        for (name, p) in [
            ("round trip", &self.round_trip),
            ("queueing", &self.queue),
            ("solve", &self.solve),
            ("transport share", &self.transport_overhead),
            ("watchdog late", &self.watchdog_late_planner),
            ("  as received", &self.watchdog_late_received),
        ] {
            out += &format!(
                "  {:<18} {:>9} {:>9} {:>9} {:>9} {:>9}\n",
                name, p.p50_us, p.p90_us, p.p99_us, p.p999_us, p.max_us
            );
        }
        if let Some(f) = &self.flood {
            let (w, r) = (&f.watchdog_late_planner, &f.watchdog_late_received);
            out += &format!(
                "  flood: vehicle {} from {} sessions: sent {}, answered {} (nominal {}, watchdog {}); watchdog late p50/p99/max {}/{}/{} us, as received {}/{}/{} us\n",
                f.vehicle_id, f.sessions, f.sent, f.answered, f.by_layer.nominal, f.by_layer.watchdog_fallback,
                w.p50_us, w.p99_us, w.max_us, r.p50_us, r.p99_us, r.max_us
            );
        }
        if let Some(p) = &self.planner {
            out += &format!(
                "  planner pid {}: CPU mean {:.1} % of a core, RSS after warm-up {} KiB, at the end {} KiB, max {} KiB (growth {:.2} %)\n",
                p.pid,
                p.cpu_mean_percent,
                p.rss_after_warmup_kib,
                p.rss_end_kib,
                p.rss_max_after_warmup_kib,
                p.rss_growth_percent
            );
        }
        out
    }
}

/// Round trip at quantiles `1 - 10^-k`, k = 0, 0.1, .., 5.
fn spectrum(rt: &Histogram<u64>) -> Vec<(f64, u64)> {
    if rt.is_empty() {
        return Vec::new();
    }
    (0..=50)
        .map(|i| {
            let nines = f64::from(i) / 10.0;
            (nines, rt.value_at_quantile(1.0 - 10f64.powf(-nines)))
        })
        .collect()
}
