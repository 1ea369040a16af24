//! A flooding vehicle beside the measured ones (`load --flood-sessions N`, Zenoh only): N
//! sessions send real requests as one vehicle id, each at a fixed rate, without waiting for
//! the answers, so that the planner's fair queue, rate limit and watchdog are measured under
//! a flood (docs/hostile-peers.md). The scene is fixed (the worked example of
//! docs/protocol.md: one SV ahead, a real MILP solve), so runs repeat.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use hdrhistogram::Histogram;
use protocol::{Layer, PlanRequest, PlanResponse};
use serde::{Deserialize, Serialize};
use stats::{LayerCounts, Percentiles};
use transport::zenoh::{ZenohChannel, ZenohTarget};

use crate::error::{Result, SimClientError};

/// The flood to run.
#[derive(Debug, Clone, Copy)]
pub struct FloodSettings {
    /// Zenoh sessions, each sending at `rate_hz`.
    pub sessions: usize,
    /// Requests per second per session.
    pub rate_hz: f64,
    /// The one vehicle id every flood request carries.
    pub vehicle_id: u64,
    /// The deadline the flood's requests ask for.
    pub deadline: Duration,
}

/// What the flood sent and got back.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct FloodReport {
    /// Zenoh sessions that flooded.
    pub sessions: usize,
    /// The flooding vehicle's id.
    pub vehicle_id: u64,
    /// Requests sent.
    pub sent: u64,
    /// Answers received (a request may be answered after the run ends and not counted).
    pub answered: u64,
    /// Answers by layer.
    pub by_layer: LayerCounts,
    /// Watchdog answers given at the deadline (not at once for overload or the rate limit):
    /// the planner's answer time minus the deadline (from the answer's `queue_us`).
    pub watchdog_late_planner: Percentiles,
    /// The same answers as received: arrival minus (sending + the deadline).
    pub watchdog_late_received: Percentiles,
}

/// What the reply callbacks collect.
struct Tally {
    answered: u64,
    by_layer: LayerCounts,
    late_planner: Histogram<u64>,
    late_received: Histogram<u64>,
}

/// The worked example of docs/protocol.md as request `sequence` of `vehicle_id`.
fn flood_request(vehicle_id: u64, sequence: u64, deadline: Duration) -> PlanRequest {
    let mut r = protocol::worked_example_request(vehicle_id, sequence);
    r.deadline_us = u32::try_from(deadline.as_micros()).unwrap_or(u32::MAX);
    r.sent_at_ns = protocol::unix_now_ns();
    r
}

/// Whether a watchdog answer was given at the deadline (rather than at once, for overload
/// or the rate limit), and how late then, µs.
pub(super) fn watchdog_lateness_us(response: &PlanResponse, deadline_us: u32) -> Option<u64> {
    let layer = response.outcome.as_decided().and_then(|d| d.layer().ok());
    (layer == Some(Layer::WatchdogFallback) && response.queue_us >= deadline_us)
        .then(|| u64::from(response.queue_us - deadline_us))
}

/// Runs the flood against `target` until `end`.
pub fn run_flood(target: &ZenohTarget, settings: FloodSettings, end: Instant) -> Result<FloodReport> {
    let tally = Arc::new(Mutex::new(Tally {
        answered: 0,
        by_layer: LayerCounts::default(),
        late_planner: stats::histogram(),
        late_received: stats::histogram(),
    }));
    let deadline_us = u32::try_from(settings.deadline.as_micros()).unwrap_or(u32::MAX);
    let sent: Vec<Result<u64>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..settings.sessions)
            .map(|k| {
                let tally = Arc::clone(&tally);
                scope.spawn(move || -> Result<u64> {
                    let channel = ZenohChannel::connect(target, Duration::from_secs(60), Duration::from_secs(2))
                        .map_err(|e| SimClientError::Config(format!("flood session: {e}")))?;
                    let period = Duration::from_secs_f64(1.0 / settings.rate_hz);
                    let mut next = Instant::now();
                    let mut sequence = (k as u64) << 40;
                    while Instant::now() < end {
                        sequence += 1;
                        let request = flood_request(settings.vehicle_id, sequence, settings.deadline);
                        let (tally, sent_at) = (Arc::clone(&tally), Instant::now());
                        let on_reply = move |bytes: Vec<u8>| {
                            let Ok(response) = protocol::decode_bincode::<PlanResponse>(&bytes) else {
                                return;
                            };
                            let mut t = tally.lock().unwrap_or_else(|e| e.into_inner());
                            t.answered += 1;
                            t.by_layer.add_response(&response);
                            if let Some(late) = watchdog_lateness_us(&response, deadline_us) {
                                let _ = t.late_planner.record(late);
                                let received = sent_at.elapsed().saturating_sub(settings.deadline);
                                stats::record(&mut t.late_received, received);
                            }
                        };
                        if let Err(e) = channel.send_without_waiting(protocol::encode_bincode(&request), on_reply) {
                            tracing::warn!("flood: {e}");
                        }
                        next += period;
                        std::thread::sleep(next.saturating_duration_since(Instant::now()));
                    }
                    Ok(sequence - ((k as u64) << 40))
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|_| Err(SimClientError::Config("a flood thread panicked".into())))
            })
            .collect()
    });
    let sent = sent.into_iter().sum::<Result<u64>>()?;
    // Answers still on their way (the deadline) are counted.
    std::thread::sleep(settings.deadline + Duration::from_millis(200));
    let t = tally.lock().unwrap_or_else(|e| e.into_inner());
    Ok(FloodReport {
        sessions: settings.sessions,
        vehicle_id: settings.vehicle_id,
        sent,
        answered: t.answered,
        by_layer: t.by_layer,
        watchdog_late_planner: Percentiles::of_histogram(&t.late_planner),
        watchdog_late_received: Percentiles::of_histogram(&t.late_received),
    })
}
