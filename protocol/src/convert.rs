//! Conversions between the wire types and the decision core's types (feature `decision`).

use crate::enums::{Layer, RejectReason};
use crate::messages::{
    bounded, Action, CorrectiveEntry, Decided, EgoState, Maneuver, PlanRequest, PlanResponse, PlanStep, PlannerMemory,
    Rejected, Road, SetPoint, SvObservation, PROTOCOL_VERSION,
};
use crate::WireError;

macro_rules! same_fields {
    ($wire:ident <=> $core:path { $($field:ident $(via $conv:ident)?),+ }) => {
        impl From<$core> for $wire {
            fn from(v: $core) -> Self {
                Self { $($field: same_fields!(@conv v.$field $(, $conv)?)),+ }
            }
        }
        impl From<$wire> for $core {
            fn from(v: $wire) -> Self {
                Self { $($field: same_fields!(@conv v.$field $(, $conv)?)),+ }
            }
        }
    };
    (@conv $e:expr) => { $e };
    (@conv $e:expr, into) => { $e.into() };
}

same_fields!(Road <=> decision::Road { lanes, lane_width_m, speed_limit_mps });
same_fields!(Maneuver <=> decision::Maneuver { lane, beta });
same_fields!(Action <=> decision::Action { lateral, longitudinal });
same_fields!(EgoState <=> decision::EgoState { x_m, y_m, v_mps, desired_speed_mps, maneuver via into });
impl From<decision::SvObservation> for SvObservation {
    fn from(v: decision::SvObservation) -> Self {
        Self {
            id: v.id,
            x_m: v.x_m,
            y_m: v.y_m,
            v_mps: v.v_mps,
            a_mps2: v.a_mps2,
            vy_mps: v.vy_mps,
            length_m: v.length_m.unwrap_or(0.0),
            width_m: v.width_m.unwrap_or(0.0),
        }
    }
}
impl From<SvObservation> for decision::SvObservation {
    /// A size of 0 means unknown.
    fn from(v: SvObservation) -> Self {
        let known = |m: f64| (m != 0.0).then_some(m);
        decision::SvObservation {
            vy_mps: v.vy_mps,
            length_m: known(v.length_m),
            width_m: known(v.width_m),
            ..decision::SvObservation::new(v.id, v.x_m, v.y_m, v.v_mps, v.a_mps2)
        }
    }
}
same_fields!(SetPoint <=> decision::SetPoint { accel_mps2, target_speed_mps });
same_fields!(CorrectiveEntry <=> decision::CorrectiveEntry { sv_id, release_m, trigger_m });
same_fields!(PlanStep <=> decision::PlanStep { action via into, maneuver via into, x_m, v_mps, occupied_lanes });

fn converted<W: Clone, C: Copy + Into<W>, const N: usize>(
    field: &str,
    items: &[C],
) -> Result<iceoryx2_bb_container::vector::StaticVec<W, N>, WireError> {
    let wire: Vec<W> = items.iter().map(|&c| c.into()).collect();
    bounded(field, &wire)
}

impl TryFrom<&decision::PlannerMemory> for PlannerMemory {
    type Error = WireError;

    /// Fails with [`WireError::CapacityExceeded`] beyond [`crate::MAX_CORRECTIVE`] entries or
    /// [`crate::MAX_HORIZON`] actions.
    fn try_from(m: &decision::PlannerMemory) -> Result<Self, WireError> {
        Ok(Self {
            corrective: converted("memory.corrective", &m.corrective)?,
            previous_plan: converted("memory.previous_plan", &m.previous_plan)?,
        })
    }
}

impl From<&PlannerMemory> for decision::PlannerMemory {
    fn from(m: &PlannerMemory) -> Self {
        Self {
            corrective: m.corrective.iter().map(|&e| e.into()).collect(),
            previous_plan: m.previous_plan.iter().map(|&a| a.into()).collect(),
        }
    }
}

