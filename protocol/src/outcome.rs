//! [`Outcome`]: a decision or a rejection, stored without a Rust enum discriminant so that it
//! can live in shared memory, with the serde form of an externally tagged enum.

use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;
use serde::de::{self, EnumAccess, VariantAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::error::{refuse, Failure, WireError};
use crate::messages::{Decided, Rejected};

/// The outcome of a request: a decision or a rejection.
///
/// Stored as a kind code plus both bodies (the inactive one is default), so that no Rust
/// enum discriminant lives in shared memory. Read it with [`Outcome::get`]. With serde it
/// is an externally tagged enum: `{"decided": {...}}` / `{"rejected": {...}}` in JSON, a
/// `u32` variant index (0 decided, 1 rejected) followed by the body in bincode.
#[derive(Debug, Clone, ZeroCopySend)]
#[type_name("hmdp::Outcome/v3")]
#[repr(C)]
pub struct Outcome {
    kind: u8,
    decided: Decided,
    rejected: Rejected,
}

/// A checked view of an [`Outcome`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OutcomeRef<'a> {
    Decided(&'a Decided),
    Rejected(&'a Rejected),
}

impl Outcome {
    /// Kind code of a decision.
    pub const DECIDED: u8 = 0;
    /// Kind code of a rejection.
    pub const REJECTED: u8 = 1;

    pub fn decided(decided: Decided) -> Self {
        Self {
            kind: Self::DECIDED,
            decided,
            rejected: Rejected::default(),
        }
    }

    pub fn rejected(rejected: Rejected) -> Self {
        Self {
            kind: Self::REJECTED,
            decided: Decided::default(),
            rejected,
        }
    }

    /// The raw kind code as stored.
    pub fn kind_code(&self) -> u8 {
        self.kind
    }

    /// The outcome; an unknown kind code is an error.
    pub fn get(&self) -> Result<OutcomeRef<'_>, WireError> {
        match self.kind {
            Self::DECIDED => Ok(OutcomeRef::Decided(&self.decided)),
            Self::REJECTED => Ok(OutcomeRef::Rejected(&self.rejected)),
            other => Err(WireError::UnknownEnumValue(format!("code {other} is not an Outcome"))),
        }
    }

    /// The decision, if this is one.
    pub fn as_decided(&self) -> Option<&Decided> {
        (self.kind == Self::DECIDED).then_some(&self.decided)
    }

    /// The rejection, if this is one.
    pub fn as_rejected(&self) -> Option<&Rejected> {
        (self.kind == Self::REJECTED).then_some(&self.rejected)
    }
}

impl PartialEq for Outcome {
    /// Equal when the kinds are equal and the active bodies are equal.
    fn eq(&self, other: &Self) -> bool {
        self.kind == other.kind
            && match self.kind {
                Self::DECIDED => self.decided == other.decided,
                Self::REJECTED => self.rejected == other.rejected,
                _ => true,
            }
    }
}

impl Serialize for Outcome {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self.kind {
            Self::DECIDED => serializer.serialize_newtype_variant("Outcome", 0, "decided", &self.decided),
            Self::REJECTED => serializer.serialize_newtype_variant("Outcome", 1, "rejected", &self.rejected),
            // Encoding never fails; decoders reject the unknown variant.
            other => serializer.serialize_newtype_variant("Outcome", u32::from(other), "unknown", &self.rejected),
        }
    }
}

/// The variant of an [`Outcome`] being decoded: its name (JSON) or index (bincode); an
/// unknown one is a typed refusal.
enum OutcomeTag {
    Decided,
    Rejected,
}

impl<'de> Deserialize<'de> for OutcomeTag {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = OutcomeTag;
            fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                f.write_str("`decided` or `rejected` (variant 0 or 1)")
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<OutcomeTag, E> {
                match v {
                    0 => Ok(OutcomeTag::Decided),
                    1 => Ok(OutcomeTag::Rejected),
                    _ => Err(refuse(
                        Failure::UnknownEnum,
                        format_args!("unknown Outcome variant {v}"),
                    )),
                }
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<OutcomeTag, E> {
                match v {
                    "decided" => Ok(OutcomeTag::Decided),
                    "rejected" => Ok(OutcomeTag::Rejected),
                    _ => Err(refuse(
                        Failure::UnknownEnum,
                        format_args!("unknown Outcome variant `{v}`"),
                    )),
                }
            }
        }
        deserializer.deserialize_identifier(V)
    }
}

impl<'de> Deserialize<'de> for Outcome {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Outcome;
            fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                f.write_str("an Outcome: `decided` or `rejected` with its body")
            }
            fn visit_enum<A: EnumAccess<'de>>(self, data: A) -> Result<Outcome, A::Error> {
                Ok(match data.variant()? {
                    (OutcomeTag::Decided, body) => Outcome::decided(body.newtype_variant()?),
                    (OutcomeTag::Rejected, body) => Outcome::rejected(body.newtype_variant()?),
                })
            }
        }
        deserializer.deserialize_enum("Outcome", &["decided", "rejected"], V)
    }
}
