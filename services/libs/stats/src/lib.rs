//! The statistics every part reports in the same shape: answers counted by the layer on the
//! wire ([`LayerCounts`]) and latency percentiles ([`Percentiles`]), from an HDR histogram
//! ([`histogram`]) or exactly from samples (nearest rank).

use hdrhistogram::Histogram;
use protocol::{Layer, OutcomeRef, PlanResponse};
use serde::{Deserialize, Serialize};

/// Answers by the layer that produced them, as on the wire, and rejections.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct LayerCounts {
    /// The nominal MILP.
    pub nominal: u64,
    /// Layer A, the bounded global relaxation.
    pub global_relaxation: u64,
    /// Layer B, the deterministic fallback.
    pub fallback: u64,
    /// The planner's watchdog (deadline) or overload fallback.
    pub watchdog_fallback: u64,
    /// The fallback for a request that arrived older than its deadline. Absent in documents
    /// written before protocol version 3.
    #[serde(default)]
    pub stale_fallback: u64,
    /// Rejections (invalid request).
    pub rejected: u64,
}

impl LayerCounts {
    /// Counts one decision of `layer`.
    pub fn add(&mut self, layer: Layer) {
        match layer {
            Layer::Nominal => self.nominal += 1,
            Layer::GlobalRelaxation => self.global_relaxation += 1,
            Layer::Fallback => self.fallback += 1,
            Layer::WatchdogFallback => self.watchdog_fallback += 1,
            Layer::StaleFallback => self.stale_fallback += 1,
        }
    }

    /// Counts one answer: its layer, or a rejection (also an unreadable outcome).
    pub fn add_response(&mut self, response: &PlanResponse) {
        match response.outcome.get() {
            Ok(OutcomeRef::Decided(d)) => match d.layer() {
                Ok(layer) => self.add(layer),
                Err(_) => self.rejected += 1,
            },
            _ => self.rejected += 1,
        }
    }

    /// Adds another tally.
    pub fn merge(&mut self, other: &LayerCounts) {
        self.nominal += other.nominal;
        self.global_relaxation += other.global_relaxation;
        self.fallback += other.fallback;
        self.watchdog_fallback += other.watchdog_fallback;
        self.stale_fallback += other.stale_fallback;
        self.rejected += other.rejected;
    }

    /// Decisions counted (rejections excluded).
    pub fn decisions(&self) -> u64 {
        self.nominal + self.global_relaxation + self.fallback + self.watchdog_fallback + self.stale_fallback
    }

    /// Everything counted.
    pub fn total(&self) -> u64 {
        self.decisions() + self.rejected
    }
}

/// Percentiles of a latency, µs.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
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
    /// Of an HDR histogram (3 significant digits); all zero when it is empty.
    pub fn of_histogram(h: &Histogram<u64>) -> Self {
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

    /// Exact, by nearest rank (sorts `samples` in place); all zero without samples.
    pub fn of_samples(samples: &mut [u64]) -> Self {
        if samples.is_empty() {
            return Self::default();
        }
        samples.sort_unstable();
        let sum: u128 = samples.iter().map(|&s| u128::from(s)).sum();
        Self {
            count: samples.len() as u64,
            mean_us: sum as f64 / samples.len() as f64,
            p50_us: nearest_rank(samples, 0.5),
            p90_us: nearest_rank(samples, 0.9),
            p99_us: nearest_rank(samples, 0.99),
            p999_us: nearest_rank(samples, 0.999),
            max_us: samples[samples.len() - 1],
        }
    }
}

/// The `q`-quantile of sorted samples by nearest rank (the smallest sample with at least
/// `q` of them at or below it); 0 without samples.
pub fn nearest_rank(sorted: &[u64], q: f64) -> u64 {
    if sorted.is_empty() {
        return 0;
    }
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

/// A histogram of microseconds, 1 µs .. 60 s at 3 significant digits.
pub fn histogram() -> Histogram<u64> {
    // Cannot fail: the bounds are valid.
    Histogram::new_with_bounds(1, 60_000_000, 3).expect("valid histogram bounds")
}

/// Records a duration in µs (at least 1, the histogram's lowest value).
pub fn record(h: &mut Histogram<u64>, d: std::time::Duration) {
    h.saturating_record(u64::try_from(d.as_micros()).unwrap_or(u64::MAX).max(1));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_of_one_to_a_hundred() {
        let mut samples: Vec<u64> = (1..=100).rev().collect();
        let p = Percentiles::of_samples(&mut samples);
        assert_eq!(
            (p.p50_us, p.p90_us, p.p99_us, p.p999_us, p.max_us),
            (50, 90, 99, 100, 100)
        );
        assert_eq!(p.count, 100);
        assert!((p.mean_us - 50.5).abs() < 1e-12);
        assert_eq!(Percentiles::of_samples(&mut []), Percentiles::default());
        assert_eq!(nearest_rank(&[7], 0.0), 7);
    }

    #[test]
    fn histogram_percentiles_are_close_to_exact() {
        let mut h = histogram();
        let mut samples: Vec<u64> = (1..=10_000).collect();
        for &s in &samples {
            h.saturating_record(s);
        }
        let (a, b) = (Percentiles::of_histogram(&h), Percentiles::of_samples(&mut samples));
        for (x, y) in [(a.p50_us, b.p50_us), (a.p99_us, b.p99_us), (a.max_us, b.max_us)] {
            assert!(x.abs_diff(y) <= y / 500, "{x} vs {y}");
        }
        assert_eq!(Percentiles::of_histogram(&histogram()), Percentiles::default());
    }

    #[test]
    fn counts_by_layer_and_rejections() {
        let mut c = LayerCounts::default();
        for layer in [
            Layer::Nominal,
            Layer::Nominal,
            Layer::WatchdogFallback,
            Layer::Fallback,
            Layer::StaleFallback,
        ] {
            c.add(layer);
        }
        let rejected = PlanResponse::rejected(1, 2, protocol::Rejected::default(), 0);
        c.add_response(&rejected);
        let mut d = c;
        d.merge(&c);
        assert_eq!(
            (c.nominal, c.fallback, c.watchdog_fallback, c.stale_fallback, c.rejected),
            (2, 1, 1, 1, 1)
        );
        assert_eq!((c.decisions(), c.total(), d.total()), (5, 6, 12));
    }
}
