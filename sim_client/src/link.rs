//! The one transport interface the planner is reached through.
//!
//! The simulation loop only sees [`PlannerLink`]; implementations: [`InProcess`], which owns
//! a [`decision::Planner`], and [`ZenohLink`], which asks a `planner serve` process over
//! Zenoh. iceoryx2 plugs in behind the same trait later, selected through [`Transport`].

use std::fmt;
use std::str::FromStr;

use std::time::{Duration, Instant};

use decision::{Decision, DecisionError, Planner, PlannerConfig, Situation};
use thiserror::Error;
use zenoh::Wait;

/// Why a link could not produce a decision.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum LinkError {
    /// The planner rejected the situation or failed.
    #[error("planner error: {0}")]
    Decision(#[from] DecisionError),
    /// The transport failed (no answer, broken connection, unsupported transport).
    #[error("transport error: {0}")]
    Transport(String),
}

/// A way to ask a planner for a decision. Object safe: the episode loop holds a
/// `&mut dyn PlannerLink`.
pub trait PlannerLink {
    /// One decision for one situation.
    fn decide(&mut self, situation: &Situation) -> Result<Decision, LinkError>;
}

/// The planner in the same process and thread (a `Planner` is not `Send`).
pub struct InProcess {
    planner: Planner,
}

impl InProcess {
    /// Builds a planner from `config`.
    pub fn new(config: PlannerConfig) -> Result<Self, LinkError> {
        Ok(Self {
            planner: Planner::new(config)?,
        })
    }

    /// Wraps an existing planner.
    pub fn from_planner(planner: Planner) -> Self {
        Self { planner }
    }

    /// The planner's configuration.
    pub fn config(&self) -> &PlannerConfig {
        self.planner.config()
    }
}

impl PlannerLink for InProcess {
    fn decide(&mut self, situation: &Situation) -> Result<Decision, LinkError> {
        Ok(self.planner.decide(situation)?)
    }
}

/// Which transport carries situations to the planner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Transport {
    /// Direct call in the same thread.
    #[default]
    InProcess,
    /// A `planner serve` process reached over Zenoh at this endpoint (e.g.
    /// `tcp/127.0.0.1:7447`). Not parsed from a bare name: it needs an endpoint, which the
    /// command line gives with `--zenoh-connect` (the `&'static str` keeps the enum `Copy`).
    Zenoh {
        /// The Zenoh endpoint of the planner service.
        connect: &'static str,
    },
}

/// Transports that are planned but not implemented yet (`zenoh` is implemented but needs an
/// endpoint, see [`Transport::Zenoh`]).
const PLANNED: [&str; 3] = ["iceoryx2", "zenoh", "shm"];

impl FromStr for Transport {
    type Err = LinkError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "inproc" => Ok(Transport::InProcess),
            "zenoh" => Err(LinkError::Transport(
                "transport `zenoh` needs an endpoint: add `--zenoh-connect ENDPOINT` or `--spawn-planner`".into(),
            )),
            other if PLANNED.contains(&other) => Err(LinkError::Transport(format!(
                "transport `{other}` is not implemented yet; the only available transport is `inproc`"
            ))),
            other => Err(LinkError::Transport(format!(
                "unknown transport `{other}`; the only available transport is `inproc`"
            ))),
        }
    }
}

impl fmt::Display for Transport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Transport::InProcess => f.write_str("inproc"),
            Transport::Zenoh { .. } => f.write_str("zenoh"),
        }
    }
}

impl Transport {
    /// Opens a link to a planner with `config`. Call it on the thread that will use the link.
    pub fn connect(self, config: PlannerConfig) -> Result<Box<dyn PlannerLink>, LinkError> {
        match self {
            Transport::InProcess => Ok(Box::new(InProcess::new(config)?)),
            Transport::Zenoh { connect } => Ok(Box::new(ZenohLink::connect(
                connect,
                config,
                ZenohLinkOptions::default(),
            )?)),
        }
    }
}

