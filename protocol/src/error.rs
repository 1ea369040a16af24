//! [`WireError`], and how a decoder's failure keeps its kind: the crate's own serde code
//! records what it refused ([`refuse`]) before it returns serde's untyped error, and the
//! decoders read the record ([`WireError::from_decoder`]) instead of the error's text.

use std::cell::Cell;
use std::fmt::Display;

use thiserror::Error;

/// What this crate's deserialisation code refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Failure {
    /// A list or string over its capacity.
    Capacity,
    /// An enumeration code or name the protocol does not define.
    UnknownEnum,
}

thread_local! {
    /// The last refusal on this thread; decoding runs on the caller's thread, start to end.
    static FAILURE: Cell<Option<Failure>> = const { Cell::new(None) };
}

/// The serde error for a refusal of kind `failure`, recorded for the decoder to type it.
pub(crate) fn refuse<E: serde::de::Error>(failure: Failure, msg: impl Display) -> E {
    FAILURE.set(Some(failure));
    E::custom(msg)
}

/// Forgets a refusal left by an earlier decode (called before each decode).
pub(crate) fn clear_refusal() {
    FAILURE.set(None);
}

/// Why bytes could not be decoded into a message.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum WireError {
    /// The input ends before the message does.
    #[error("input is truncated")]
    Truncated,
    /// The message ends before the input does.
    #[error("{extra} trailing bytes after the message")]
    TrailingBytes { extra: usize },
    /// The input is not a message of this protocol.
    #[error("malformed message: {0}")]
    Malformed(String),
    /// The message carries another protocol version.
    #[error("unsupported protocol version {found} (this build speaks version {supported})")]
    UnsupportedVersion { found: u16, supported: u16 },
    /// A list or string holds more than its capacity.
    #[error("capacity exceeded: {0}")]
    CapacityExceeded(String),
    /// An enum code or name that the protocol does not define.
    #[error("unknown enum value: {0}")]
    UnknownEnumValue(String),
}

impl WireError {
    /// A decoder's error, typed by what this crate's own deserialisation code recorded when
    /// it failed ([`refuse`]); anything else the decoders report is malformed input.
    pub(crate) fn from_decoder(msg: String) -> Self {
        match FAILURE.take() {
            Some(Failure::Capacity) => WireError::CapacityExceeded(msg),
            Some(Failure::UnknownEnum) => WireError::UnknownEnumValue(msg),
            None => WireError::Malformed(msg),
        }
    }
}
