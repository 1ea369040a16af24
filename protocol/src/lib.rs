//! The wire contract of the HMDP planner service, shared by every process.
//!
//! * [`PlanRequest`] (a perception snapshot) and [`PlanResponse`] (a decision or a typed
//!   rejection): one definition each, `#[repr(C)]` with fixed capacity so that they are
//!   iceoryx2 zero-copy payloads, and serde types for bincode and JSON.
//! * Codecs: [`encode_bincode`] / [`decode_bincode`] with a fixed configuration
//!   ([`BINCODE_CONFIG`]), [`encode_json`] / [`decode_json`]; errors are [`WireError`].
//! * [`PlanRequest::check_wire`]: what the wire alone can check; with the `decision` feature
//!   `PlanRequest::validate` runs every check once and gives a `ValidRequest`, which
//!   `answer` and `fallback_answer` take: the one path from a request to its answer.
//! * [`PlanRequest::is_stale_at`]: when a request is too old to solve; [`ResponseSigner`] /
//!   [`ResponseVerifier`]: signed answers.
//! * The iceoryx2 service names, Zenoh key expressions and encodings ([`ZENOH_PLAN_KEY`], ...).
//! * With the `decision` feature: conversions to and from the decision core's types.
//!
//! The byte layout, the JSON form and the versioning rules are in `docs/protocol.md`.

// The containers log through iceoryx2-log, which links against the logger this crate
// provides; without this line the linker may drop it.
use iceoryx2_bb_loggers as _;

// The modules from the leaves up (each uses only those before it): error, signature; enums;
// serde_util; messages (and its outcome); codec; format, validate, names, signing, staleness; convert, answer.
#[cfg(feature = "decision")]
mod answer;
mod codec;
#[cfg(feature = "decision")]
mod convert;
mod enums;
mod error;
mod format;
mod messages;
mod names;
mod outcome;
mod serde_util;
mod signature;
mod signing;
mod staleness;
mod validate;

#[cfg(feature = "decision")]
pub use answer::{answer, fallback_answer, InvalidRequest, ValidRequest};
pub use codec::{
    decode_bincode, decode_json, decode_json_str, encode_bincode, encode_json, encode_json_pretty,
    worked_example_request, WireMessage, BINCODE_CONFIG, MAX_MESSAGE_BYTES,
};
pub use enums::{Layer, RejectReason};
pub use error::WireError;
pub use format::{layout, WireFormat};
pub use messages::{
    bounded, Action, ActionList, CorrectiveEntry, CorrectiveList, Decided, EgoState, FieldName, Maneuver, Outcome,
    OutcomeRef, PlanRequest, PlanResponse, PlanStep, PlanStepList, PlannerMemory, Rejected, Road, SetPoint, SvList,
    SvObservation, DEFAULT_DEADLINE, FIELD_NAME_CAPACITY, MAX_CORRECTIVE, MAX_HORIZON, MAX_SVS, PROBE_VERSION,
    PROTOCOL_VERSION,
};
pub use names::*;
pub use signature::{parse_hex, to_hex, Signature, SIGNATURE_LENGTH};
pub use signing::{signed_bytes, KeyError, ResponseSigner, ResponseVerifier, VerifyError, KEY_LENGTH};
pub use staleness::{unix_now_ns, DEFAULT_CLOCK_SKEW_TOLERANCE};

/// The iceoryx2 building blocks the payloads are made of, re-exported so that users need no
/// direct dependency: `StaticVec` with its `Vector` trait (`push`, `len`, ...), `StaticString`,
/// and the `ZeroCopySend` trait (the one `iceoryx2::prelude` re-exports).
pub mod containers {
    pub use iceoryx2_bb_container::string::{StaticString, String};
    pub use iceoryx2_bb_container::vector::{StaticVec, Vector};
    pub use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;
}
