//! Conversions between the protocol's messages and the ROS messages of [`crate::msg`].
//!
//! protocol -> ROS cannot fail: every protocol value has a ROS form. ROS -> protocol checks
//! only what the ROS types cannot say and the protocol types cannot hold: the bounds of the
//! bounded sequences and of the `field` string (CDR writes them like unbounded ones, so a
//! peer may send more), the outcome kind and the enumeration codes. Those give a
//! [`ConvertError`] carrying the rejection the planner answers with, so that the service
//! can answer a typed rejection. Everything else (version, ranges, NaN, ...) passes through
//! unchanged for the planner's own validation, exactly as over the other transports.

use protocol::{Layer, RejectReason, FIELD_NAME_CAPACITY};
use thiserror::Error;

use crate::msg;

/// A ROS message the protocol cannot hold: the rejection that answers it and the ids it
/// carried.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
#[error("vehicle {vehicle_id} sequence {sequence}: {} `{}`", reason_name(.rejected), .rejected.field())]
pub struct ConvertError {
    pub vehicle_id: u64,
    pub sequence: u64,
    pub rejected: protocol::Rejected,
}

fn reason_name(rejected: &protocol::Rejected) -> &'static str {
    rejected.reason().map_or("unknown reason", RejectReason::name)
}

impl ConvertError {
    fn new(ids: (u64, u64), reason: RejectReason, field: &str) -> Self {
        Self {
            vehicle_id: ids.0,
            sequence: ids.1,
            rejected: protocol::Rejected::new(reason, field),
        }
    }

    /// The rejection answering the request this error came from.
    pub fn to_response(&self) -> protocol::PlanResponse {
        protocol::PlanResponse::rejected(self.vehicle_id, self.sequence, self.rejected, 0)
    }
}

/// A bounded list from a ROS sequence; over its capacity is `capacity_exceeded` naming it.
fn bounded<P: Clone, const N: usize>(
    ids: (u64, u64),
    field: &str,
    items: Vec<P>,
) -> Result<protocol::containers::StaticVec<P, N>, ConvertError> {
    protocol::bounded(field, &items).map_err(|_| ConvertError::new(ids, RejectReason::CapacityExceeded, field))
}

// ---------------------------------------------------------------------------------------
// Leaf types: the same fields on both sides.

impl From<protocol::Road> for msg::Road {
    fn from(r: protocol::Road) -> Self {
        Self {
            lanes: r.lanes,
            lane_width_m: r.lane_width_m,
            speed_limit_mps: r.speed_limit_mps,
        }
    }
}

impl From<msg::Road> for protocol::Road {
    fn from(r: msg::Road) -> Self {
        Self {
            lanes: r.lanes,
            lane_width_m: r.lane_width_m,
            speed_limit_mps: r.speed_limit_mps,
        }
    }
}

impl From<protocol::Maneuver> for msg::Maneuver {
    fn from(m: protocol::Maneuver) -> Self {
        Self {
            lane: m.lane,
            beta: m.beta,
        }
    }
}

impl From<msg::Maneuver> for protocol::Maneuver {
    fn from(m: msg::Maneuver) -> Self {
        Self {
            lane: m.lane,
            beta: m.beta,
        }
    }
}

impl From<protocol::Action> for msg::Action {
    fn from(a: protocol::Action) -> Self {
        Self {
            lateral: a.lateral,
            longitudinal: a.longitudinal,
        }
    }
}

impl From<msg::Action> for protocol::Action {
    fn from(a: msg::Action) -> Self {
        Self {
            lateral: a.lateral,
            longitudinal: a.longitudinal,
        }
    }
}

impl From<protocol::EgoState> for msg::EgoState {
    fn from(e: protocol::EgoState) -> Self {
        Self {
            x_m: e.x_m,
            y_m: e.y_m,
            v_mps: e.v_mps,
            desired_speed_mps: e.desired_speed_mps,
            maneuver: e.maneuver.into(),
        }
    }
}

impl From<msg::EgoState> for protocol::EgoState {
    fn from(e: msg::EgoState) -> Self {
        Self {
            x_m: e.x_m,
            y_m: e.y_m,
            v_mps: e.v_mps,
            desired_speed_mps: e.desired_speed_mps,
            maneuver: e.maneuver.into(),
        }
    }
}

