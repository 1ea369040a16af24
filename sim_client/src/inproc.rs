//! Requests answered by a planner in this thread, through the same path as the service
//! ([`PlanRequest::validate`], then [`protocol::answer`]): the baseline a transport's share
//! is measured against.

use std::time::{Duration, Instant};

use decision::{Planner, PlannerConfig};
use protocol::PlanRequest;

use transport::{Answer, ChannelError, PlanChannel};

use crate::link::LinkError;

/// A planner in this thread (a `Planner` is not `Send`: build the channel where it is used).
pub struct InProcessChannel {
    planner: Planner,
}

impl InProcessChannel {
    /// A planner with `config`.
    pub fn new(config: PlannerConfig) -> Result<Self, LinkError> {
        Ok(Self {
            planner: Planner::new(config)?,
        })
    }

    /// Wraps an existing planner.
    pub fn from_planner(planner: Planner) -> Self {
        Self { planner }
    }

    /// The answer to `request`, at once.
    pub fn answer(&mut self, request: &PlanRequest) -> protocol::PlanResponse {
        match request.clone().validate(self.planner.config()) {
            Ok(valid) => protocol::answer(&mut self.planner, &valid),
            Err(invalid) => invalid.response(),
        }
    }

    /// The planner's configuration.
    pub fn config(&self) -> &PlannerConfig {
        self.planner.config()
    }
}

impl PlanChannel for InProcessChannel {
    fn exchange(&mut self, request: PlanRequest, _wait: Duration) -> Result<Answer, ChannelError> {
        let response = self.answer(&request);
        Ok(Answer {
            response: Some(response),
            answered_at: Some(Instant::now()),
            extra_responses: 0,
            refused: Vec::new(),
            retries: 0,
            mismatched: 0,
        })
    }

    fn name(&self) -> &'static str {
        "inproc"
    }
}
