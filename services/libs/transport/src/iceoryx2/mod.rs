//! The protocol over iceoryx2: zero-copy shared memory between processes on one machine.
//!
//! * Data: the request-response service [`protocol::ICEORYX2_PLAN_SERVICE`] carrying
//!   [`PlanRequest`] / [`PlanResponse`] in place (no serialisation).
//! * Wake-ups: iceoryx2 request-response has no blocking receive, so two event services pair
//!   with it. Clients notify [`protocol::ICEORYX2_PLAN_REQUEST_EVENT_SERVICE`] after sending,
//!   which wakes the server; the server notifies
//!   [`protocol::ICEORYX2_PLAN_RESPONSE_EVENT_SERVICE`] after answering, which wakes the
//!   clients. Nobody polls.
//! * Threads: the `ipc_threadsafe` service variant, so that an answer can be sent from the
//!   thread that produced it (a solver worker or the watchdog) while the server thread keeps
//!   receiving.
//! * Addressing: every request and answer carries an [`ExchangeTag`] (the iceoryx2 user
//!   header). iceoryx2 0.10 sends an answer through the connection slot its request came in
//!   on, and gives a killed client's slot to the next client that opens the service: without
//!   more, a late answer to a killed vehicle can reach a new one. The server therefore
//!   answers only clients that are still there, and a client takes only answers tagged with
//!   its own port id and exchange number.
//! * Crashes: a process killed with SIGKILL leaves its node's shared memory behind; both sides
//!   remove dead nodes' resources when they start (see [`dead_nodes`]).

mod channel;
mod client;
mod server;

pub use channel::Iceoryx2Channel;
pub use client::{Client, ClientOptions, Exchange};
pub use server::{serve, Responder, ServerOptions, WaitMode};

pub use iceoryx2::config::Config as IceoryxConfig;
use iceoryx2::config::Config;
use iceoryx2::prelude::*;
use thiserror::Error;

/// The iceoryx2 service variant of every port here.
pub type Ipc = ipc_threadsafe::Service;

/// The iceoryx2 user header of every request and answer: which client port sent the request
/// and which of its exchanges it is. The client writes its own port id and a counter; the
/// server answers with the port id iceoryx2 itself names as the request's origin and the
/// echoed counter; the client takes nothing that does not carry both of its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ZeroCopySend)]
#[repr(C)]
#[type_name("hmdp::ExchangeTag/v1")]
pub struct ExchangeTag {
    /// The client port's `UniqueClientId` (system-wide unique: process id, monotonic time
    /// and a counter).
    pub client: u128,
    /// The client's count of its requests, from 1.
    pub exchange: u64,
}

/// iceoryx2's own error of a failed call, kept as the source.
pub type Cause = Box<dyn std::error::Error + Send + Sync>;

/// Failures of the iceoryx2 transport; iceoryx2's own error (a different type per call) is
/// the source.
#[derive(Debug, Error)]
pub enum TransportError {
    /// The prefix is not a valid file name.
    #[error("iceoryx2 prefix `{prefix}` is not a valid file name")]
    Prefix {
        prefix: String,
        #[source]
        source: Cause,
    },
    /// A node, service or port could not be created or opened.
    #[error("iceoryx2 setup ({what})")]
    Setup {
        what: &'static str,
        #[source]
        source: Cause,
    },
    /// The planner's service does not exist (no planner running under this prefix).
    #[error("no planner service `{service}` (is `planner serve --iceoryx2` running with the same prefix?)")]
    NoService { service: &'static str },
    /// The planner's service exists with other message types (another release of the
    /// planner serves this prefix).
    #[error(
        "the planner service `{service}` has other message types (a planner of another release serves this prefix)"
    )]
    Incompatible { service: &'static str },
    /// The client that sent the request is gone (killed, or its port closed): the answer is
    /// not sent, since its connection slot may already belong to another client.
    #[error("the requesting client is gone: answer not sent")]
    ClientGone,
    /// Sending a request or a response, or notifying its event, failed.
    #[error("iceoryx2 send ({what})")]
    Send {
        what: &'static str,
        #[source]
        source: Cause,
    },
    /// Receiving or waiting failed.
    #[error("iceoryx2 receive ({what})")]
    Receive {
        what: &'static str,
        #[source]
        source: Cause,
    },
}

fn setup<E: std::error::Error + Send + Sync + 'static>(what: &'static str) -> impl FnOnce(E) -> TransportError {
    move |e| TransportError::Setup {
        what,
        source: Box::new(e),
    }
}

fn send<E: std::error::Error + Send + Sync + 'static>(what: &'static str) -> impl FnOnce(E) -> TransportError {
    move |e| TransportError::Send {
        what,
        source: Box::new(e),
    }
}

fn receive<E: std::error::Error + Send + Sync + 'static>(what: &'static str) -> impl FnOnce(E) -> TransportError {
    move |e| TransportError::Receive {
        what,
        source: Box::new(e),
    }
}

/// The iceoryx2 configuration: the defaults with `prefix` (when given) as the prefix of every
/// shared-memory file, so that independent deployments (or tests) on one machine do not see
/// each other. Planner and clients must use the same prefix.
pub fn config(prefix: Option<&str>) -> Result<Config, TransportError> {
    let mut config = Config::default();
    if let Some(prefix) = prefix {
        config.global.prefix = FileName::new(prefix.as_bytes()).map_err(|e| TransportError::Prefix {
            prefix: prefix.to_owned(),
            source: Box::new(e),
        })?;
    }
    Ok(config)
}

/// Nodes under `config`'s prefix whose process died without cleaning up (e.g. killed with
/// SIGKILL): their shared memory is still there until a node is created or a service opened.
pub fn dead_nodes(config: &Config) -> usize {
    let mut dead = 0;
    let result = Node::<Ipc>::list(config, |state| {
        if let NodeState::Dead(_) = state {
            dead += 1;
        }
        CallbackProgression::Continue
    });
    if let Err(e) = result {
        tracing::warn!("cannot list iceoryx2 nodes: {e}");
    }
    dead
}

/// iceoryx2 logs through its own logger; keep it to warnings unless `IOX2_LOG_LEVEL` says
/// otherwise.
fn quiet_iceoryx2_log() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| set_log_level_from_env_or(LogLevel::Warn));
}

fn node(config: &Config, name: &str) -> Result<Node<Ipc>, TransportError> {
    quiet_iceoryx2_log();
    let name = NodeName::new(name).map_err(setup("node name"))?;
    let node = NodeBuilder::new()
        .name(&name)
        .config(config)
        // The process decides about signals (the planner handles SIGINT/SIGTERM itself).
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<Ipc>()
        .map_err(setup("node"))?;
    // Creating a node already removes dead nodes' resources (iceoryx2's default); this
    // catches the ones another process was busy with, and says so.
    let cleanup = node.try_cleanup_dead_nodes();
    if cleanup.cleanups > 0 || cleanup.failed_cleanups > 0 {
        tracing::info!(
            cleaned = cleanup.cleanups,
            failed = cleanup.failed_cleanups,
            "stale iceoryx2 resources of dead processes"
        );
    }
    Ok(node)
}

fn service_name(name: &'static str) -> Result<ServiceName, TransportError> {
    ServiceName::new(name).map_err(setup("service name"))
}
