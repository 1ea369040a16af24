//! The ROS 2 messages as serde structs, field for field in the order of their `.msg` files,
//! so that the CDR encoder of RustDDS writes what rosidl's typesupport writes.
//!
//! * `hmdp_msgs` (`ros2/hmdp_msgs/`): the protocol v3 messages and the `Plan` service. ROS has
//!   no unions, so [`PlanResponse`] carries `outcome` plus both bodies; enumerations are `u8`
//!   codes; bounded sequences (`T[<=N]`) are `Vec`s whose bound the conversions check
//!   (the conversions to the protocol's types), because CDR writes a bounded sequence exactly like an unbounded one.
//! * [`viz`]: `visualization_msgs/Marker` and `MarkerArray` of ROS 2 Kilted with everything
//!   they nest, for the planner's RViz markers.
//!
//! Constants of the `.msg` files are associated constants. Type names for ros2-client are
//! the `TYPE_NAME` functions.

pub mod viz;

use ros2_client::{Message, MessageTypeName, ServiceTypeName};
use serde::{Deserialize, Serialize};

/// The ROS package of the planner's interface.
pub const PACKAGE: &str = "hmdp_msgs";

/// `uint8[64]`: a fixed-size CDR array, written as its 64 bytes with no length (serde's
/// tuple form, which is how RustDDS's CDR encoder writes fixed arrays). serde itself
/// implements arrays only up to 32 elements.
mod byte_array_64 {
    use core::fmt;

    use serde::de::{self, SeqAccess, Visitor};
    use serde::ser::SerializeTuple;
    use serde::{Deserializer, Serializer};

    pub const LEN: usize = 64;

    pub fn serialize<S: Serializer>(bytes: &[u8; LEN], serializer: S) -> Result<S::Ok, S::Error> {
        let mut tuple = serializer.serialize_tuple(LEN)?;
        for byte in bytes {
            tuple.serialize_element(byte)?;
        }
        tuple.end()
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<[u8; LEN], D::Error> {
        deserializer.deserialize_tuple(LEN, ArrayVisitor)
    }

    struct ArrayVisitor;

    impl<'de> Visitor<'de> for ArrayVisitor {
        type Value = [u8; LEN];

        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "{LEN} bytes")
        }

        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
            let mut out = [0u8; LEN];
            for (i, byte) in out.iter_mut().enumerate() {
                *byte = seq.next_element()?.ok_or_else(|| de::Error::invalid_length(i, &self))?;
            }
            Ok(out)
        }
    }
}

/// Implements [`Message`] and names the ROS type of each struct.
macro_rules! ros_messages {
    ($($name:ident),+ $(,)?) => {$(
        impl Message for $name {}
        impl $name {
            /// The ROS type (`hmdp_msgs/msg/<name>`).
            pub fn type_name() -> MessageTypeName {
                MessageTypeName::new(PACKAGE, stringify!($name))
            }
        }
    )+};
}

/// `hmdp_msgs/Road`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Road {
    pub lanes: u8,
    pub lane_width_m: f64,
    pub speed_limit_mps: f64,
}

/// `hmdp_msgs/Maneuver`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Maneuver {
    pub lane: u8,
    pub beta: i8,
}

impl Maneuver {
    pub const BETA_DECELERATING: i8 = -1;
    pub const BETA_CRUISING: i8 = 0;
    pub const BETA_ACCELERATING: i8 = 1;
}

/// `hmdp_msgs/Action`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Action {
    pub lateral: i8,
    pub longitudinal: i8,
}

/// `hmdp_msgs/EgoState`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct EgoState {
    pub x_m: f64,
    pub y_m: f64,
    pub v_mps: f64,
    pub desired_speed_mps: f64,
    pub maneuver: Maneuver,
}

/// `hmdp_msgs/SvObservation`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct SvObservation {
    pub id: u32,
    pub x_m: f64,
    pub y_m: f64,
    pub v_mps: f64,
    pub a_mps2: f64,
    pub vy_mps: f64,
    pub length_m: f64,
    pub width_m: f64,
}

/// `hmdp_msgs/CorrectiveEntry`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct CorrectiveEntry {
    pub sv_id: u32,
    pub release_m: f64,
    pub trigger_m: f64,
}

/// `hmdp_msgs/PlannerMemory`: `corrective` at most 16, `previous_plan` at most 6.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PlannerMemory {
    pub corrective: Vec<CorrectiveEntry>,
    pub previous_plan: Vec<Action>,
}