/// Settings of a [`ZenohLink`].
#[derive(Debug, Clone)]
pub struct ZenohLinkOptions {
    /// The vehicle's deadline: no answer by then and the vehicle applies
    /// `decision::fallback_only` itself.
    pub deadline: Duration,
    /// Part of the deadline kept for the transport: the request asks the planner for
    /// `deadline - transport_margin`, so that the planner's watchdog answers before the
    /// vehicle gives up.
    pub transport_margin: Duration,
    /// How long [`ZenohLink::connect`] waits for the planner to answer a probe.
    pub ready_timeout: Duration,
    /// Sender id put in the requests.
    pub vehicle_id: u64,
}

impl Default for ZenohLinkOptions {
    fn default() -> Self {
        Self {
            deadline: protocol::DEFAULT_DEADLINE,
            transport_margin: Duration::from_millis(20),
            ready_timeout: Duration::from_secs(30),
            vehicle_id: u64::from(std::process::id()),
        }
    }
}

/// Zenoh client configuration: connect to `endpoint` only, no scouting.
pub fn zenoh_client_config(endpoint: &str) -> Result<zenoh::Config, LinkError> {
    let json = serde_json::json!({
        "mode": "client",
        "connect": { "endpoints": [endpoint] },
        "scouting": { "multicast": { "enabled": false }, "gossip": { "enabled": false } },
    });
    zenoh::Config::from_json5(&json.to_string()).map_err(|e| LinkError::Transport(format!("zenoh configuration: {e}")))
}

/// The planner in a `planner serve` process, asked over Zenoh (bincode payloads, one query
/// per decision on `hmdp/planner/plan`).
pub struct ZenohLink {
    config: PlannerConfig,
    options: ZenohLinkOptions,
    session: zenoh::Session,
    querier: zenoh::query::Querier<'static>,
    sequence: u64,
    started: Instant,
    /// Decisions the vehicle made itself (no answer by the deadline).
    pub local_fallbacks: u64,
    /// Answers over Zenoh.
    pub answered: u64,
}

