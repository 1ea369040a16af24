//! The one interface the planner is reached through.
//!
//! The simulation loop only sees [`PlannerLink`]: a request body in (the perception and the
//! memory of the last answer, in wire form), a [`Planned`] out. Implementations:
//! [`InProcess`], a planner in this thread, and [`RemoteLink`], a `planner serve` process
//! through a [`PlanChannel`]. Both answer through [`protocol::answer`], the path the
//! service takes, so that a run is the same in process and over a transport.

use std::time::{Duration, Instant};

use crate::inproc::InProcessChannel;
use decision::{DecisionError, PlannerConfig};
use protocol::{Layer, OutcomeRef, PlanRequest, PlanResponse, PlannerMemory, RejectReason, SetPoint, WireError};
use thiserror::Error;
use transport::{Answer, ChannelError, PlanChannel};

pub use crate::connect::Transport;

/// Why a link could not produce a decision.
#[derive(Debug, Error)]
pub enum LinkError {
    /// The planner rejected the request.
    #[error("the planner rejected the request: {reason} (field `{field}`)")]
    Rejected {
        /// The typed reason.
        reason: RejectReason,
        /// The offending field, e.g. `ego.v_mps` (empty when no single field is at fault).
        field: String,
    },
    /// The answer does not hold a valid decision or rejection.
    #[error("bad answer from the planner")]
    BadAnswer(#[source] WireError),
    /// The request does not fit the message (a list over its capacity).
    #[error("encoding the request")]
    Encode(#[source] WireError),
    /// The channel could not be opened or failed.
    #[error(transparent)]
    Channel(#[from] ChannelError),
    /// The vehicle's own fallback (or an in-process planner) failed.
    #[error("planner error")]
    Decision(#[from] DecisionError),
    /// The run is over (a load test's duration ran out); not a failure.
    #[error("stopped: the run is over")]
    Stopped,
}

/// What the simulation needs of one answer. The memory stays in wire form: the vehicle only
/// hands it back with its next request.
#[derive(Debug, Clone, PartialEq)]
pub struct Planned {
    /// The maneuver to command now.
    pub next_maneuver: decision::Maneuver,
    /// The longitudinal set-point of the first step.
    pub setpoint: SetPoint,
    /// The layer that answered, as on the wire.
    pub layer: Layer,
    /// The planned sequence.
    pub plan: Vec<decision::PlanStep>,
    /// SVs in corrective (hysteresis) mode.
    pub corrective_svs: usize,
    /// The planner's decision time, µs.
    pub solve_us: u64,
    /// Memory to send back with the next request.
    pub memory: PlannerMemory,
}

impl Planned {
    /// The decision `response` carries; a rejection is [`LinkError::Rejected`].
    pub fn from_response(response: &PlanResponse) -> Result<Self, LinkError> {
        match response.outcome.get().map_err(LinkError::BadAnswer)? {
            OutcomeRef::Decided(d) => Ok(Self {
                next_maneuver: d.next_maneuver.into(),
                setpoint: d.setpoint,
                layer: d.layer().map_err(LinkError::BadAnswer)?,
                plan: d.plan.iter().map(|&s| s.into()).collect(),
                corrective_svs: d.memory.corrective.len(),
                solve_us: u64::from(response.solve_us),
                memory: d.memory.clone(),
            }),
            OutcomeRef::Rejected(r) => Err(LinkError::Rejected {
                reason: r.reason().map_err(LinkError::BadAnswer)?,
                field: r.field().to_owned(),
            }),
        }
    }

    /// The vehicle's own decision for `request` (the deterministic fallback,
    /// [`protocol::fallback_answer`]), when no answer came by the deadline. A request that
    /// fails the planner's checks is [`LinkError::Rejected`].
    pub fn local_fallback(config: &PlannerConfig, request: &PlanRequest) -> Result<Self, LinkError> {
        let valid = request
            .clone()
            .validate(config)
            .map_err(|invalid| LinkError::Rejected {
                // Built by the checks: always a known reason.
                reason: invalid.rejected.reason().unwrap_or(RejectReason::InternalError),
                field: invalid.rejected.field().to_owned(),
            })?;
        Self::from_response(&protocol::fallback_answer(config, &valid, Layer::Fallback))
    }
}

/// A way to ask a planner for a decision. Object safe: the episode loop holds a
/// `&mut dyn PlannerLink`.
pub trait PlannerLink {
    /// One decision for one request body.
    fn decide(&mut self, request: &PlanRequest) -> Result<Planned, LinkError>;
}

/// The planner in the same process and thread (a `Planner` is not `Send`).
pub struct InProcess {
    channel: InProcessChannel,
}

impl InProcess {
    /// Builds a planner from `config`.
    pub fn new(config: PlannerConfig) -> Result<Self, LinkError> {
        Ok(Self {
            channel: InProcessChannel::new(config)?,
        })
    }

    /// Wraps an existing planner.
    pub fn from_planner(planner: decision::Planner) -> Self {
        Self {
            channel: InProcessChannel::from_planner(planner),
        }
    }

    /// The planner's configuration.
    pub fn config(&self) -> &PlannerConfig {
        self.channel.config()
    }
}

impl PlannerLink for InProcess {
    fn decide(&mut self, request: &PlanRequest) -> Result<Planned, LinkError> {
        Planned::from_response(&self.channel.answer(request))
    }
}

/// Settings of a remote link.
#[derive(Debug, Clone)]
pub struct LinkOptions {
    /// The vehicle's deadline: no answer by then and the vehicle applies
    /// `decision::fallback_only` itself.
    pub deadline: Duration,
    /// Part of the deadline kept for the transport: the request asks the planner for
    /// `deadline - transport_margin`, so that the planner's watchdog answers before the
    /// vehicle gives up.
    pub transport_margin: Duration,
    /// How long connecting waits for the planner to answer.
    pub ready_timeout: Duration,
    /// How long after the deadline an answer still counts as late rather than lost: the link
    /// listens that long (a measurement), and Zenoh's query timeout is `deadline +
    /// answer_grace`.
    pub answer_grace: Duration,
    /// Whether to wait for late answers (up to `answer_grace` after the deadline) instead of
    /// giving up at the deadline: what a measurement wants, not a vehicle.
    pub wait_for_late: bool,
    /// Sender id put in the requests.
    pub vehicle_id: u64,
}

impl Default for LinkOptions {
    fn default() -> Self {
        Self {
            deadline: protocol::DEFAULT_DEADLINE,
            transport_margin: Duration::from_millis(20),
            ready_timeout: Duration::from_secs(30),
            answer_grace: Duration::from_secs(1),
            wait_for_late: false,
            vehicle_id: u64::from(std::process::id()),
        }
    }
}

/// Counts of a remote link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkCounts {
    /// Answers from the planner.
    pub answered: u64,
    /// Decisions the vehicle made itself (no answer by the deadline).
    pub local_fallbacks: u64,
    /// Answers beyond the first for one request (0 with a correct planner).
    pub duplicates: u64,
    /// Answers refused because they did not verify with the planner's key.
    pub refused: u64,
}

/// One request's trip over a [`RemoteLink`].
#[derive(Debug, Clone)]
pub struct Trip {
    /// The request as sent (numbered, with its deadline).
    pub request: PlanRequest,
    /// When it was sent.
    pub sent_at: Instant,
    /// What came back.
    pub answer: Answer,
}

impl Trip {
    /// Sending to the first answer (to now when none came).
    pub fn round_trip(&self) -> Duration {
        self.answer
            .answered_at
            .unwrap_or_else(Instant::now)
            .saturating_duration_since(self.sent_at)
    }

    /// The answer, when it answers this request (vehicle id and sequence match).
    pub fn matching_response(&self) -> Option<&PlanResponse> {
        self.answer
            .response
            .as_ref()
            .filter(|r| (r.vehicle_id, r.sequence) == (self.request.vehicle_id, self.request.sequence))
    }
}

/// The planner in another process, asked through a [`PlanChannel`]. Numbers the requests,
/// asks for `deadline - transport_margin`, and falls back locally when no answer comes.
pub struct RemoteLink {
    channel: Box<dyn PlanChannel>,
    config: PlannerConfig,
    options: LinkOptions,
    sequence: u64,
    started: Instant,
    counts: LinkCounts,
}

impl RemoteLink {
    /// A link over `channel`; `config` is used for the vehicle's own fallback.
    pub fn new(channel: Box<dyn PlanChannel>, config: PlannerConfig, options: LinkOptions) -> Self {
        Self {
            channel,
            config,
            options,
            sequence: 0,
            started: Instant::now(),
            counts: LinkCounts::default(),
        }
    }

    /// The counts so far.
    pub fn counts(&self) -> LinkCounts {
        self.counts
    }

    /// The settings.
    pub fn options(&self) -> &LinkOptions {
        &self.options
    }

    /// Sends `body` as the next request and waits for its answer: until the deadline, or
    /// `answer_grace` longer with `wait_for_late`. A failed channel is an unanswered trip.
    pub fn send(&mut self, body: &PlanRequest) -> Trip {
        self.sequence += 1;
        let sent_at = Instant::now();
        let mut request = body.clone();
        request.vehicle_id = self.options.vehicle_id;
        request.sequence = self.sequence;
        request.timestamp_ns = u64::try_from(self.started.elapsed().as_nanos()).unwrap_or(u64::MAX);
        request.sent_at_ns = protocol::unix_now_ns();
        let server_deadline = self.options.deadline.saturating_sub(self.options.transport_margin);
        request.deadline_us = u32::try_from(server_deadline.as_micros()).unwrap_or(u32::MAX).max(1);
        let wait = if self.options.wait_for_late {
            self.options.deadline + self.options.answer_grace
        } else {
            self.options.deadline
        };
        let answer = match self.channel.exchange(request.clone(), wait) {
            Ok(answer) => answer,
            Err(e) => {
                tracing::warn!(sequence = self.sequence, "{} request failed: {e}", self.channel.name());
                Answer::default()
            }
        };
        self.counts.duplicates += answer.extra_responses as u64;
        self.counts.refused += answer.refused.len() as u64;
        Trip {
            request,
            sent_at,
            answer,
        }
    }

    /// What the vehicle acts on after `trip`: the planner's answer when it matches and came
    /// by the deadline, else its own fallback. A rejection is an error.
    pub fn settle(&mut self, trip: &Trip) -> Result<Planned, LinkError> {
        match trip.matching_response() {
            Some(response) if trip.round_trip() <= self.options.deadline => {
                self.counts.answered += 1;
                Planned::from_response(response)
            }
            _ => {
                tracing::warn!(
                    sequence = trip.request.sequence,
                    "no answer from the planner by the deadline: local fallback"
                );
                self.local_fallback(&trip.request)
            }
        }
    }

    /// The vehicle's own decision for `request`.
    pub fn local_fallback(&mut self, request: &PlanRequest) -> Result<Planned, LinkError> {
        self.counts.local_fallbacks += 1;
        Planned::local_fallback(&self.config, request)
    }
}

impl PlannerLink for RemoteLink {
    fn decide(&mut self, request: &PlanRequest) -> Result<Planned, LinkError> {
        let trip = self.send(request);
        self.settle(&trip)
    }
}

impl Drop for RemoteLink {
    fn drop(&mut self) {
        let c = self.counts;
        if c.local_fallbacks > 0 || c.duplicates > 0 || c.refused > 0 {
            tracing::warn!(
                transport = self.channel.name(),
                local_fallbacks = c.local_fallbacks,
                duplicates = c.duplicates,
                refused = c.refused,
                answered = c.answered,
                "remote link: decisions made by the vehicle's own fallback, duplicated or refused answers"
            );
        }
    }
}