/// `hmdp_msgs/PlanRequest`: `svs` at most 64.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PlanRequest {
    pub version: u16,
    pub vehicle_id: u64,
    pub sequence: u64,
    pub timestamp_ns: u64,
    pub deadline_us: u32,
    pub sent_at_ns: u64,
    pub road: Road,
    pub ego: EgoState,
    pub svs: Vec<SvObservation>,
    pub memory: PlannerMemory,
}

impl PlanRequest {
    pub const PROTOCOL_VERSION: u16 = 3;
}

/// `hmdp_msgs/PlanStep`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PlanStep {
    pub action: Action,
    pub maneuver: Maneuver,
    pub x_m: f64,
    pub v_mps: f64,
    pub occupied_lanes: u16,
}

/// `hmdp_msgs/SetPoint`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct SetPoint {
    pub accel_mps2: f64,
    pub target_speed_mps: f64,
}

/// `hmdp_msgs/Decided`: `plan` at most 6 steps.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Decided {
    pub action: Action,
    pub next_maneuver: Maneuver,
    pub setpoint: SetPoint,
    pub plan: Vec<PlanStep>,
    pub layer: u8,
    pub memory: PlannerMemory,
}

impl Decided {
    pub const LAYER_NOMINAL: u8 = 0;
    pub const LAYER_GLOBAL_RELAXATION: u8 = 1;
    pub const LAYER_FALLBACK: u8 = 2;
    pub const LAYER_WATCHDOG_FALLBACK: u8 = 3;
    pub const LAYER_STALE_FALLBACK: u8 = 4;
}

/// `hmdp_msgs/Rejected`: `field` at most 31 bytes.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Rejected {
    pub reason: u8,
    pub field: String,
}

impl Rejected {
    pub const REASON_UNSUPPORTED_VERSION: u8 = 1;
    pub const REASON_CAPACITY_EXCEEDED: u8 = 2;
    pub const REASON_NON_FINITE: u8 = 10;
    pub const REASON_OUT_OF_RANGE: u8 = 11;
    pub const REASON_NEGATIVE_SPEED: u8 = 12;
    pub const REASON_LANE_COUNT: u8 = 13;
    pub const REASON_LANE_OUT_OF_RANGE: u8 = 14;
    pub const REASON_BETA_OUT_OF_RANGE: u8 = 15;
    pub const REASON_DUPLICATE_SV_ID: u8 = 16;
    pub const REASON_TOO_MANY_VEHICLES: u8 = 17;
    pub const REASON_INVALID_MEMORY: u8 = 18;
    pub const REASON_MALFORMED: u8 = 30;
    pub const REASON_OVERLOADED: u8 = 31;
    pub const REASON_INTERNAL_ERROR: u8 = 32;
}

/// `hmdp_msgs/PlanResponse`: `outcome` says which of `decided` and `rejected` holds the
/// answer; the other is all defaults.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanResponse {
    pub version: u16,
    pub vehicle_id: u64,
    pub sequence: u64,
    pub solve_us: u32,
    pub queue_us: u32,
    pub outcome: u8,
    pub decided: Decided,
    pub rejected: Rejected,
    #[serde(with = "byte_array_64")]
    pub signature: [u8; 64],
}

impl PlanResponse {
    pub const OUTCOME_DECIDED: u8 = 0;
    pub const OUTCOME_REJECTED: u8 = 1;
}

impl Default for PlanResponse {
    fn default() -> Self {
        Self {
            version: 0,
            vehicle_id: 0,
            sequence: 0,
            solve_us: 0,
            queue_us: 0,
            outcome: 0,
            decided: Decided::default(),
            rejected: Rejected::default(),
            signature: [0; 64],
        }
    }
}

ros_messages!(
    Road,
    Maneuver,
    Action,
    EgoState,
    SvObservation,
    CorrectiveEntry,
    PlannerMemory,
    PlanRequest,
    PlanStep,
    SetPoint,
    Decided,
    Rejected,
    PlanResponse,
);

/// `hmdp_msgs/srv/Plan` request (`Plan_Request`): one field, `request`. In CDR a struct adds
/// nothing around its fields, so its bytes are those of the [`PlanRequest`].
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PlanServiceRequest {
    pub request: PlanRequest,
}

/// `hmdp_msgs/srv/Plan` response (`Plan_Response`): one field, `response`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PlanServiceResponse {
    pub response: PlanResponse,
}

impl Message for PlanServiceRequest {}
impl Message for PlanServiceResponse {}

/// The service type `hmdp_msgs/srv/Plan`.
pub fn plan_service_type_name() -> ServiceTypeName {
    ServiceTypeName::new(PACKAGE, "Plan")
}
