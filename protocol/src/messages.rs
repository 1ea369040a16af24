//! The message types: one definition each, usable as iceoryx2 zero-copy payloads
//! (`#[repr(C)]`, fixed capacity, no pointers) and with serde (bincode, JSON).
//!
//! Field order is wire order: bincode writes fields in declaration order, so reordering,
//! adding or removing a field, or changing a type, is a protocol change
//! (see `docs/protocol.md`, "Versioning").

use core::time::Duration;

use iceoryx2_bb_container::string::{StaticString, String as _};
use iceoryx2_bb_container::vector::{StaticVec, Vector};
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;
use serde::{Deserialize, Serialize};

use crate::enums::{layer_code, reject_reason_code, Layer, RejectReason};
use crate::error::WireError;
pub use crate::outcome::{Outcome, OutcomeRef};
use crate::serde_util::{bounded_str, bounded_vec, signature_bytes};
use crate::signature::Signature;

/// Version of the wire contract. Carried first in every message and in the iceoryx2
/// `type_name` of the payloads (`.../v3`).
pub const PROTOCOL_VERSION: u16 = 3;
/// The version of a readiness probe ([`PlanRequest::probe`]); never a protocol version.
pub const PROBE_VERSION: u16 = 0;
/// At most this many SVs in a request (the decision core's `MAX_INPUT_SVS`; the planner uses
/// the nearest `perception.max_svs` of them).
pub const MAX_SVS: usize = 64;
/// At most this many corrective (hysteresis) entries in the planner memory.
pub const MAX_CORRECTIVE: usize = 16;
/// At most this many steps in a plan (and actions in the previous plan).
pub const MAX_HORIZON: usize = 6;
/// Capacity of the field name in a rejection, bytes (ASCII).
pub const FIELD_NAME_CAPACITY: usize = 31;
/// Deadline the service applies when a request says `deadline_us = 0`.
pub const DEFAULT_DEADLINE: Duration = Duration::from_millis(400);

/// Bounded list of SVs.
pub type SvList = StaticVec<SvObservation, MAX_SVS>;
/// Bounded list of corrective entries.
pub type CorrectiveList = StaticVec<CorrectiveEntry, MAX_CORRECTIVE>;
/// Bounded list of actions (a previous plan).
pub type ActionList = StaticVec<Action, MAX_HORIZON>;
/// Bounded list of plan steps.
pub type PlanStepList = StaticVec<PlanStep, MAX_HORIZON>;
/// Field name of a rejection.
pub type FieldName = StaticString<FIELD_NAME_CAPACITY>;

/// The road as the planner sees it.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, ZeroCopySend)]
#[type_name("hmdp::Road/v3")]
#[serde(deny_unknown_fields)]
#[repr(C)]
pub struct Road {
    /// Number of lanes; lane 1 is the leftmost.
    pub lanes: u8,
    /// Lane width, m.
    pub lane_width_m: f64,
    /// Speed limit, m/s.
    pub speed_limit_mps: f64,
}

/// Discrete maneuver state: target lane and longitudinal state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize, ZeroCopySend)]
#[type_name("hmdp::Maneuver/v3")]
#[serde(deny_unknown_fields)]
#[repr(C)]
pub struct Maneuver {
    /// Target lane, `1..=lanes`.
    pub lane: u8,
    /// `-1` decelerating, `0` cruising, `1` accelerating.
    pub beta: i8,
}

/// One action: lateral (`-1` = change to the left) and longitudinal change, each in `-1..=1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize, ZeroCopySend)]
#[type_name("hmdp::Action/v3")]
#[serde(deny_unknown_fields)]
#[repr(C)]
pub struct Action {
    pub lateral: i8,
    pub longitudinal: i8,
}

/// The ego's state and current maneuver.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, ZeroCopySend)]
#[type_name("hmdp::EgoState/v3")]
#[serde(deny_unknown_fields)]
#[repr(C)]
pub struct EgoState {
    /// Longitudinal position, m.
    pub x_m: f64,
    /// Lateral position, m (lane `i` has its centre at `(lanes - i) * lane_width_m`).
    pub y_m: f64,
    /// Speed, m/s.
    pub v_mps: f64,
    /// Desired speed, m/s.
    pub desired_speed_mps: f64,
    pub maneuver: Maneuver,
}

