//! Lenient decoding of what arrives over DDS, so that a payload the CDR decoder cannot read
//! does not vanish inside ros2-client.
//!
//! ros2-client decodes a service payload after it has taken the sample, and on failure
//! returns an error that carries neither the RMW request id nor the payload: the request
//! could never be answered. These types never fail to deserialize: a bad payload becomes
//! the `Undecodable` variant, so the request id (taken from the sample's metadata) survives
//! and the server answers a `malformed` rejection with whatever ids it could read first.

use core::fmt;

use serde::de::{Deserialize, Deserializer, SeqAccess, Visitor};
use serde::ser::{self, Serialize, Serializer};

use crate::msg;

/// A `hmdp_msgs/srv/Plan` request as the server receives it.
#[derive(Debug, Clone, PartialEq)]
pub enum IncomingRequest {
    Decoded(msg::PlanRequest),
    /// The CDR did not decode; the ids are those read before the failure (0 when not).
    Undecodable {
        vehicle_id: u64,
        sequence: u64,
        error: String,
    },
}

impl ros2_client::Message for IncomingRequest {}

impl Serialize for IncomingRequest {
    /// Only for ros2-client's trait bounds: the server never writes a request.
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self {
            Self::Decoded(request) => msg::PlanServiceRequest {
                request: request.clone(),
            }
            .serialize(serializer),
            Self::Undecodable { .. } => Err(ser::Error::custom("an undecodable request cannot be written")),
        }
    }
}

impl<'de> Deserialize<'de> for IncomingRequest {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        // `Plan_Request { request }`: the outer struct's one field is the PlanRequest.
        deserializer.deserialize_struct("Plan_Request", &["request"], OuterVisitor)
    }
}

struct OuterVisitor;

impl<'de> Visitor<'de> for OuterVisitor {
    type Value = IncomingRequest;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a hmdp_msgs/srv/Plan request")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<IncomingRequest, A::Error> {
        Ok(match seq.next_element::<LenientPlanRequest>() {
            Ok(Some(LenientPlanRequest(request))) => request,
            Ok(None) => undecodable((0, 0), "empty request".to_owned()),
            Err(e) => undecodable((0, 0), e.to_string()),
        })
    }
}

struct LenientPlanRequest(IncomingRequest);

const REQUEST_FIELDS: &[&str] = &[
    "version",
    "vehicle_id",
    "sequence",
    "timestamp_ns",
    "deadline_us",
    "sent_at_ns",
    "road",
    "ego",
    "svs",
    "memory",
];

impl<'de> Deserialize<'de> for LenientPlanRequest {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer
            .deserialize_struct("PlanRequest", REQUEST_FIELDS, RequestVisitor)
            .map(LenientPlanRequest)
    }
}

fn undecodable((vehicle_id, sequence): (u64, u64), error: String) -> IncomingRequest {
    IncomingRequest::Undecodable {
        vehicle_id,
        sequence,
        error,
    }
}

fn field<'de, T: Deserialize<'de>, A: SeqAccess<'de>>(seq: &mut A, name: &str) -> Result<T, String> {
    match seq.next_element::<T>() {
        Ok(Some(value)) => Ok(value),
        Ok(None) => Err(format!("`{name}` is missing")),
        Err(e) => Err(format!("`{name}`: {e}")),
    }
}

struct RequestVisitor;

impl RequestVisitor {
    /// Reads the fields after the ids; the first error is returned as text.
    fn rest<'de, A: SeqAccess<'de>>(
        seq: &mut A,
        version: u16,
        (vehicle_id, sequence): (u64, u64),
    ) -> Result<msg::PlanRequest, String> {
        Ok(msg::PlanRequest {
            version,
            vehicle_id,
            sequence,
            timestamp_ns: field(seq, "timestamp_ns")?,
            deadline_us: field(seq, "deadline_us")?,
            sent_at_ns: field(seq, "sent_at_ns")?,
            road: field(seq, "road")?,
            ego: field(seq, "ego")?,
            svs: field(seq, "svs")?,
            memory: field(seq, "memory")?,
        })
    }
}

impl<'de> Visitor<'de> for RequestVisitor {
    type Value = IncomingRequest;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a hmdp_msgs/PlanRequest")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<IncomingRequest, A::Error> {
        let version = match field::<u16, _>(&mut seq, "version") {
            Ok(v) => v,
            Err(e) => return Ok(undecodable((0, 0), e)),
        };
        let vehicle_id = match field::<u64, _>(&mut seq, "vehicle_id") {
            Ok(v) => v,
            Err(e) => return Ok(undecodable((0, 0), e)),
        };
        let sequence = match field::<u64, _>(&mut seq, "sequence") {
            Ok(v) => v,
            Err(e) => return Ok(undecodable((vehicle_id, 0), e)),
        };
        let ids = (vehicle_id, sequence);
        Ok(match Self::rest(&mut seq, version, ids) {
            Ok(request) => IncomingRequest::Decoded(request),
            Err(e) => undecodable(ids, e),
        })
    }
}

/// A `hmdp_msgs/srv/Plan` response as the client receives it.
#[derive(Debug, Clone, PartialEq)]
pub enum IncomingResponse {
    Decoded(msg::PlanResponse),
    Undecodable(String),
}

impl ros2_client::Message for IncomingResponse {}

impl Serialize for IncomingResponse {
    /// Only for ros2-client's trait bounds: the client never writes a response.
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self {
            Self::Decoded(response) => msg::PlanServiceResponse {
                response: response.clone(),
            }
            .serialize(serializer),
            Self::Undecodable(_) => Err(ser::Error::custom("an undecodable response cannot be written")),
        }
    }
}

impl<'de> Deserialize<'de> for IncomingResponse {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        Ok(match msg::PlanServiceResponse::deserialize(deserializer) {
            Ok(msg::PlanServiceResponse { response }) => Self::Decoded(response),
            Err(e) => Self::Undecodable(e.to_string()),
        })
    }
}
