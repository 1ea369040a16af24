//! The one transport interface the planner is reached through.
//!
//! The simulation loop only sees [`PlannerLink`]; implementations: [`InProcess`], which owns
//! a [`decision::Planner`], and [`RemoteLink`], which asks a `planner serve` process through
//! a [`PlanChannel`]: [`ZenohChannel`] or [`Iceoryx2Channel`]. [`Transport`] picks one.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;
use std::time::{Duration, Instant};

use decision::{Decision, DecisionError, Planner, PlannerConfig, Situation};
use protocol::{PlanRequest, PlanResponse};
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
    /// The run is over (a load test's duration ran out); not a failure.
    #[error("stopped: the run is over")]
    Stopped,
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
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum Transport {
    /// Direct call in the same thread.
    #[default]
    InProcess,
    /// A `planner serve` process over Zenoh.
    Zenoh(ZenohTarget),
    /// A `planner serve --iceoryx2` process on this machine, over shared memory.
    Iceoryx2 {
        /// Shared-memory file prefix of the planner (`--iceoryx2-prefix`); iceoryx2's default
        /// when `None`.
        prefix: Option<String>,
    },
}

/// Where a Zenoh planner is: an endpoint, a Zenoh configuration file, or both (the endpoint
/// then replaces the file's `connect` endpoints).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ZenohTarget {
    /// E.g. `tcp/127.0.0.1:7447`.
    pub endpoint: Option<String>,
    /// A zenohd-style JSON5 file, e.g. `deploy/zenoh/client.json5`.
    pub config_file: Option<PathBuf>,
}

impl FromStr for Transport {
    type Err = LinkError;

    /// `inproc`, `iceoryx2` (default prefix) or `zenoh` (with no target yet: the command line
    /// adds it from `--zenoh-connect` / `--zenoh-config`).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "inproc" => Ok(Transport::InProcess),
            "iceoryx2" => Ok(Transport::Iceoryx2 { prefix: None }),
            "zenoh" => Ok(Transport::Zenoh(ZenohTarget::default())),
            other => Err(LinkError::Transport(format!(
                "unknown transport `{other}`; expected `inproc`, `iceoryx2` or `zenoh`"
            ))),
        }
    }
}

impl fmt::Display for Transport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Transport::InProcess => f.write_str("inproc"),
            Transport::Zenoh(_) => f.write_str("zenoh"),
            Transport::Iceoryx2 { .. } => f.write_str("iceoryx2"),
        }
    }
}

impl Transport {
    /// Opens a link to a planner with `config`. Call it on the thread that will use the link.
    pub fn connect(&self, config: PlannerConfig) -> Result<Box<dyn PlannerLink>, LinkError> {
        self.connect_with(config, LinkOptions::default())
    }

    /// [`Transport::connect`] with explicit link settings.
    pub fn connect_with(&self, config: PlannerConfig, options: LinkOptions) -> Result<Box<dyn PlannerLink>, LinkError> {
        match self {
            Transport::InProcess => Ok(Box::new(InProcess::new(config)?)),
            _ => {
                let channel = self.open_channel(&config, &options)?;
                Ok(Box::new(RemoteLink::new(channel, config, options)))
            }
        }
    }

    /// The request/answer channel of the transport; for `inproc` a planner with `config` in
    /// this thread, answering through the same message conversions as the service.
    pub fn open_channel(
        &self,
        config: &PlannerConfig,
        options: &LinkOptions,
    ) -> Result<Box<dyn PlanChannel>, LinkError> {
        match self {
            Transport::InProcess => Ok(Box::new(InProcessChannel {
                planner: Planner::new(config.clone())?,
            })),
            Transport::Zenoh(target) => Ok(Box::new(ZenohChannel::connect(target, options)?)),
            Transport::Iceoryx2 { prefix } => Ok(Box::new(Iceoryx2Channel::connect(prefix.clone(), options)?)),
        }
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
    /// How long after the deadline a channel still listens for a (late) answer before the
    /// request counts as lost (Zenoh's query timeout is `deadline + answer_grace`).
    pub answer_grace: Duration,
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
            vehicle_id: u64::from(std::process::id()),
        }
    }
}