/// One perceived surrounding vehicle. Positions are of the vehicle's centre.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, ZeroCopySend)]
#[type_name("hmdp::SvObservation/v3")]
#[serde(deny_unknown_fields)]
#[repr(C)]
pub struct SvObservation {
    pub id: u32,
    /// Longitudinal position of the centre, m.
    pub x_m: f64,
    /// Lateral position of the centre, m.
    pub y_m: f64,
    /// Speed, m/s.
    pub v_mps: f64,
    /// Acceleration, m/s².
    pub a_mps2: f64,
    /// Lateral velocity, m/s (positive to the left). Optional in JSON (0).
    #[serde(default)]
    pub vy_mps: f64,
    /// Length, m; 0 = unknown (the planner assumes its default). Optional in JSON.
    #[serde(default)]
    pub length_m: f64,
    /// Width, m; 0 = unknown. Optional in JSON.
    #[serde(default)]
    pub width_m: f64,
}

impl SvObservation {
    /// An SV with no lateral velocity and unknown size.
    pub fn new(id: u32, x_m: f64, y_m: f64, v_mps: f64, a_mps2: f64) -> Self {
        Self {
            id,
            x_m,
            y_m,
            v_mps,
            a_mps2,
            ..Self::default()
        }
    }
}

/// Hysteresis state of one SV in corrective mode.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, ZeroCopySend)]
#[type_name("hmdp::CorrectiveEntry/v3")]
#[serde(deny_unknown_fields)]
#[repr(C)]
pub struct CorrectiveEntry {
    pub sv_id: u32,
    /// Frozen release distance, m.
    pub release_m: f64,
    /// Frozen trigger distance, m.
    pub trigger_m: f64,
}

/// What the planner remembers between decisions; the vehicle sends back what it last got.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, ZeroCopySend)]
#[type_name("hmdp::PlannerMemory/v3")]
#[serde(deny_unknown_fields)]
#[repr(C)]
pub struct PlannerMemory {
    /// SVs in corrective mode, at most [`MAX_CORRECTIVE`].
    #[serde(with = "bounded_vec")]
    pub corrective: CorrectiveList,
    /// Actions planned last time, at most [`MAX_HORIZON`].
    #[serde(with = "bounded_vec")]
    pub previous_plan: ActionList,
}

/// A perception snapshot asking for a decision.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ZeroCopySend)]
#[type_name("hmdp::PlanRequest/v3")]
#[serde(deny_unknown_fields)]
#[repr(C)]
pub struct PlanRequest {
    /// Always [`PROTOCOL_VERSION`].
    pub version: u16,
    pub vehicle_id: u64,
    /// Sequence number chosen by the vehicle, echoed in the response.
    pub sequence: u64,
    /// Time of the snapshot, ns (the vehicle's clock).
    pub timestamp_ns: u64,
    /// Deadline for the answer, µs after receipt; 0 = [`DEFAULT_DEADLINE`]. Optional in JSON.
    #[serde(default)]
    pub deadline_us: u32,
    /// When the request was sent, ns since the Unix epoch on a clock the vehicle and the
    /// planner share; 0 = unknown. The planner answers a request older than its deadline on
    /// arrival as stale ([`PlanRequest::is_stale_at`]). Optional in JSON.
    #[serde(default)]
    pub sent_at_ns: u64,
    pub road: Road,
    pub ego: EgoState,
    /// Perceived SVs, at most [`MAX_SVS`].
    #[serde(with = "bounded_vec")]
    pub svs: SvList,
    /// The memory of the last response (empty on the first request). Optional in JSON.
    #[serde(default)]
    pub memory: PlannerMemory,
}

impl PlanRequest {
    /// A request of the current version with no SVs, empty memory and the default deadline.
    pub fn new(vehicle_id: u64, sequence: u64, timestamp_ns: u64, road: Road, ego: EgoState) -> Self {
        Self {
            version: PROTOCOL_VERSION,
            vehicle_id,
            sequence,
            timestamp_ns,
            deadline_us: 0,
            sent_at_ns: 0,
            road,
            ego,
            svs: SvList::new(),
            memory: PlannerMemory::default(),
        }
    }