impl PlanRequest {
    /// A request carrying `situation`; fails with [`WireError::CapacityExceeded`] when a list
    /// does not fit. The deadline is the default (set `deadline_us` to change it).
    pub fn from_situation(
        vehicle_id: u64,
        sequence: u64,
        timestamp_ns: u64,
        situation: &decision::Situation,
    ) -> Result<Self, WireError> {
        Ok(Self {
            version: PROTOCOL_VERSION,
            vehicle_id,
            sequence,
            timestamp_ns,
            deadline_us: 0,
            sent_at_ns: 0,
            road: situation.road.into(),
            ego: situation.ego.into(),
            svs: converted("svs", &situation.svs)?,
            memory: PlannerMemory::try_from(&situation.memory)?,
        })
    }

    /// The situation for the decision core, unchecked ([`PlanRequest::validate`] checks it on
    /// the way to an answer).
    pub fn to_situation(&self) -> decision::Situation {
        decision::Situation {
            road: self.road.into(),
            ego: self.ego.into(),
            svs: self.svs.iter().map(|&sv| sv.into()).collect(),
            memory: (&self.memory).into(),
        }
    }
}

impl From<decision::Layer> for Layer {
    fn from(layer: decision::Layer) -> Self {
        match layer {
            decision::Layer::Nominal => Layer::Nominal,
            decision::Layer::GlobalRelaxation => Layer::GlobalRelaxation,
            decision::Layer::Fallback => Layer::Fallback,
        }
    }
}

impl TryFrom<&decision::Decision> for Decided {
    type Error = WireError;

    /// Fails with [`WireError::CapacityExceeded`] when the plan or the memory does not fit.
    fn try_from(d: &decision::Decision) -> Result<Self, WireError> {
        Ok(Decided::new(
            d.action.into(),
            d.next_maneuver.into(),
            d.setpoint.into(),
            converted("plan", &d.plan)?,
            d.layer.into(),
            PlannerMemory::try_from(&d.memory)?,
        ))
    }
}

impl PlanResponse {
    /// The response to `request` carrying `decision`; `solve_us` is the decision's total wall
    /// time (saturated to `u32`).
    pub fn from_decision(
        request: &PlanRequest,
        decision: &decision::Decision,
        queue_us: u32,
    ) -> Result<Self, WireError> {
        Ok(Self::decided(
            request.vehicle_id,
            request.sequence,
            Decided::try_from(decision)?,
            u32::try_from(decision.stats.total_us).unwrap_or(u32::MAX),
            queue_us,
        ))
    }
}

impl From<&decision::InputError> for Rejected {
    /// Every input error has its own reason code; the field is the decision core's dotted
    /// path (`road.lane_width_m`, `ego.v_mps`, `sv.x_m`, ...).
    fn from(e: &decision::InputError) -> Self {
        use decision::InputError as E;
        match e {
            E::NonFinite { field } => Rejected::new(RejectReason::NonFinite, field),
            E::OutOfRange { field, .. } => Rejected::new(RejectReason::OutOfRange, field),
            E::NegativeSpeed { field, .. } => Rejected::new(RejectReason::NegativeSpeed, field),
            E::LaneCount { .. } => Rejected::new(RejectReason::LaneCount, "road.lanes"),
            E::LaneOutOfRange { field, .. } => Rejected::new(RejectReason::LaneOutOfRange, field),
            E::BetaOutOfRange { field, .. } => Rejected::new(RejectReason::BetaOutOfRange, field),
            E::DuplicateSvId { .. } => Rejected::new(RejectReason::DuplicateSvId, "sv.id"),
            E::TooManyVehicles { .. } => Rejected::new(RejectReason::TooManyVehicles, "svs"),
            E::InvalidMemory { field, .. } => Rejected::new(RejectReason::InvalidMemory, field),
        }
    }
}

impl From<&decision::DecisionError> for Rejected {
    /// Input errors as above; configuration and solver failures are `InternalError`.
    fn from(e: &decision::DecisionError) -> Self {
        match e {
            decision::DecisionError::Input(input) => input.into(),
            decision::DecisionError::Config(_) => Rejected::new(RejectReason::InternalError, "config"),
            decision::DecisionError::Solver(_) => Rejected::new(RejectReason::InternalError, "solver"),
        }
    }
}

impl From<&decision::InputError> for RejectReason {
    fn from(e: &decision::InputError) -> Self {
        // Cannot fail: the conversion above only builds known reasons.
        Rejected::from(e).reason().unwrap_or(RejectReason::InternalError)
    }
}
