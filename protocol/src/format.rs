//! The two encodings as one value, and what can be read from a message that does not decode
//! (its ids, the list over capacity): the header knowledge lives here, next to the layout.

use crate::codec::{decode_bincode, decode_json, encode_bincode, encode_json, WireMessage, MAX_MESSAGE_BYTES};
use crate::enums::RejectReason;
use crate::error::WireError;
use crate::messages::{PlanRequest, Rejected, MAX_CORRECTIVE, MAX_HORIZON, MAX_SVS};

/// How a message body is encoded (a transport's encoding field says which).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireFormat {
    Bincode,
    Json,
}

impl WireFormat {
    /// Decodes one message from exactly `bytes`.
    pub fn decode<T: WireMessage>(self, bytes: &[u8]) -> Result<T, WireError> {
        match self {
            WireFormat::Bincode => decode_bincode(bytes),
            WireFormat::Json => decode_json(bytes),
        }
    }

    /// Encodes a message.
    pub fn encode<T: WireMessage>(self, message: &T) -> Vec<u8> {
        match self {
            WireFormat::Bincode => encode_bincode(message),
            WireFormat::Json => encode_json(message).into_bytes(),
        }
    }

    /// The vehicle id and sequence of a request that does not decode, when they can be read
    /// (else 0): the answer's echo.
    pub fn peek_ids(self, bytes: &[u8]) -> (u64, u64) {
        match self {
            WireFormat::Bincode => {
                let at = |range: std::ops::Range<usize>| {
                    bytes
                        .get(range)
                        .and_then(|b| b.try_into().ok())
                        .map_or(0, u64::from_le_bytes)
                };
                (
                    at(layout::VEHICLE_ID..layout::SEQUENCE),
                    at(layout::SEQUENCE..layout::SEQUENCE + 8),
                )
            }
            WireFormat::Json => {
                let Some(value) = json_value(bytes) else { return (0, 0) };
                let field = |name: &str| value.get(name).and_then(serde_json::Value::as_u64).unwrap_or(0);
                (field("vehicle_id"), field("sequence"))
            }
        }
    }

    /// The list of an undecodable request that holds more than its capacity, when it can be
    /// told (`svs`, `memory.corrective` or `memory.previous_plan`).
    pub fn over_capacity_field(self, bytes: &[u8]) -> Option<&'static str> {
        let lists = [
            ("svs", MAX_SVS),
            ("memory.corrective", MAX_CORRECTIVE),
            ("memory.previous_plan", MAX_HORIZON),
        ];
        match self {
            WireFormat::Json => {
                let value = json_value(bytes)?;
                lists.into_iter().find_map(|(name, cap)| {
                    let pointer = format!("/{}", name.replace('.', "/"));
                    let len = value
                        .pointer(&pointer)
                        .and_then(serde_json::Value::as_array)
                        .map_or(0, Vec::len);
                    (len > cap).then_some(name)
                })
            }
            WireFormat::Bincode => {
                let element_bytes = [layout::SV, layout::CORRECTIVE_ENTRY, layout::ACTION];
                let mut at = layout::SVS_COUNT;
                for ((name, cap), size) in lists.into_iter().zip(element_bytes) {
                    let count = u64::from_le_bytes(bytes.get(at..at + 8)?.try_into().ok()?);
                    if count > cap as u64 {
                        return Some(name);
                    }
                    at += 8 + usize::try_from(count).ok()?.checked_mul(size)?;
                }
                None
            }
        }
    }

    /// The rejection answering bytes that did not decode as a request.
    pub fn rejection(self, bytes: &[u8], error: &WireError) -> Rejected {
        match error {
            WireError::UnsupportedVersion { .. } => Rejected::new(RejectReason::UnsupportedVersion, "version"),
            WireError::CapacityExceeded(_) => Rejected::new(
                RejectReason::CapacityExceeded,
                self.over_capacity_field(bytes).unwrap_or(""),
            ),
            _ => Rejected::new(RejectReason::Malformed, ""),
        }
    }

    /// Decodes a request; when it does not decode, the rejection to answer with and the ids
    /// to echo.
    pub fn decode_request(self, bytes: &[u8]) -> Result<PlanRequest, (Rejected, (u64, u64), WireError)> {
        self.decode(bytes)
            .map_err(|e| (self.rejection(bytes, &e), self.peek_ids(bytes), e))
    }
}

fn json_value(bytes: &[u8]) -> Option<serde_json::Value> {
    // Bounded like the decoder: parsing builds a tree several times the input's size.
    if bytes.len() > MAX_MESSAGE_BYTES {
        return None;
    }
    serde_json::from_slice(bytes).ok()
}

/// Byte offsets and sizes of the bincode request (docs/protocol.md, "Byte layout").
pub mod layout {
    /// `vehicle_id`, after the `u16` version.
    pub const VEHICLE_ID: usize = 2;
    /// `sequence`.
    pub const SEQUENCE: usize = VEHICLE_ID + 8;
    /// After `timestamp_ns` (8), `deadline_us` (4) and `sent_at_ns` (8).
    const ROAD: usize = SEQUENCE + 8 + 8 + 4 + 8;
    /// `lanes` (1) and two `f64`.
    const EGO: usize = ROAD + 1 + 2 * 8;
    /// The `u64` count of the SV list: after four `f64` and the maneuver (2).
    pub const SVS_COUNT: usize = EGO + 4 * 8 + 2;
    /// One SV: `u32` id and seven `f64`.
    pub const SV: usize = 4 + 7 * 8;
    /// One corrective entry: `u32` id and two `f64`.
    pub const CORRECTIVE_ENTRY: usize = 4 + 2 * 8;
    /// One action: two `i8`.
    pub const ACTION: usize = 2;
}