    /// A readiness probe: version [`PROBE_VERSION`], answered with an `unsupported_version`
    /// rejection that the planner does not count as one. Over Zenoh the empty query is the
    /// probe.
    pub fn probe(vehicle_id: u64) -> Self {
        Self {
            version: PROBE_VERSION,
            ..Self::new(vehicle_id, 0, 0, Road::default(), EgoState::default())
        }
    }

    /// Whether this is a readiness probe.
    pub fn is_probe(&self) -> bool {
        self.version == PROBE_VERSION
    }

    /// The deadline the service should apply.
    pub fn deadline(&self) -> Duration {
        match self.deadline_us {
            0 => DEFAULT_DEADLINE,
            us => Duration::from_micros(u64::from(us)),
        }
    }
}

/// One step of the planned sequence.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, ZeroCopySend)]
#[type_name("hmdp::PlanStep/v3")]
#[serde(deny_unknown_fields)]
#[repr(C)]
pub struct PlanStep {
    pub action: Action,
    /// Maneuver after the action.
    pub maneuver: Maneuver,
    /// Predicted position at the end of the step, m.
    pub x_m: f64,
    /// Predicted speed at the end of the step, m/s.
    pub v_mps: f64,
    /// Bit `l - 1` set when the ego occupies lane `l` at the end of the step.
    pub occupied_lanes: u16,
}

/// What to command now: the first step's longitudinal acceleration and the speed it reaches
/// at the end of the first step.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, ZeroCopySend)]
#[type_name("hmdp::SetPoint/v3")]
#[serde(deny_unknown_fields)]
#[repr(C)]
pub struct SetPoint {
    /// m/s².
    pub accel_mps2: f64,
    /// m/s.
    pub target_speed_mps: f64,
}

/// A decision.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, ZeroCopySend)]
#[type_name("hmdp::Decided/v3")]
#[serde(deny_unknown_fields)]
#[repr(C)]
pub struct Decided {
    /// First action of the plan.
    pub action: Action,
    /// Maneuver to command now.
    pub next_maneuver: Maneuver,
    /// Longitudinal set-point of the first step.
    pub setpoint: SetPoint,
    /// The planned sequence, at most [`MAX_HORIZON`] steps.
    #[serde(with = "bounded_vec")]
    pub plan: PlanStepList,
    /// Code of the [`Layer`] that answered; read it with [`Decided::layer`].
    #[serde(with = "layer_code")]
    layer: u8,
    /// Memory to send back with the next request.
    pub memory: PlannerMemory,
}

impl Decided {
    pub fn new(
        action: Action,
        next_maneuver: Maneuver,
        setpoint: SetPoint,
        plan: PlanStepList,
        layer: Layer,
        memory: PlannerMemory,
    ) -> Self {
        Self {
            action,
            next_maneuver,
            setpoint,
            plan,
            layer: layer.code(),
            memory,
        }
    }

    /// The layer that answered; an unknown code (a faulty peer in shared memory) is an error.
    pub fn layer(&self) -> Result<Layer, WireError> {
        Layer::checked(self.layer)
    }

    /// The raw layer code as stored.
    pub fn layer_code(&self) -> u8 {
        self.layer
    }

    pub fn set_layer(&mut self, layer: Layer) {
        self.layer = layer.code();
    }

    /// Whether this is an emergency brake: a fallback (the vehicle's own, the watchdog's or
    /// a stale request's) braking beyond `planned_decel_mps2`, the strongest braking the
    /// planner's MPC plans (its `ego.max_decel_mps2`). Only the fallback's answer to a vehicle
    /// ahead that planned braking cannot stay behind goes beyond it (docs/protocol.md, "An
    /// emergency brake").
    pub fn is_emergency_brake(&self, planned_decel_mps2: f64) -> bool {
        matches!(
            self.layer(),
            Ok(Layer::Fallback | Layer::WatchdogFallback | Layer::StaleFallback)
        ) && self.setpoint.accel_mps2 < planned_decel_mps2
    }
}