/// What came back for one request over a [`PlanChannel`].
#[derive(Debug, Clone, Default)]
pub struct Answer {
    /// The first valid answer that arrived in time.
    pub response: Option<PlanResponse>,
    /// When it arrived (a channel may wait longer, to count duplicates).
    pub answered_at: Option<Instant>,
    /// Answers beyond the first (0 with a correct planner: one request, one answer).
    pub extra_responses: usize,
}

/// A request/answer channel to a planner process: one request at a time.
pub trait PlanChannel {
    /// Sends `request` and waits up to `wait` for its answer.
    fn exchange(&mut self, request: PlanRequest, wait: Duration) -> Result<Answer, LinkError>;
    /// The transport's name (`zenoh`, `iceoryx2`).
    fn name(&self) -> &'static str;
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

fn zenoh_target_config(target: &ZenohTarget) -> Result<zenoh::Config, LinkError> {
    let err = |e: String| LinkError::Transport(format!("zenoh configuration: {e}"));
    match (&target.config_file, &target.endpoint) {
        (None, None) => Err(LinkError::Transport(
            "transport `zenoh` needs `--zenoh-connect ENDPOINT`, `--zenoh-config FILE` or `--spawn-planner`".into(),
        )),
        (None, Some(endpoint)) => zenoh_client_config(endpoint),
        (Some(file), endpoint) => {
            let mut config = zenoh::Config::from_file(file).map_err(|e| err(format!("{}: {e}", file.display())))?;
            if let Some(endpoint) = endpoint {
                let json = serde_json::to_string(&[endpoint]).map_err(|e| err(e.to_string()))?;
                config
                    .insert_json5("connect/endpoints", &json)
                    .map_err(|e| err(e.to_string()))?;
            }
            Ok(config)
        }
    }
}

/// Requests as Zenoh queries on `hmdp/planner/plan` (bincode payloads).
pub struct ZenohChannel {
    session: zenoh::Session,
    querier: zenoh::query::Querier<'static>,
}

impl ZenohChannel {
    /// Opens a session to `target` and waits (up to `options.ready_timeout`) until a planner
    /// answers a probe.
    pub fn connect(target: &ZenohTarget, options: &LinkOptions) -> Result<Self, LinkError> {
        let give_up = Instant::now() + options.ready_timeout;
        let where_ = target
            .endpoint
            .clone()
            .or_else(|| target.config_file.as_ref().map(|f| f.display().to_string()))
            .unwrap_or_default();
        let session = loop {
            match zenoh::open(zenoh_target_config(target)?).wait() {
                Ok(s) => break s,
                Err(e) if Instant::now() >= give_up => {
                    return Err(LinkError::Transport(format!(
                        "cannot reach the planner at {where_}: {e}"
                    )))
                }
                Err(_) => std::thread::sleep(Duration::from_millis(100)),
            }
        };
        let querier = session
            .declare_querier(protocol::ZENOH_PLAN_KEY)
            .timeout(options.deadline + options.answer_grace)
            .consolidation(zenoh::query::ConsolidationMode::None)
            .wait()
            .map_err(|e| LinkError::Transport(format!("declaring the querier: {e}")))?;
        let channel = Self { session, querier };
        // Readiness: an empty query must come back rejected (`malformed`).
        loop {
            if channel.ask(&[], Duration::from_millis(500)).response.is_some() {
                break;
            }
            if Instant::now() >= give_up {
                return Err(LinkError::Transport(format!("the planner at {where_} does not answer")));
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        Ok(channel)
    }

    /// One query: the first decodable answer within `wait`, and how many more came.
    fn ask(&self, bytes: &[u8], wait: Duration) -> Answer {
        let deadline = Instant::now() + wait;
        let mut answer = Answer::default();
        let Ok(replies) = self
            .querier
            .get()
            .payload(bytes.to_vec())
            .encoding(zenoh::bytes::Encoding::from(protocol::ENCODING_BINCODE))
            .wait()
        else {
            return answer;
        };
        // The query ends when every queryable has answered (or at the querier's timeout);
        // answers after the first are counted, not used.
        while let Ok(Some(reply)) = replies.recv_deadline(deadline) {
            let Ok(sample) = reply.result() else { continue };
            match protocol::decode_bincode::<PlanResponse>(&sample.payload().to_bytes()) {
                Ok(response) if answer.response.is_none() => {
                    answer.response = Some(response);
                    answer.answered_at = Some(Instant::now());
                }
                Ok(_) => answer.extra_responses += 1,
                Err(e) => tracing::warn!("undecodable answer: {e}"),
            }
            if answer.response.is_some() && deadline <= Instant::now() {
                break;
            }
        }
        answer
    }

    /// The Zenoh session (to declare more entities on it).
    pub fn session(&self) -> &zenoh::Session {
        &self.session
    }
}

impl PlanChannel for ZenohChannel {
    fn exchange(&mut self, request: PlanRequest, wait: Duration) -> Result<Answer, LinkError> {
        Ok(self.ask(&protocol::encode_bincode(&request), wait))
    }

    fn name(&self) -> &'static str {
        "zenoh"
    }
}

/// Requests answered by a planner in this thread: the baseline a transport's share is measured
/// against (validation and message conversions included, as in the service).
pub struct InProcessChannel {
    planner: Planner,
}

impl PlanChannel for InProcessChannel {
    fn exchange(&mut self, request: PlanRequest, _wait: Duration) -> Result<Answer, LinkError> {
        let started = Instant::now();
        let response = match request.validate() {
            Err(rejected) => PlanResponse::rejected(request.vehicle_id, request.sequence, rejected, 0),
            Ok(()) => match self.planner.decide(&request.to_situation()) {
                Ok(decision) => PlanResponse::from_decision(&request, &decision, 0)
                    .map_err(|e| LinkError::Transport(format!("encoding the decision: {e}")))?,
                Err(e) => PlanResponse::rejected(
                    request.vehicle_id,
                    request.sequence,
                    protocol::Rejected::from(&e),
                    u32::try_from(started.elapsed().as_micros()).unwrap_or(u32::MAX),
                ),
            },
        };
        Ok(Answer {
            response: Some(response),
            answered_at: Some(Instant::now()),
            extra_responses: 0,
        })
    }

