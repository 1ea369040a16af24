//! One simulated vehicle under load: its own simulation, paced requests over a
//! [`RemoteLink`], every request measured.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use hdrhistogram::Histogram;
use protocol::PlanRequest;
use stats::LayerCounts;

use super::report::{Counts, TimelinePoint};
use super::LoadSettings;
use crate::campaign::{paper_entries, trial_spec, CampaignSettings};
use crate::episode::{run_episode, Driver};
use crate::error::{Result, SimClientError};
use crate::link::{LinkError, LinkOptions, Planned, PlannerLink, RemoteLink, Trip};

/// What one vehicle thread measures.
pub(super) struct VehicleStats {
    pub counts: Counts,
    pub by_layer: LayerCounts,
    pub round_trip: Histogram<u64>,
    pub queue: Histogram<u64>,
    pub solve: Histogram<u64>,
    pub transport: Histogram<u64>,
    /// Watchdog answers given at the deadline: the planner's answer time minus the deadline.
    pub watchdog_late_planner: Histogram<u64>,
    /// The same answers as received: the round trip minus the deadline the request asked for.
    pub watchdog_late_received: Histogram<u64>,
    pub timeline: Vec<TimelinePoint>,
}

impl VehicleStats {
    fn new() -> Self {
        Self {
            counts: Counts::default(),
            by_layer: LayerCounts::default(),
            round_trip: stats::histogram(),
            queue: stats::histogram(),
            solve: stats::histogram(),
            transport: stats::histogram(),
            watchdog_late_planner: stats::histogram(),
            watchdog_late_received: stats::histogram(),
            timeline: Vec::new(),
        }
    }

    fn point(&mut self, start: Instant, period: Duration, at: Instant) -> &mut TimelinePoint {
        let i = (at.saturating_duration_since(start).as_secs_f64() / period.as_secs_f64()) as usize;
        while self.timeline.len() <= i {
            let t_s = (self.timeline.len() + 1) as f64 * period.as_secs_f64();
            self.timeline.push(TimelinePoint {
                t_s,
                ..Default::default()
            });
        }
        &mut self.timeline[i]
    }

    /// Accounts for one trip; whether it ended in time, late or lost.
    fn record(&mut self, trip: &Trip, deadline: Duration) -> AnswerKind {
        let round_trip = trip.round_trip();
        let kind = match (&trip.answer.response, round_trip <= deadline) {
            (None, _) => AnswerKind::Lost,
            (Some(_), true) => AnswerKind::InTime,
            (Some(_), false) => AnswerKind::Late,
        };
        let c = &mut self.counts;
        c.sent += 1;
        c.duplicated += trip.answer.extra_responses as u64;
        c.refused += trip.answer.refused.len() as u64;
        c.retried += trip.answer.retries as u64;
        c.discarded += trip.answer.mismatched as u64;
        match kind {
            AnswerKind::InTime => c.in_time += 1,
            AnswerKind::Late => c.late += 1,
            AnswerKind::Lost => c.lost += 1,
        }
        if let Some(response) = &trip.answer.response {
            if trip.matching_response().is_none() {
                c.mismatched += 1;
            }
            let server = Duration::from_micros(u64::from(response.queue_us) + u64::from(response.solve_us));
            stats::record(&mut self.round_trip, round_trip);
            stats::record(&mut self.queue, Duration::from_micros(response.queue_us.into()));
            stats::record(&mut self.solve, Duration::from_micros(response.solve_us.into()));
            stats::record(&mut self.transport, round_trip.saturating_sub(server));
            if let Some(late) = super::flood::watchdog_lateness_us(response, trip.request.deadline_us) {
                let _ = self.watchdog_late_planner.record(late);
                let asked = Duration::from_micros(trip.request.deadline_us.into());
                stats::record(&mut self.watchdog_late_received, round_trip.saturating_sub(asked));
            }
            self.by_layer.add_response(response);
        }
        kind
    }
}

/// How one request ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum AnswerKind {
    InTime,
    Late,
    Lost,
}

/// Counters shared by every vehicle thread, for progress lines while the run goes on.
#[derive(Debug, Default)]
pub struct LiveCounters {
    /// Requests sent.
    pub sent: AtomicU64,
    /// Decided by the deadline.
    pub in_time: AtomicU64,
    /// Answered after the deadline.
    pub late: AtomicU64,
    /// Never answered.
    pub lost: AtomicU64,
    /// Extra answers.
    pub duplicated: AtomicU64,
}

