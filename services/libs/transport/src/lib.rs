//! How a request reaches a planner and its answer comes back.
//!
//! * [`PlanChannel`]: one request at a time, waiting for its answer ([`Answer`]); one
//!   implementation per transport: [`iceoryx2::Iceoryx2Channel`] (shared memory, this
//!   machine) and [`zenoh::ZenohChannel`] (queries, across machines); the simulator adds a
//!   planner in its own thread, the baseline of measurements.
//! * [`iceoryx2`] also holds the planner's server loop; [`zenoh`] builds every Zenoh
//!   configuration (the planner's, the vehicles', the tests').
//! * With the planner's public key ([`protocol::ResponseVerifier`]) a channel refuses every
//!   answer that does not verify ([`Answer::refused`]) and goes on waiting for the real one.
//! * Channels wait at connect until the planner answers a readiness probe
//!   ([`protocol::PlanRequest::probe`], the empty query over Zenoh), which the planner
//!   does not count as a rejection.

pub mod iceoryx2;
pub mod zenoh;

use std::time::{Duration, Instant};

use protocol::{PlanRequest, PlanResponse, VerifyError};
use thiserror::Error;

/// Why a channel could not be opened or a request not be sent.
#[derive(Debug, Error)]
pub enum ChannelError {
    /// The iceoryx2 transport failed.
    #[error(transparent)]
    Iceoryx2(#[from] crate::iceoryx2::TransportError),
    /// A Zenoh configuration could not be built or read.
    #[error("zenoh configuration ({what})")]
    ZenohConfig {
        /// The file or the key at fault.
        what: String,
        #[source]
        source: crate::zenoh::Cause,
    },
    /// Transport `zenoh` without anywhere to go.
    #[error("transport `zenoh` needs `--zenoh-connect ENDPOINT`, `--zenoh-config FILE` or `--spawn-planner`")]
    NoZenohTarget,
    /// A Zenoh session or entity could not be opened.
    #[error("zenoh: {what}")]
    Zenoh {
        what: String,
        #[source]
        source: crate::zenoh::Cause,
    },
    /// No planner key for a session that may reach beyond this host, and no `insecure`:
    /// any peer there could answer and be believed.
    #[error(
        "the planner may be reached beyond this host ({reach}) and its answers cannot be verified: give the \
         planner's public key (sim_client --planner-key FILE), or accept unverified answers with --insecure"
    )]
    UnverifiedRemotePlanner {
        /// The non-loopback endpoints and the scouting that reach beyond.
        reach: String,
    },
    /// A request no planner could receive: Zenoh drops a message that large on the way,
    /// unanswered.
    #[error("a request of {bytes} bytes: the planner receives at most {max} (Zenoh drops larger ones unanswered)")]
    RequestTooLarge { bytes: usize, max: usize },
    /// A channel defined outside this crate failed (the simulator's ROS 2 channel).
    #[error("{transport}")]
    Other {
        /// The transport's name.
        transport: &'static str,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The planner did not answer the readiness probe in time.
    #[error("the planner {at} does not answer")]
    NotReady {
        /// Where it was looked for, e.g. `over iceoryx2` or `at tcp/127.0.0.1:7447`.
        at: String,
    },
}

/// What came back for one request.
#[derive(Debug, Clone, Default)]
pub struct Answer {
    /// The first valid answer that arrived in time.
    pub response: Option<PlanResponse>,
    /// When it arrived (a channel may wait longer, to count duplicates).
    pub answered_at: Option<Instant>,
    /// Answers beyond the first (0 with a correct planner: one request, one answer).
    pub extra_responses: usize,
    /// Answers refused because they did not verify with the planner's key (forged, altered
    /// or unsigned), and why; never taken as the answer.
    pub refused: Vec<VerifyError>,
    /// Times the request was sent again to another planner instance (Zenoh failover, 0 or
    /// 1); the retried instance's answers are discarded once one is taken.
    pub retries: usize,
    /// Answers that reached this channel for another request and were discarded (another
    /// vehicle id or sequence; over iceoryx2 also tagged for another client or exchange);
    /// never taken, 0 with a correct planner.
    pub mismatched: usize,
}

/// A request/answer channel to a planner: one request at a time.
pub trait PlanChannel {
    /// Sends `request` and waits up to `wait` for its answer.
    fn exchange(&mut self, request: PlanRequest, wait: Duration) -> Result<Answer, ChannelError>;
    /// The transport's name (`inproc`, `iceoryx2`, `zenoh`).
    fn name(&self) -> &'static str;
}

/// Repeats `probe` every `pause` until it answers or `ready_timeout` has passed since `since`.
fn await_ready(
    since: Instant,
    ready_timeout: Duration,
    pause: Duration,
    at: impl FnOnce() -> String,
    mut probe: impl FnMut() -> Result<bool, ChannelError>,
) -> Result<(), ChannelError> {
    loop {
        if probe()? {
            return Ok(());
        }
        if since.elapsed() >= ready_timeout {
            return Err(ChannelError::NotReady { at: at() });
        }
        std::thread::sleep(pause);
    }
}
