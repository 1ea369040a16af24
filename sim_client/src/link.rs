//! The one transport interface the planner is reached through.
//!
//! The simulation loop only sees [`PlannerLink`]; today the only implementation is
//! [`InProcess`], which owns a [`decision::Planner`]. Inter-process transports (iceoryx2,
//! Zenoh) plug in behind the same trait later, selected through [`Transport`].

use std::fmt;
use std::str::FromStr;

use decision::{Decision, DecisionError, Planner, PlannerConfig, Situation};
use thiserror::Error;

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
}

/// Transports that are planned but not implemented yet.
const PLANNED: [&str; 3] = ["iceoryx2", "zenoh", "shm"];

impl FromStr for Transport {
    type Err = LinkError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "inproc" => Ok(Transport::InProcess),
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
        }
    }
}

impl Transport {
    /// Opens a link to a planner with `config`. Call it on the thread that will use the link.
    pub fn connect(self, config: PlannerConfig) -> Result<Box<dyn PlannerLink>, LinkError> {
        match self {
            Transport::InProcess => Ok(Box::new(InProcess::new(config)?)),
        }
    }
}