impl LiveCounters {
    fn record(&self, decided_in_time: bool, kind: AnswerKind, duplicated: usize) {
        self.sent.fetch_add(1, Ordering::Relaxed);
        self.duplicated.fetch_add(duplicated as u64, Ordering::Relaxed);
        if decided_in_time {
            self.in_time.fetch_add(1, Ordering::Relaxed);
        }
        match kind {
            AnswerKind::Late => self.late.fetch_add(1, Ordering::Relaxed),
            AnswerKind::Lost => self.lost.fetch_add(1, Ordering::Relaxed),
            AnswerKind::InTime => 0,
        };
    }

    /// (sent, in time, late, lost, duplicated) so far.
    pub fn get(&self) -> [u64; 5] {
        [&self.sent, &self.in_time, &self.late, &self.lost, &self.duplicated].map(|a| a.load(Ordering::Relaxed))
    }
}

/// A [`PlannerLink`] that sends at the vehicle's rate over a [`RemoteLink`] and measures;
/// the simulation sees the planner's decision when it came in time, else the vehicle's own
/// fallback.
struct PacedVehicle<'a> {
    link: RemoteLink,
    settings: &'a LoadSettings,
    start: Instant,
    next_send: Instant,
    end: Instant,
    stats: VehicleStats,
    live: Option<Arc<LiveCounters>>,
}

impl PlannerLink for PacedVehicle<'_> {
    fn decide(&mut self, body: &PlanRequest) -> std::result::Result<Planned, LinkError> {
        let now = Instant::now();
        if self.next_send > now {
            std::thread::sleep(self.next_send - now);
        }
        // Behind schedule (a late answer): send now rather than in a burst.
        self.next_send = self.next_send.max(Instant::now()) + Duration::from_secs_f64(1.0 / self.settings.rate_hz);
        if Instant::now() >= self.end {
            return Err(LinkError::Stopped);
        }
        let trip = self.link.send(body);
        if let Some(recorder) = &self.settings.recorder {
            // The answer as it came, also a late or mismatched one: what the vehicle got.
            recorder.request(&trip.request, trip.sent_at);
            if let (Some(response), Some(at)) = (&trip.answer.response, trip.answer.answered_at) {
                recorder.response(response.clone(), at);
            }
        }
        let kind = self.stats.record(&trip, self.settings.deadline);
        // A rejection or a late answer: the vehicle decides by itself.
        let planned = match trip.matching_response() {
            Some(response) if kind == AnswerKind::InTime => Planned::from_response(response).ok(),
            _ => None,
        };
        let decided_in_time = planned.is_some();
        if let Some(live) = &self.live {
            live.record(decided_in_time, kind, trip.answer.extra_responses);
        }
        let point = self.stats.point(self.start, self.settings.sample_period, trip.sent_at);
        point.sent += 1;
        if decided_in_time {
            point.in_time += 1;
        } else {
            point.misses += 1;
        }
        let round_trip_us = u64::try_from(trip.round_trip().as_micros()).unwrap_or(u64::MAX);
        point.max_round_trip_us = point.max_round_trip_us.max(round_trip_us);
        match planned {
            Some(p) => Ok(p),
            None => self.link.local_fallback(&trip.request),
        }
    }
}

/// One vehicle: simulations one after another (Table I classes in turn), until the end.
pub(super) fn run_vehicle(settings: &LoadSettings, index: usize, start: Instant, end: Instant) -> Result<VehicleStats> {
    let vehicle_id = settings.vehicle_id_base + index as u64;
    let options = LinkOptions {
        deadline: settings.deadline,
        transport_margin: settings.transport_margin,
        ready_timeout: Duration::from_secs(60),
        answer_grace: settings.grace,
        wait_for_late: true,
        vehicle_id,
    };
    let link = settings.transport.remote_link(settings.planner.clone(), options)?;
    // Spread the vehicles over the period, so that the load is even.
    let phase = Duration::from_secs_f64(index as f64 / (settings.clients as f64 * settings.rate_hz));
    let mut vehicle = PacedVehicle {
        link,
        settings,
        start,
        next_send: start + phase,
        end,
        stats: VehicleStats::new(),
        live: settings.live.clone(),
    };
    let entries = paper_entries();
    let mut campaign = CampaignSettings::new(entries.clone(), settings.seed ^ vehicle_id, 1);
    campaign.planner = settings.planner.clone();
    for episode in 0u32.. {
        let entry = &entries[(index + episode as usize) % entries.len()];
        let spec = trial_spec(entry, episode, &campaign)?;
        match run_episode(&spec, Driver::Planner(&mut vehicle)) {
            Ok(_) => {}
            Err(SimClientError::Link(LinkError::Stopped)) => break,
            Err(e) => return Err(e),
        }
    }
    Ok(vehicle.stats)
}
