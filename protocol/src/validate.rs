//! Checks that need nothing but the message: what a zero-copy receiver (which skips the
//! decoders) must run before trusting a payload, and what a sender can check before sending.
//! The planner's own plausibility checks (finite numbers, lanes on the road, unique ids)
//! stay in the decision core and come back as [`RejectReason`]s 10..=29.

use iceoryx2_bb_container::vector::Vector;

use crate::enums::{Layer, RejectReason};
use crate::messages::{
    Action, Decided, OutcomeRef, PlanRequest, PlanResponse, PlannerMemory, MAX_CORRECTIVE, MAX_HORIZON, MAX_SVS,
    PROTOCOL_VERSION,
};
use crate::{Rejected, WireError};

fn unit(v: i8) -> bool {
    (-1..=1).contains(&v)
}

fn action_ok(a: &Action) -> bool {
    unit(a.lateral) && unit(a.longitudinal)
}

/// Lengths first: a length beyond capacity (only possible in corrupted shared memory) must
/// be caught before any slice of the list is formed.
fn check_memory(memory: &PlannerMemory, prefix: &str) -> Result<(), Rejected> {
    if memory.corrective.len() > MAX_CORRECTIVE {
        return Err(Rejected::new(
            RejectReason::CapacityExceeded,
            &format!("{prefix}memory.corrective"),
        ));
    }
    if memory.previous_plan.len() > MAX_HORIZON {
        return Err(Rejected::new(
            RejectReason::CapacityExceeded,
            &format!("{prefix}memory.previous_plan"),
        ));
    }
    if !memory.previous_plan.iter().all(action_ok) {
        return Err(Rejected::new(
            RejectReason::InvalidMemory,
            &format!("{prefix}memory.previous_plan"),
        ));
    }
    Ok(())
}

impl PlanRequest {
    /// The checks the message alone allows: version, list lengths and the enum-like values
    /// (`beta`, previous actions in `-1..=1`). The rejection names the field, e.g.
    /// `(UnsupportedVersion, "version")`. A sender can run it before sending; the planner
    /// runs it first in `PlanRequest::validate`.
    pub fn check_wire(&self) -> Result<(), Rejected> {
        if self.version != PROTOCOL_VERSION {
            return Err(Rejected::new(RejectReason::UnsupportedVersion, "version"));
        }
        if self.svs.len() > MAX_SVS {
            return Err(Rejected::new(RejectReason::CapacityExceeded, "svs"));
        }
        check_memory(&self.memory, "")?;
        if !unit(self.ego.maneuver.beta) {
            return Err(Rejected::new(RejectReason::BetaOutOfRange, "ego.maneuver.beta"));
        }
        Ok(())
    }
}

impl PlanResponse {
    /// Checks version, outcome kind, layer and reason codes, list lengths, and that actions
    /// and longitudinal states are in `-1..=1`.
    pub fn validate(&self) -> Result<(), WireError> {
        if self.version != PROTOCOL_VERSION {
            return Err(WireError::UnsupportedVersion {
                found: self.version,
                supported: PROTOCOL_VERSION,
            });
        }
        match self.outcome.get()? {
            OutcomeRef::Decided(d) => validate_decided(d),
            OutcomeRef::Rejected(r) => r.reason().map(|_| ()),
        }
    }
}

fn validate_decided(d: &Decided) -> Result<(), WireError> {
    let _: Layer = d.layer()?;
    if d.plan.len() > MAX_HORIZON {
        return Err(WireError::CapacityExceeded(format!(
            "`plan` has {} steps, capacity {MAX_HORIZON}",
            d.plan.len()
        )));
    }
    check_memory(&d.memory, "").map_err(|r| match r.reason() {
        Ok(RejectReason::CapacityExceeded) => WireError::CapacityExceeded(r.field().to_owned()),
        _ => WireError::Malformed(format!("`{}` holds an action outside -1..=1", r.field())),
    })?;
    let actions_ok = action_ok(&d.action) && d.plan.iter().all(|s| action_ok(&s.action));
    let betas_ok = unit(d.next_maneuver.beta) && d.plan.iter().all(|s| unit(s.maneuver.beta));
    if !(actions_ok && betas_ok) {
        return Err(WireError::Malformed(
            "an action or a longitudinal state of the plan is outside -1..=1".to_owned(),
        ));
    }
    Ok(())
}