impl ZenohLink {
    /// Opens a client session to `endpoint` and waits (up to `options.ready_timeout`) until
    /// the planner answers a probe. `config` is used for the vehicle's own fallback.
    pub fn connect(endpoint: &str, config: PlannerConfig, options: ZenohLinkOptions) -> Result<Self, LinkError> {
        let give_up = Instant::now() + options.ready_timeout;
        let session = loop {
            match zenoh::open(zenoh_client_config(endpoint)?).wait() {
                Ok(s) => break s,
                Err(e) if Instant::now() >= give_up => {
                    return Err(LinkError::Transport(format!(
                        "cannot reach the planner at {endpoint}: {e}"
                    )))
                }
                Err(_) => std::thread::sleep(Duration::from_millis(100)),
            }
        };
        let querier = session
            .declare_querier(protocol::ZENOH_PLAN_KEY)
            .timeout(options.deadline)
            .consolidation(zenoh::query::ConsolidationMode::None)
            .wait()
            .map_err(|e| LinkError::Transport(format!("declaring the querier: {e}")))?;
        let link = Self {
            config,
            options,
            session,
            querier,
            sequence: 0,
            started: Instant::now(),
            local_fallbacks: 0,
            answered: 0,
        };
        // Readiness: an empty query must come back rejected (`malformed`).
        loop {
            if link.ask(&[], Duration::from_millis(500)).is_some() {
                break;
            }
            if Instant::now() >= give_up {
                return Err(LinkError::Transport(format!(
                    "the planner at {endpoint} does not answer"
                )));
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        Ok(link)
    }

    /// One query; the decoded response, or `None` when nothing valid came back in `wait`.
    fn ask(&self, bytes: &[u8], wait: Duration) -> Option<protocol::PlanResponse> {
        let deadline = Instant::now() + wait;
        let replies = self
            .querier
            .get()
            .payload(bytes.to_vec())
            .encoding(zenoh::bytes::Encoding::from(protocol::ENCODING_BINCODE))
            .wait()
            .ok()?;
        while let Ok(Some(reply)) = replies.recv_deadline(deadline) {
            if let Ok(sample) = reply.result() {
                if let Ok(response) = protocol::decode_bincode::<protocol::PlanResponse>(&sample.payload().to_bytes()) {
                    return Some(response);
                }
            }
        }
        None
    }

    /// The Zenoh session (to declare more entities on it).
    pub fn session(&self) -> &zenoh::Session {
        &self.session
    }
}

/// The decision a response carries (a watchdog answer becomes a `Fallback` decision).
pub fn decision_from_response(
    config: &PlannerConfig,
    response: &protocol::PlanResponse,
) -> Result<Decision, LinkError> {
    use protocol::OutcomeRef;
    match response.outcome.get() {
        Ok(OutcomeRef::Decided(d)) => {
            let layer = match d.layer() {
                Ok(protocol::Layer::Nominal) => decision::Layer::Nominal,
                Ok(protocol::Layer::GlobalRelaxation) => decision::Layer::GlobalRelaxation,
                Ok(protocol::Layer::Fallback) | Ok(protocol::Layer::WatchdogFallback) => decision::Layer::Fallback,
                Err(e) => return Err(LinkError::Transport(format!("bad response: {e}"))),
            };
            let memory = decision::PlannerMemory::from(&d.memory);
            Ok(Decision {
                action: d.action.into(),
                next_maneuver: d.next_maneuver.into(),
                plan: d.plan.iter().map(|&s| s.into()).collect(),
                layer,
                stats: decision::SolveStats {
                    total_us: u64::from(response.solve_us),
                    solve_us: u64::from(response.solve_us),
                    corrective_svs: memory.corrective.len(),
                    ..decision::SolveStats::new(config.solver.backend)
                },
                memory,
            })
        }
        Ok(OutcomeRef::Rejected(r)) => Err(LinkError::Transport(format!(
            "planner rejected the request: {} ({})",
            r.reason()
                .map(|r| r.to_string())
                .unwrap_or_else(|_| format!("code {}", r.reason_code())),
            r.field()
        ))),
        Err(e) => Err(LinkError::Transport(format!("bad response: {e}"))),
    }
}

impl PlannerLink for ZenohLink {
    fn decide(&mut self, situation: &Situation) -> Result<Decision, LinkError> {
        self.sequence += 1;
        let asked = Instant::now();
        let timestamp_ns = u64::try_from(self.started.elapsed().as_nanos()).unwrap_or(u64::MAX);
        let mut request =
            protocol::PlanRequest::from_situation(self.options.vehicle_id, self.sequence, timestamp_ns, situation)
                .map_err(|e| LinkError::Transport(format!("encoding the request: {e}")))?;
        let server_deadline = self.options.deadline.saturating_sub(self.options.transport_margin);
        request.deadline_us = u32::try_from(server_deadline.as_micros()).unwrap_or(u32::MAX).max(1);
        let bytes = protocol::encode_bincode(&request);
        let wait = self.options.deadline.saturating_sub(asked.elapsed());
        match self.ask(&bytes, wait) {
            Some(response) if response.vehicle_id == request.vehicle_id && response.sequence == request.sequence => {
                self.answered += 1;
                decision_from_response(&self.config, &response)
            }
            _ => {
                self.local_fallbacks += 1;
                tracing::warn!(
                    sequence = self.sequence,
                    "no answer from the planner by the deadline: local fallback"
                );
                Ok(decision::fallback_only(&self.config, situation)?)
            }
        }
    }
}

impl Drop for ZenohLink {
    fn drop(&mut self) {
        if self.local_fallbacks > 0 {
            tracing::warn!(
                local_fallbacks = self.local_fallbacks,
                answered = self.answered,
                "zenoh link: decisions made by the vehicle's own fallback"
            );
        }
    }
}