    fn name(&self) -> &'static str {
        "inproc"
    }
}

/// Requests over iceoryx2 shared memory (zero copy: the request is written in place).
pub struct Iceoryx2Channel {
    client: iceoryx2_transport::Client,
}

impl Iceoryx2Channel {
    /// Opens the planner's iceoryx2 services under `prefix` and waits (up to
    /// `options.ready_timeout`) until a planner answers a probe.
    pub fn connect(prefix: Option<String>, options: &LinkOptions) -> Result<Self, LinkError> {
        let give_up = Instant::now() + options.ready_timeout;
        let client_options = iceoryx2_transport::ClientOptions {
            prefix,
            ready_timeout: options.ready_timeout,
            node_name: format!("hmdp-vehicle-{}", options.vehicle_id),
        };
        let client =
            iceoryx2_transport::Client::connect(&client_options).map_err(|e| LinkError::Transport(e.to_string()))?;
        let mut channel = Self { client };
        // The services can exist before the planner's server port does: an empty request
        // (which comes back rejected) tells when it serves.
        let probe = PlanRequest::new(
            options.vehicle_id,
            0,
            0,
            protocol::Road::default(),
            protocol::EgoState::default(),
        );
        loop {
            if channel
                .exchange(probe.clone(), Duration::from_millis(500))?
                .response
                .is_some()
            {
                return Ok(channel);
            }
            if Instant::now() >= give_up {
                return Err(LinkError::Transport("the planner over iceoryx2 does not answer".into()));
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl PlanChannel for Iceoryx2Channel {
    fn exchange(&mut self, request: PlanRequest, wait: Duration) -> Result<Answer, LinkError> {
        let exchange = self
            .client
            .request(request, wait)
            .map_err(|e| LinkError::Transport(e.to_string()))?;
        Ok(Answer {
            answered_at: exchange.response.as_ref().map(|_| Instant::now()),
            response: exchange.response,
            extra_responses: exchange.extra_responses,
        })
    }

    fn name(&self) -> &'static str {
        "iceoryx2"
    }
}

/// The decision a response carries (a watchdog answer becomes a `Fallback` decision).
pub fn decision_from_response(config: &PlannerConfig, response: &PlanResponse) -> Result<Decision, LinkError> {
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
            let next_maneuver: decision::Maneuver = d.next_maneuver.into();
            let first_speed = d.plan.iter().next().map(|s| s.v_mps);
            let accel = match next_maneuver.beta {
                -1 => config.ego.decel_mps2,
                1 => config.ego.accel_mps2,
                _ => 0.0,
            };
            Ok(Decision {
                action: d.action.into(),
                next_maneuver,
                setpoint: decision::SetPoint {
                    accel_mps2: accel,
                    target_speed_mps: first_speed.unwrap_or(0.0),
                },
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

/// Counts of a remote link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkCounts {
    /// Answers from the planner.
    pub answered: u64,
    /// Decisions the vehicle made itself (no answer by the deadline).
    pub local_fallbacks: u64,
    /// Answers beyond the first for one request (0 with a correct planner).
    pub duplicates: u64,
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
}

impl PlannerLink for RemoteLink {
    fn decide(&mut self, situation: &Situation) -> Result<Decision, LinkError> {
        self.sequence += 1;
        let asked = Instant::now();
        let timestamp_ns = u64::try_from(self.started.elapsed().as_nanos()).unwrap_or(u64::MAX);
        let mut request = PlanRequest::from_situation(self.options.vehicle_id, self.sequence, timestamp_ns, situation)
            .map_err(|e| LinkError::Transport(format!("encoding the request: {e}")))?;
        let server_deadline = self.options.deadline.saturating_sub(self.options.transport_margin);
        request.deadline_us = u32::try_from(server_deadline.as_micros()).unwrap_or(u32::MAX).max(1);
        let (vehicle_id, sequence) = (request.vehicle_id, request.sequence);
        let wait = self.options.deadline.saturating_sub(asked.elapsed());
        let answer = match self.channel.exchange(request, wait) {
            Ok(answer) => answer,
            Err(e) => {
                tracing::warn!(sequence, "{} request failed: {e}", self.channel.name());
                Answer::default()
            }
        };
        self.counts.duplicates += answer.extra_responses as u64;
        match answer.response {
            Some(response) if response.vehicle_id == vehicle_id && response.sequence == sequence => {
                self.counts.answered += 1;
                decision_from_response(&self.config, &response)
            }
            _ => {
                self.counts.local_fallbacks += 1;
                tracing::warn!(sequence, "no answer from the planner by the deadline: local fallback");
                Ok(decision::fallback_only(&self.config, situation)?)
            }
        }
    }
}

impl Drop for RemoteLink {
    fn drop(&mut self) {
        let c = self.counts;
        if c.local_fallbacks > 0 || c.duplicates > 0 {
            tracing::warn!(
                transport = self.channel.name(),
                local_fallbacks = c.local_fallbacks,
                duplicates = c.duplicates,
                answered = c.answered,
                "remote link: decisions made by the vehicle's own fallback or duplicated answers"
            );
        }
    }
}
