//! Fairness between vehicles, as pure logic (no threads, no clock of its own):
//!
//! * [`FairQueue`]: the requests waiting for a worker, one lane per vehicle id, served
//!   round-robin across vehicles: a vehicle that floods waits behind its own requests, not in
//!   front of everyone else's.
//! * [`RateLimiter`]: a token bucket per vehicle id; what exceeds it is answered at once by
//!   the fallback instead of taking a worker.
//!
//! Both key on the vehicle id the request declares. A peer that forges many ids gets many
//! lanes and buckets; the total capacity of the queue still bounds it (docs/service.md).

use std::collections::{HashMap, VecDeque};
use std::time::Instant;

/// Why [`FairQueue::push`] refused an item.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refused {
    /// The queue holds its total capacity.
    Full,
    /// This vehicle already has its share queued.
    VehicleFull,
}

/// A bounded queue served round-robin across vehicle ids.
#[derive(Debug)]
pub struct FairQueue<T> {
    lanes: HashMap<u64, VecDeque<T>>,
    /// Vehicles with something queued, in serving order.
    turn: VecDeque<u64>,
    len: usize,
    capacity: usize,
    per_vehicle: usize,
}

impl<T> FairQueue<T> {
    /// At most `capacity` items in all, `per_vehicle` of one vehicle (both at least 1).
    pub fn new(capacity: usize, per_vehicle: usize) -> Self {
        Self {
            lanes: HashMap::new(),
            turn: VecDeque::new(),
            len: 0,
            capacity: capacity.max(1),
            per_vehicle: per_vehicle.max(1),
        }
    }

    /// Queues `item` of `vehicle`, or gives it back with the reason.
    pub fn push(&mut self, vehicle: u64, item: T) -> Result<(), (T, Refused)> {
        if self.len >= self.capacity {
            return Err((item, Refused::Full));
        }
        let lane = self.lanes.entry(vehicle).or_default();
        if lane.len() >= self.per_vehicle {
            return Err((item, Refused::VehicleFull));
        }
        if lane.is_empty() {
            self.turn.push_back(vehicle);
        }
        lane.push_back(item);
        self.len += 1;
        Ok(())
    }

    /// The next item: the oldest of the vehicle whose turn it is.
    pub fn pop(&mut self) -> Option<T> {
        let vehicle = self.turn.pop_front()?;
        let lane = self.lanes.get_mut(&vehicle)?;
        let item = lane.pop_front();
        if lane.is_empty() {
            self.lanes.remove(&vehicle);
        } else {
            self.turn.push_back(vehicle);
        }
        self.len -= usize::from(item.is_some());
        item
    }

    /// Items queued.
    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether nothing is queued.
    #[cfg(test)]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// Requests per second and burst allowed to one vehicle id.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RateLimit {
    /// Sustained requests per second.
    pub per_second: f64,
    /// Requests allowed at once after a quiet period.
    pub burst: f64,
}

/// Buckets kept before idle (full) ones are forgotten.
const MAX_IDLE_BUCKETS: usize = 4096;

#[derive(Debug, Clone, Copy)]
struct Bucket {
    tokens: f64,
    at: Instant,
}

/// A token bucket per vehicle id.
#[derive(Debug)]
pub struct RateLimiter {
    limit: RateLimit,
    buckets: HashMap<u64, Bucket>,
}

impl RateLimiter {
    /// Buckets of `limit`.
    pub fn new(limit: RateLimit) -> Self {
        Self {
            limit,
            buckets: HashMap::new(),
        }
    }

    /// Whether `vehicle` may send a request at `now` (takes a token if so).
    pub fn allow(&mut self, vehicle: u64, now: Instant) -> bool {
        let limit = self.limit;
        if self.buckets.len() > MAX_IDLE_BUCKETS {
            // A bucket refilled to the burst carries no information: forget it.
            self.buckets.retain(|_, b| Self::refilled(limit, b, now) < limit.burst);
        }
        let bucket = self.buckets.entry(vehicle).or_insert(Bucket {
            tokens: limit.burst,
            at: now,
        });
        bucket.tokens = Self::refilled(limit, bucket, now);
        bucket.at = now.max(bucket.at);
        if bucket.tokens >= 1.0 {
            bucket.tokens -= 1.0;
            true
        } else {
            false
        }
    }

    fn refilled(limit: RateLimit, bucket: &Bucket, now: Instant) -> f64 {
        let elapsed = now.saturating_duration_since(bucket.at);
        (bucket.tokens + elapsed.as_secs_f64() * limit.per_second).min(limit.burst)
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    #[test]
    fn vehicles_are_served_in_turn_whatever_their_backlog() {
        let mut q = FairQueue::new(100, 100);
        for i in 0..10 {
            q.push(1, (1, i)).unwrap();
        }
        q.push(2, (2, 0)).unwrap();
        q.push(3, (3, 0)).unwrap();
        let first: Vec<_> = (0..4).map(|_| q.pop().unwrap()).collect();
        assert_eq!(first, vec![(1, 0), (2, 0), (3, 0), (1, 1)]);
        assert_eq!(q.len(), 8);
        while q.pop().is_some() {}
        assert!(q.is_empty());
    }

    #[test]
    fn one_vehicle_cannot_take_the_whole_queue() {
        let mut q = FairQueue::new(10, 3);
        for i in 0..3 {
            q.push(1, i).unwrap();
        }
        assert_eq!(q.push(1, 3), Err((3, Refused::VehicleFull)));
        for v in 2..9 {
            q.push(v, 0).unwrap();
        }
        assert_eq!(q.push(9, 0), Err((0, Refused::Full)));
    }

    #[test]
    fn a_rate_limited_vehicle_leaves_the_others_alone_and_recovers() {
        let limit = RateLimit {
            per_second: 10.0,
            burst: 5.0,
        };
        let mut limiter = RateLimiter::new(limit);
        let t0 = Instant::now();
        let allowed = (0..20).filter(|_| limiter.allow(1, t0)).count();
        assert_eq!(allowed, 5);
        assert!(limiter.allow(2, t0));
        assert!(!limiter.allow(1, t0 + Duration::from_millis(50)));
        assert!(limiter.allow(1, t0 + Duration::from_millis(150)));
    }
}
