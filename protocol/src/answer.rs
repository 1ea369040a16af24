//! The one path from a request to its answer (feature `decision`), shared by the service's
//! workers and watchdog, the in-process channel and the vehicle's own fallback:
//!
//! 1. [`PlanRequest::validate`] runs every check once, the wire's first
//!    ([`PlanRequest::check_wire`]), then the decision core's against the planner's
//!    configuration, and gives a [`ValidRequest`] or an [`InvalidRequest`];
//! 2. [`answer`] decides a [`ValidRequest`]; [`fallback_answer`] answers it with the
//!    deterministic fallback, unsolved. Neither checks anything again.

use crate::enums::{Layer, RejectReason};
use crate::messages::{Decided, PlanRequest, PlanResponse, Rejected};

/// A request that passed every check, with the situation the decision core decides on.
#[derive(Debug, Clone)]
pub struct ValidRequest {
    request: PlanRequest,
    situation: decision::ValidSituation,
}

impl ValidRequest {
    /// The request as it came (ids, deadline, send time).
    pub fn request(&self) -> &PlanRequest {
        &self.request
    }

    /// The checked situation, measurement tolerances applied.
    pub fn situation(&self) -> &decision::ValidSituation {
        &self.situation
    }
}

/// A request that failed a check: its ids and the typed rejection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InvalidRequest {
    pub vehicle_id: u64,
    pub sequence: u64,
    pub rejected: Rejected,
}

impl InvalidRequest {
    /// The rejection as an answer (`queue_us` 0).
    pub fn response(&self) -> PlanResponse {
        PlanResponse::rejected(self.vehicle_id, self.sequence, self.rejected, 0)
    }
}

impl PlanRequest {
    /// Every check of the request, once: the wire's, then the decision core's input checks
    /// against `config` (its lane count and horizon bound the request).
    pub fn validate(self, config: &decision::PlannerConfig) -> Result<ValidRequest, InvalidRequest> {
        let invalid = |rejected| InvalidRequest {
            vehicle_id: self.vehicle_id,
            sequence: self.sequence,
            rejected,
        };
        self.check_wire().map_err(invalid)?;
        match decision::ValidSituation::new(config, &self.to_situation()) {
            Ok(situation) => Ok(ValidRequest {
                request: self,
                situation,
            }),
            Err(e) => Err(invalid(Rejected::from(&e))),
        }
    }
}

/// The planner's answer to `request`: the decision, in wire form. `queue_us` is 0 (the caller
/// sets it when the request waited).
pub fn answer(planner: &mut decision::Planner, request: &ValidRequest) -> PlanResponse {
    let ids = (request.request.vehicle_id, request.request.sequence);
    match planner.decide_valid(&request.situation) {
        Ok(decision) => {
            PlanResponse::from_decision(&request.request, &decision, 0).unwrap_or_else(|_| internal_error(ids))
        }
        Err(e) => PlanResponse::rejected(ids.0, ids.1, Rejected::from(&e), 0),
    }
}

/// The deterministic fallback for `request`, unsolved, marked `layer`:
/// [`Layer::WatchdogFallback`] when a deadline runs out or the service sheds load,
/// [`Layer::StaleFallback`] for a request that arrived too old, [`Layer::Fallback`] for a
/// vehicle's own. `solve_us` and `queue_us` are 0.
pub fn fallback_answer(config: &decision::PlannerConfig, request: &ValidRequest, layer: Layer) -> PlanResponse {
    let ids = (request.request.vehicle_id, request.request.sequence);
    let decision = decision::fallback_only(config, &request.situation);
    match Decided::try_from(&decision) {
        Ok(mut decided) => {
            decided.set_layer(layer);
            PlanResponse::decided(ids.0, ids.1, decided, 0, 0)
        }
        Err(_) => internal_error(ids),
    }
}

/// A decision that does not fit the message (cannot happen with a valid configuration).
fn internal_error((vehicle_id, sequence): (u64, u64)) -> PlanResponse {
    PlanResponse::rejected(
        vehicle_id,
        sequence,
        Rejected::new(RejectReason::InternalError, "solver"),
        0,
    )
}