impl From<protocol::SvObservation> for msg::SvObservation {
    fn from(s: protocol::SvObservation) -> Self {
        Self {
            id: s.id,
            x_m: s.x_m,
            y_m: s.y_m,
            v_mps: s.v_mps,
            a_mps2: s.a_mps2,
            vy_mps: s.vy_mps,
            length_m: s.length_m,
            width_m: s.width_m,
        }
    }
}

impl From<msg::SvObservation> for protocol::SvObservation {
    fn from(s: msg::SvObservation) -> Self {
        Self {
            id: s.id,
            x_m: s.x_m,
            y_m: s.y_m,
            v_mps: s.v_mps,
            a_mps2: s.a_mps2,
            vy_mps: s.vy_mps,
            length_m: s.length_m,
            width_m: s.width_m,
        }
    }
}

impl From<protocol::CorrectiveEntry> for msg::CorrectiveEntry {
    fn from(c: protocol::CorrectiveEntry) -> Self {
        Self {
            sv_id: c.sv_id,
            release_m: c.release_m,
            trigger_m: c.trigger_m,
        }
    }
}

impl From<msg::CorrectiveEntry> for protocol::CorrectiveEntry {
    fn from(c: msg::CorrectiveEntry) -> Self {
        Self {
            sv_id: c.sv_id,
            release_m: c.release_m,
            trigger_m: c.trigger_m,
        }
    }
}

impl From<protocol::PlanStep> for msg::PlanStep {
    fn from(s: protocol::PlanStep) -> Self {
        Self {
            action: s.action.into(),
            maneuver: s.maneuver.into(),
            x_m: s.x_m,
            v_mps: s.v_mps,
            occupied_lanes: s.occupied_lanes,
        }
    }
}

impl From<msg::PlanStep> for protocol::PlanStep {
    fn from(s: msg::PlanStep) -> Self {
        Self {
            action: s.action.into(),
            maneuver: s.maneuver.into(),
            x_m: s.x_m,
            v_mps: s.v_mps,
            occupied_lanes: s.occupied_lanes,
        }
    }
}

impl From<protocol::SetPoint> for msg::SetPoint {
    fn from(s: protocol::SetPoint) -> Self {
        Self {
            accel_mps2: s.accel_mps2,
            target_speed_mps: s.target_speed_mps,
        }
    }
}

impl From<msg::SetPoint> for protocol::SetPoint {
    fn from(s: msg::SetPoint) -> Self {
        Self {
            accel_mps2: s.accel_mps2,
            target_speed_mps: s.target_speed_mps,
        }
    }
}

// ---------------------------------------------------------------------------------------
// Lists and messages.

fn list<P: Clone + Into<R>, R>(items: &[P]) -> Vec<R> {
    items.iter().cloned().map(Into::into).collect()
}

fn to_items<R: Into<P>, P>(items: Vec<R>) -> Vec<P> {
    items.into_iter().map(Into::into).collect()
}

impl From<&protocol::PlannerMemory> for msg::PlannerMemory {
    fn from(m: &protocol::PlannerMemory) -> Self {
        Self {
            corrective: list(&m.corrective),
            previous_plan: list(&m.previous_plan),
        }
    }
}

fn memory_from_msg(ids: (u64, u64), m: msg::PlannerMemory) -> Result<protocol::PlannerMemory, ConvertError> {
    Ok(protocol::PlannerMemory {
        corrective: bounded(ids, "memory.corrective", to_items(m.corrective))?,
        previous_plan: bounded(ids, "memory.previous_plan", to_items(m.previous_plan))?,
    })
}

impl From<&protocol::PlanRequest> for msg::PlanRequest {
    fn from(r: &protocol::PlanRequest) -> Self {
        Self {
            version: r.version,
            vehicle_id: r.vehicle_id,
            sequence: r.sequence,
            timestamp_ns: r.timestamp_ns,
            deadline_us: r.deadline_us,
            sent_at_ns: r.sent_at_ns,
            road: r.road.into(),
            ego: r.ego.into(),
            svs: list(&r.svs),
            memory: (&r.memory).into(),
        }
    }
}

impl TryFrom<msg::PlanRequest> for protocol::PlanRequest {
    type Error = ConvertError;

