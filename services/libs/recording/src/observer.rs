//! What watches the planner's traffic: the [`PlanObserver`] trait, which the recorder
//! ([`crate::PlanRecorder`]) and the live view (`live_view::PlannerView`) implement, and
//! [`Observers`], the list the service calls on its answer path.
//!
//! One copy per request and per answer, whatever the number of observers: the request and the
//! answer are shared behind an [`Arc`]; the observers encode on their own threads.

use std::sync::Arc;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use protocol::{PlanRequest, PlanResponse};

/// Watches every decoded request (not the readiness probes), every answer and the statistics.
///
/// Every method is called on the service's answer path (a transport's receiving thread, a
/// worker, the watchdog) and must return at once: copy or share what it needs, hand it to a
/// thread of its own, and drop (and count) what that thread cannot take.
pub trait PlanObserver: Send + Sync {
    /// What it is, for the logs (`recorder`, `live view`).
    fn name(&self) -> &'static str;
    /// `request` arrived at `arrival`.
    fn request(&self, request: &Arc<PlanRequest>, arrival: Instant);
    /// `response` answered `request`; it left at `at` (handed to the transport).
    fn response(&self, request: &Arc<PlanRequest>, response: &Arc<PlanResponse>, at: Instant);
    /// A statistics document (the JSON published on `hmdp/planner/stats`), taken at `at`.
    fn stats(&self, json: &[u8], at: Instant);
    /// Messages dropped so far because its thread was behind.
    fn dropped(&self) -> u64;
}

/// The observers of a service (cheap to clone; empty by default).
#[derive(Clone, Default)]
pub struct Observers(Arc<Vec<Arc<dyn PlanObserver>>>);

impl std::fmt::Debug for Observers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.0.iter().map(|o| o.name())).finish()
    }
}

impl Observers {
    pub fn new(observers: Vec<Arc<dyn PlanObserver>>) -> Self {
        Self(Arc::new(observers))
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    pub fn iter(&self) -> impl Iterator<Item = &Arc<dyn PlanObserver>> {
        self.0.iter()
    }

    /// Shows `request` (arrived at `arrival`) to every observer now and returns `reply` wrapped
    /// so that, after passing the answer on, it shows them the answer. With no observer,
    /// `reply` itself, boxed.
    pub fn wrap_reply<F>(
        &self,
        request: &PlanRequest,
        arrival: Instant,
        reply: F,
    ) -> Box<dyn FnOnce(PlanResponse) + Send>
    where
        F: FnOnce(PlanResponse) + Send + 'static,
    {
        if self.is_empty() {
            return Box::new(reply);
        }
        let request = Arc::new(request.clone());
        for o in self.iter() {
            o.request(&request, arrival);
        }
        let observers = self.clone();
        Box::new(move |response: PlanResponse| {
            let at = Instant::now();
            let copy = Arc::new(response.clone());
            reply(response);
            for o in observers.iter() {
                o.response(&request, &copy, at);
            }
        })
    }

    /// Encodes `doc` once (recording JSON, [`crate::json`]) and shows it to every observer;
    /// a document that cannot be encoded is logged and skipped.
    pub fn stats<T: serde::Serialize>(&self, doc: &T) {
        if self.is_empty() {
            return;
        }
        match crate::json::to_vec(doc) {
            Ok(json) => {
                let at = Instant::now();
                for o in self.iter() {
                    o.stats(&json, at);
                }
            }
            Err(e) => tracing::warn!(error = %e, "statistics document not encodable"),
        }
    }
}

/// Turns [`Instant`]s into wall-clock nanoseconds (Unix time), anchored once, so that log
/// times are monotonic within a run.
#[derive(Debug, Clone, Copy)]
pub struct WallClock {
    at: Instant,
    unix_ns: u64,
}

impl Default for WallClock {
    fn default() -> Self {
        Self::now()
    }
}

impl WallClock {
    /// Anchored at this instant.
    pub fn now() -> Self {
        let unix_ns = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
        Self {
            at: Instant::now(),
            unix_ns,
        }
    }

    /// Wall-clock nanoseconds at `t`.
    pub fn ns(&self, t: Instant) -> u64 {
        if t >= self.at {
            self.unix_ns
                .saturating_add(u64::try_from((t - self.at).as_nanos()).unwrap_or(u64::MAX))
        } else {
            self.unix_ns
                .saturating_sub(u64::try_from((self.at - t).as_nanos()).unwrap_or(u64::MAX))
        }
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;
    use std::time::Duration;

    use protocol::{EgoState, RejectReason, Rejected, Road};

    use super::*;

    #[derive(Default)]
    struct Seen(Mutex<Vec<String>>);

    impl PlanObserver for Seen {
        fn name(&self) -> &'static str {
            "seen"
        }
        fn request(&self, request: &Arc<PlanRequest>, _: Instant) {
            self.0.lock().unwrap().push(format!("request {}", request.sequence));
        }
        fn response(&self, request: &Arc<PlanRequest>, response: &Arc<PlanResponse>, _: Instant) {
            self.0
                .lock()
                .unwrap()
                .push(format!("response {} to {}", response.sequence, request.sequence));
        }
        fn stats(&self, json: &[u8], _: Instant) {
            self.0.lock().unwrap().push(String::from_utf8_lossy(json).into_owned());
        }
        fn dropped(&self) -> u64 {
            0
        }
    }

    #[test]
    fn every_observer_sees_the_request_then_the_answer_after_the_transport() {
        let (a, b) = (Arc::new(Seen::default()), Arc::new(Seen::default()));
        let observers = Observers::new(vec![a.clone(), b.clone()]);
        let road = Road {
            lanes: 2,
            lane_width_m: 3.5,
            speed_limit_mps: 30.0,
        };
        let request = PlanRequest::new(1, 9, 0, road, EgoState::default());
        let sent = Arc::new(Mutex::new(None));
        let sent_by_reply = Arc::clone(&sent);
        let reply = observers.wrap_reply(&request, Instant::now(), move |r: PlanResponse| {
            *sent_by_reply.lock().unwrap() = Some(r.sequence);
        });
        assert_eq!(*a.0.lock().unwrap(), ["request 9"]);
        reply(PlanResponse::rejected(
            1,
            9,
            Rejected::new(RejectReason::OutOfRange, "x"),
            0,
        ));
        assert_eq!(*sent.lock().unwrap(), Some(9));
        #[derive(serde::Serialize)]
        struct Doc {
            answered: f64,
        }
        // Recording JSON: a NaN is the string "NaN", as in every recording.
        observers.stats(&Doc { answered: f64::NAN });
        for seen in [a, b] {
            assert_eq!(
                *seen.0.lock().unwrap(),
                ["request 9", "response 9 to 9", r#"{"answered":"NaN"}"#]
            );
        }
        assert_eq!(format!("{observers:?}"), r#"["seen", "seen"]"#);
    }

    #[test]
    fn wall_clock_times_follow_the_monotonic_clock() {
        let clock = WallClock::now();
        let t = clock.at + Duration::from_millis(1500);
        assert_eq!(clock.ns(t) - clock.ns(clock.at), 1_500_000_000);
        assert_eq!(
            clock.ns(clock.at) - clock.ns(clock.at.checked_sub(Duration::from_secs(2)).expect("up for 2 s")),
            2_000_000_000
        );
    }
}