/// A rejection: a typed reason and the offending field.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ZeroCopySend)]
#[type_name("hmdp::Rejected/v3")]
#[serde(deny_unknown_fields)]
#[repr(C)]
pub struct Rejected {
    /// Code of the [`RejectReason`]; read it with [`Rejected::reason`].
    #[serde(with = "reject_reason_code")]
    reason: u8,
    /// Dotted path of the offending field (e.g. `ego.v_mps`, `sv.x_m`), ASCII, at most
    /// [`FIELD_NAME_CAPACITY`] bytes; empty when no single field is at fault.
    #[serde(with = "bounded_str")]
    field: FieldName,
}

impl Default for Rejected {
    fn default() -> Self {
        Self::new(RejectReason::InternalError, "")
    }
}

impl Rejected {
    /// A rejection; `field` is cut to [`FIELD_NAME_CAPACITY`] bytes and every byte outside
    /// printable ASCII is replaced by `?`.
    pub fn new(reason: RejectReason, field: &str) -> Self {
        let bytes: Vec<u8> = field
            .bytes()
            .take(FIELD_NAME_CAPACITY)
            .map(|b| if (0x20..0x7f).contains(&b) { b } else { b'?' })
            .collect();
        Self {
            reason: reason.code(),
            // Cannot fail: at most FIELD_NAME_CAPACITY printable ASCII bytes.
            field: FieldName::from_bytes(&bytes).unwrap_or_default(),
        }
    }

    /// The reason; an unknown code is an error.
    pub fn reason(&self) -> Result<RejectReason, WireError> {
        RejectReason::checked(self.reason)
    }

    /// The raw reason code as stored.
    pub fn reason_code(&self) -> u8 {
        self.reason
    }

    /// The offending field.
    pub fn field(&self) -> &str {
        core::str::from_utf8(self.field.as_bytes()).unwrap_or("?")
    }
}

/// The planner's answer to a [`PlanRequest`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ZeroCopySend)]
#[type_name("hmdp::PlanResponse/v3")]
#[serde(deny_unknown_fields)]
#[repr(C)]
pub struct PlanResponse {
    /// Always [`PROTOCOL_VERSION`].
    pub version: u16,
    /// Echoed from the request.
    pub vehicle_id: u64,
    /// Echoed from the request.
    pub sequence: u64,
    /// Time spent deciding, µs.
    pub solve_us: u32,
    /// Time the request waited before deciding started, µs.
    pub queue_us: u32,
    pub outcome: Outcome,
    /// Ed25519 signature of the bincode encoding of every field before it; all zeros =
    /// unsigned ([`crate::ResponseSigner`]). Last so that the signed bytes are a prefix of the
    /// encoding. Optional in JSON.
    #[serde(with = "signature_bytes", default)]
    pub signature: Signature,
}

impl PlanResponse {
    /// A decision answering the request `(vehicle_id, sequence)`.
    pub fn decided(vehicle_id: u64, sequence: u64, decided: Decided, solve_us: u32, queue_us: u32) -> Self {
        Self {
            version: PROTOCOL_VERSION,
            vehicle_id,
            sequence,
            solve_us,
            queue_us,
            outcome: Outcome::decided(decided),
            signature: Signature::UNSIGNED,
        }
    }

    /// A rejection answering the request `(vehicle_id, sequence)`.
    pub fn rejected(vehicle_id: u64, sequence: u64, rejected: Rejected, queue_us: u32) -> Self {
        Self {
            version: PROTOCOL_VERSION,
            vehicle_id,
            sequence,
            solve_us: 0,
            queue_us,
            outcome: Outcome::rejected(rejected),
            signature: Signature::UNSIGNED,
        }
    }
}

/// Compile-time proof that the payloads are zero-copy sendable.
const _: () = {
    const fn assert_zero_copy<T: ZeroCopySend>() {}
    assert_zero_copy::<PlanRequest>();
    assert_zero_copy::<PlanResponse>();
};

/// Builds a bounded list from a slice; more than its capacity is
/// [`WireError::CapacityExceeded`] naming `field`.
pub fn bounded<T: Clone, const N: usize>(field: &str, items: &[T]) -> Result<StaticVec<T, N>, WireError> {
    if items.len() > N {
        return Err(WireError::CapacityExceeded(format!(
            "`{field}` has {} elements, capacity {N}",
            items.len()
        )));
    }
    let mut out = StaticVec::new();
    for item in items {
        // Cannot fail: the length was checked.
        let _ = out.push(item.clone());
    }
    Ok(out)
}