    /// Over capacity: `svs` (64), `memory.corrective` (16), `memory.previous_plan` (6).
    fn try_from(r: msg::PlanRequest) -> Result<Self, ConvertError> {
        let ids = (r.vehicle_id, r.sequence);
        Ok(Self {
            version: r.version,
            vehicle_id: r.vehicle_id,
            sequence: r.sequence,
            timestamp_ns: r.timestamp_ns,
            deadline_us: r.deadline_us,
            sent_at_ns: r.sent_at_ns,
            road: r.road.into(),
            ego: r.ego.into(),
            svs: bounded(ids, "svs", to_items(r.svs))?,
            memory: memory_from_msg(ids, r.memory)?,
        })
    }
}

impl From<&protocol::Decided> for msg::Decided {
    fn from(d: &protocol::Decided) -> Self {
        Self {
            action: d.action.into(),
            next_maneuver: d.next_maneuver.into(),
            setpoint: d.setpoint.into(),
            plan: list(&d.plan),
            layer: d.layer_code(),
            memory: (&d.memory).into(),
        }
    }
}

impl From<&protocol::Rejected> for msg::Rejected {
    fn from(r: &protocol::Rejected) -> Self {
        Self {
            reason: r.reason_code(),
            field: r.field().to_owned(),
        }
    }
}

impl From<&protocol::PlanResponse> for msg::PlanResponse {
    fn from(r: &protocol::PlanResponse) -> Self {
        Self {
            version: r.version,
            vehicle_id: r.vehicle_id,
            sequence: r.sequence,
            solve_us: r.solve_us,
            queue_us: r.queue_us,
            outcome: r.outcome.kind_code(),
            decided: r.outcome.as_decided().map(Into::into).unwrap_or_default(),
            rejected: r.outcome.as_rejected().map(Into::into).unwrap_or_default(),
            signature: r.signature.0,
        }
    }
}

fn decided_from_msg(ids: (u64, u64), d: msg::Decided) -> Result<protocol::Decided, ConvertError> {
    let layer = Layer::from_code(d.layer).ok_or_else(|| ConvertError::new(ids, RejectReason::Malformed, "layer"))?;
    Ok(protocol::Decided::new(
        d.action.into(),
        d.next_maneuver.into(),
        d.setpoint.into(),
        bounded(ids, "plan", to_items(d.plan))?,
        layer,
        memory_from_msg(ids, d.memory)?,
    ))
}

fn rejected_from_msg(ids: (u64, u64), r: msg::Rejected) -> Result<protocol::Rejected, ConvertError> {
    let reason =
        RejectReason::from_code(r.reason).ok_or_else(|| ConvertError::new(ids, RejectReason::Malformed, "reason"))?;
    if r.field.len() > FIELD_NAME_CAPACITY {
        return Err(ConvertError::new(ids, RejectReason::CapacityExceeded, "field"));
    }
    // The protocol's field is ASCII without NUL (docs/protocol.md, "string<N>").
    if !r.field.bytes().all(|b| (1..128).contains(&b)) {
        return Err(ConvertError::new(ids, RejectReason::Malformed, "field"));
    }
    Ok(protocol::Rejected::new(reason, &r.field))
}

impl TryFrom<msg::PlanResponse> for protocol::PlanResponse {
    type Error = ConvertError;

    /// Checks the outcome kind and the active body only (the other one is ignored): layer and
    /// reason codes, `plan` (6), the memory's lists, `field` (31 ASCII bytes).
    fn try_from(r: msg::PlanResponse) -> Result<Self, ConvertError> {
        let ids = (r.vehicle_id, r.sequence);
        let outcome = match r.outcome {
            msg::PlanResponse::OUTCOME_DECIDED => protocol::Outcome::decided(decided_from_msg(ids, r.decided)?),
            msg::PlanResponse::OUTCOME_REJECTED => protocol::Outcome::rejected(rejected_from_msg(ids, r.rejected)?),
            _ => return Err(ConvertError::new(ids, RejectReason::Malformed, "outcome")),
        };
        Ok(Self {
            version: r.version,
            vehicle_id: r.vehicle_id,
            sequence: r.sequence,
            solve_us: r.solve_us,
            queue_us: r.queue_us,
            outcome,
            signature: protocol::Signature(r.signature),
        })
    }
}

impl From<&protocol::PlanRequest> for msg::PlanServiceRequest {
    fn from(r: &protocol::PlanRequest) -> Self {
        Self { request: r.into() }
    }
}

impl From<&protocol::PlanResponse> for msg::PlanServiceResponse {
    fn from(r: &protocol::PlanResponse) -> Self {
        Self { response: r.into() }
    }
}
