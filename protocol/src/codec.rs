//! Byte encodings: bincode (the binary form every transport uses) and JSON.
//!
//! bincode configuration, fixed for every version of this protocol: little endian,
//! fixed-width integers (`u16` = 2 bytes, `u64` = 8 bytes, lengths and enum variant indices
//! as `u64` / `u32`), no length prefix around the message, and the whole input must be one
//! message (trailing bytes are an error). See `docs/protocol.md` for the byte layout.

use bincode::config::{Configuration, Fixint, Limit, LittleEndian};
use bincode::error::DecodeError;
use serde::de::DeserializeOwned;
use serde::Serialize;

use crate::error::{clear_refusal, WireError};
use crate::messages::{PlanRequest, PlanResponse, PROTOCOL_VERSION};

/// Upper bound on a message (bincode or JSON), bytes; the largest valid message is far smaller.
pub const MAX_MESSAGE_BYTES: usize = 64 * 1024;

/// The bincode configuration of the protocol.
pub const BINCODE_CONFIG: Configuration<LittleEndian, Fixint, Limit<MAX_MESSAGE_BYTES>> = bincode::config::standard()
    .with_little_endian()
    .with_fixed_int_encoding()
    .with_limit::<MAX_MESSAGE_BYTES>();

/// Another protocol version than this build's.
fn unsupported(found: u16) -> WireError {
    WireError::UnsupportedVersion {
        found,
        supported: PROTOCOL_VERSION,
    }
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for super::PlanRequest {}
    impl Sealed for super::PlanResponse {}
}

/// A top-level message of the protocol: [`PlanRequest`] or [`PlanResponse`]. Both start with
/// the `u16` protocol version, which the decoders check before anything else.
pub trait WireMessage: Serialize + DeserializeOwned + sealed::Sealed {
    /// The version this message carries.
    fn version(&self) -> u16;
}

impl WireMessage for PlanRequest {
    fn version(&self) -> u16 {
        self.version
    }
}

impl WireMessage for PlanResponse {
    fn version(&self) -> u16 {
        self.version
    }
}

/// Encodes a message with the protocol's bincode configuration.
pub fn encode_bincode<T: WireMessage>(message: &T) -> Vec<u8> {
    // Cannot fail: the writer is a Vec, every sequence has a known length and no Serialize
    // impl of the protocol returns an error (unknown enum codes are written as they are).
    bincode::serde::encode_to_vec(message, BINCODE_CONFIG).unwrap_or_default()
}

/// Decodes one message from exactly `bytes`.
pub fn decode_bincode<T: WireMessage>(bytes: &[u8]) -> Result<T, WireError> {
    let [lo, hi, ..] = *bytes else {
        return Err(WireError::Truncated);
    };
    let version = u16::from_le_bytes([lo, hi]);
    if version != PROTOCOL_VERSION {
        return Err(unsupported(version));
    }
    clear_refusal();
    let (message, read): (T, usize) =
        bincode::serde::borrow_decode_from_slice(bytes, BINCODE_CONFIG).map_err(|e| match e {
            DecodeError::UnexpectedEnd { .. } => WireError::Truncated,
            DecodeError::OtherString(msg) => WireError::from_decoder(msg),
            DecodeError::Other(msg) => WireError::from_decoder(msg.to_owned()),
            other => WireError::Malformed(other.to_string()),
        })?;
    if read < bytes.len() {
        return Err(WireError::TrailingBytes {
            extra: bytes.len() - read,
        });
    }
    Ok(message)
}

/// Encodes a message as compact JSON. Non-finite numbers become `null` (which no decoder
/// accepts back): JSON has no NaN.
pub fn encode_json<T: WireMessage>(message: &T) -> String {
    // Cannot fail: no maps with non-string keys, no Serialize impl returns an error.
    serde_json::to_string(message).unwrap_or_default()
}

/// Encodes a message as indented JSON (for logs and documentation).
pub fn encode_json_pretty<T: WireMessage>(message: &T) -> String {
    serde_json::to_string_pretty(message).unwrap_or_default()
}

/// Decodes one JSON message from `bytes` (UTF-8); whitespace around it is allowed.
pub fn decode_json<T: WireMessage>(bytes: &[u8]) -> Result<T, WireError> {
    // Bounded like bincode: parsing builds a tree several times the input's size.
    if bytes.len() > MAX_MESSAGE_BYTES {
        return Err(WireError::Malformed(format!(
            "{} bytes: a message is at most {MAX_MESSAGE_BYTES}",
            bytes.len()
        )));
    }
    let mut stream = serde_json::Deserializer::from_slice(bytes).into_iter::<serde_json::Value>();
    let value = match stream.next() {
        None => return Err(WireError::Truncated),
        Some(Err(e)) if e.is_eof() => return Err(WireError::Truncated),
        Some(Err(e)) => return Err(WireError::Malformed(e.to_string())),
        Some(Ok(value)) => value,
    };
    let rest = &bytes[stream.byte_offset()..];
    let extra = rest.iter().filter(|b| !b.is_ascii_whitespace()).count();
    if extra > 0 {
        return Err(WireError::TrailingBytes {
            extra: rest.len() - rest.iter().take_while(|b| b.is_ascii_whitespace()).count(),
        });
    }
    // serde would also take a struct as a positional array, which skips the version check.
    if !value.is_object() {
        return Err(WireError::Malformed("a message is a JSON object".into()));
    }
    match value.get("version").map(serde_json::Value::as_u64) {
        Some(Some(v)) if v != u64::from(PROTOCOL_VERSION) => {
            return Err(match u16::try_from(v) {
                Ok(found) => unsupported(found),
                Err(_) => WireError::Malformed(format!("version {v} is not a u16")),
            })
        }
        _ => {}
    }
    clear_refusal();
    serde_json::from_value(value).map_err(|e| WireError::from_decoder(e.to_string()))
}

/// Decodes one JSON message from a string.
pub fn decode_json_str<T: WireMessage>(text: &str) -> Result<T, WireError> {
    decode_json(text.as_bytes())
}

/// The worked example of `docs/protocol.md` (3 lanes, one SV 30 m ahead) as `vehicle_id`'s
/// request number `sequence`: what tests and load tools send when the scene does not matter.
pub fn worked_example_request(vehicle_id: u64, sequence: u64) -> PlanRequest {
    let mut r: PlanRequest = decode_json_str(
        r#"{"version":3,"vehicle_id":0,"sequence":0,"timestamp_ns":1000000000,
            "road":{"lanes":3,"lane_width_m":3.5,"speed_limit_mps":30.0},
            "ego":{"x_m":0.0,"y_m":3.5,"v_mps":25.0,"desired_speed_mps":28.0,"maneuver":{"lane":2,"beta":0}},
            "svs":[{"id":1,"x_m":30.0,"y_m":3.5,"v_mps":20.0,"a_mps2":-0.5}]}"#,
    )
    .expect("the documented example decodes");
    r.vehicle_id = vehicle_id;
    r.sequence = sequence;
    r
}
