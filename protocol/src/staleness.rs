//! Stale requests: a request whose `sent_at_ns` is already older than its deadline when it
//! arrives (it waited in a socket buffer, a stopped process, a slow link) is answered at once
//! with the fallback marked [`Layer::StaleFallback`](crate::Layer::StaleFallback), never
//! solved as if the scene were current.
//!
//! The clock is the Unix time (`CLOCK_REALTIME`) of the vehicle and the planner, which must
//! be synchronised (NTP or PTP); [`DEFAULT_CLOCK_SKEW_TOLERANCE`] absorbs what is left. A
//! `sent_at_ns` of 0 (unknown) or in the future is never stale.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use crate::messages::PlanRequest;

/// How far the vehicle's and the planner's clocks may disagree: a request counts as stale
/// only when older than its deadline plus this. NTP on a LAN keeps clocks within a few ms.
pub const DEFAULT_CLOCK_SKEW_TOLERANCE: Duration = Duration::from_millis(50);

/// Now, ns since the Unix epoch (what a client puts in `sent_at_ns`); 0 if the clock is
/// before the epoch.
pub fn unix_now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

impl PlanRequest {
    /// The request's age at `now_ns` (Unix ns) by its `sent_at_ns`; `None` when unknown (0)
    /// or when it was sent "after" now (clock skew).
    pub fn age_at(&self, now_ns: u64) -> Option<Duration> {
        if self.sent_at_ns == 0 || self.sent_at_ns > now_ns {
            return None;
        }
        Some(Duration::from_nanos(now_ns - self.sent_at_ns))
    }

    /// Whether the request is already older than `deadline` plus `tolerance` at `now_ns`.
    pub fn is_stale_at(&self, now_ns: u64, deadline: Duration, tolerance: Duration) -> bool {
        self.age_at(now_ns)
            .is_some_and(|age| age > deadline.saturating_add(tolerance))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{EgoState, Road};

    const MS: u64 = 1_000_000;

    fn sent_at(ns: u64) -> PlanRequest {
        let mut r = PlanRequest::new(1, 1, 0, Road::default(), EgoState::default());
        r.sent_at_ns = ns;
        r
    }

    #[test]
    fn stale_only_beyond_deadline_plus_tolerance() {
        let (deadline, tol) = (Duration::from_millis(400), Duration::from_millis(50));
        let now = 10_000 * MS;
        assert!(!sent_at(now - 10 * MS).is_stale_at(now, deadline, tol));
        assert!(!sent_at(now - 450 * MS).is_stale_at(now, deadline, tol));
        assert!(sent_at(now - 451 * MS).is_stale_at(now, deadline, tol));
        assert!(sent_at(now - 2_000 * MS).is_stale_at(now, deadline, tol));
        assert_eq!(sent_at(now - 3 * MS).age_at(now), Some(Duration::from_millis(3)));
    }

    #[test]
    fn unknown_or_future_send_times_are_never_stale() {
        let now = 10_000 * MS;
        assert!(!sent_at(0).is_stale_at(now, Duration::ZERO, Duration::ZERO));
        assert!(!sent_at(now + 5_000 * MS).is_stale_at(now, Duration::ZERO, Duration::ZERO));
        assert_eq!(sent_at(0).age_at(now), None);
    }

    #[test]
    fn the_clock_is_unix_time() {
        // 2020-01-01 in ns: any sane clock is later.
        assert!(unix_now_ns() > 1_577_836_800 * 1_000_000_000);
    }
}
