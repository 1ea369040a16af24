//! Enumerations carried on the wire.
//!
//! In the zero-copy payloads an enum is stored as its `u8` code, never as a Rust enum: a
//! peer in shared memory could write any byte, and an invalid discriminant in a Rust enum is
//! undefined behaviour. The message types expose checked accessors that turn the code into
//! the enum (or [`WireError::UnknownEnumValue`](crate::WireError::UnknownEnumValue)).
//!
//! With serde, an enum is a snake_case string in human-readable formats (JSON) and its `u8`
//! code in binary formats (bincode); an unknown name or code is a decoding error.

use core::fmt;

use serde::de::{self, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::error::{refuse, Failure};

/// Generates a `#[repr(u8)]` wire enum with explicit codes and names, its serde impls, and a
/// serde adapter module for a `u8` field holding its code.
macro_rules! wire_enum {
    (
        $(#[$meta:meta])*
        $name:ident, code module $module:ident {
            $( $(#[$vmeta:meta])* $variant:ident = $code:literal => $text:literal, )+
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        #[repr(u8)]
        pub enum $name {
            $( $(#[$vmeta])* $variant = $code, )+
        }

        impl $name {
            /// Every value, in code order.
            pub const ALL: &'static [$name] = &[$($name::$variant),+];
            /// The snake_case names, in code order.
            pub const NAMES: &'static [&'static str] = &[$($text),+];

            /// The `u8` code on the wire.
            pub const fn code(self) -> u8 {
                self as u8
            }

            /// The value with this code, if there is one.
            pub const fn from_code(code: u8) -> Option<Self> {
                match code {
                    $( $code => Some($name::$variant), )+
                    _ => None,
                }
            }

            /// The snake_case name used in JSON.
            pub const fn name(self) -> &'static str {
                match self {
                    $( $name::$variant => $text, )+
                }
            }

            /// The value with this snake_case name, if there is one.
            pub fn from_name(name: &str) -> Option<Self> {
                match name {
                    $( $text => Some($name::$variant), )+
                    _ => None,
                }
            }

            pub(crate) fn checked(code: u8) -> Result<Self, crate::WireError> {
                Self::from_code(code).ok_or_else(|| {
                    crate::WireError::UnknownEnumValue(format!(
                        "code {code} is not a {}",
                        stringify!($name)
                    ))
                })
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(self.name())
            }
        }

        impl Serialize for $name {
            fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                if serializer.is_human_readable() {
                    serializer.serialize_str(self.name())
                } else {
                    serializer.serialize_u8(self.code())
                }
            }
        }

        impl<'de> Deserialize<'de> for $name {
            fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
                struct V;
                impl<'de> Visitor<'de> for V {
                    type Value = $name;
                    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                        write!(f, "a {} name or code", stringify!($name))
                    }
                    fn visit_str<E: de::Error>(self, v: &str) -> Result<$name, E> {
                        $name::from_name(v).ok_or_else(|| refuse(
                            Failure::UnknownEnum,
                            format_args!("unknown variant `{v}` of {}, expected one of {:?}", stringify!($name), $name::NAMES),
                        ))
                    }
                    fn visit_u64<E: de::Error>(self, v: u64) -> Result<$name, E> {
                        u8::try_from(v)
                            .ok()
                            .and_then($name::from_code)
                            .ok_or_else(|| refuse(
                                Failure::UnknownEnum,
                                format_args!("unknown variant code {v} for {}", stringify!($name)),
                            ))
                    }
                }
                if deserializer.is_human_readable() {
                    deserializer.deserialize_str(V)
                } else {
                    deserializer.deserialize_u8(V)
                }
            }
        }

        /// Serde adapter for a `u8` field that holds the code of this enum: the field
        /// (de)serializes exactly like the enum. An unknown code is still encoded (as the
        /// bare number) so that encoding never fails; decoding rejects it.
        pub(crate) mod $module {
            use super::$name;
            use serde::{Deserialize, Deserializer, Serialize, Serializer};

            pub fn serialize<S: Serializer>(code: &u8, serializer: S) -> Result<S::Ok, S::Error> {
                match $name::from_code(*code) {
                    Some(value) => value.serialize(serializer),
                    None => serializer.serialize_u8(*code),
                }
            }

            pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<u8, D::Error> {
                $name::deserialize(deserializer).map($name::code)
            }
        }
    };
}

wire_enum! {
    /// Which part of the planner produced a decision.
    Layer, code module layer_code {
        /// The nominal MPC.
        Nominal = 0 => "nominal",
        /// Layer A: bounded global relaxation.
        GlobalRelaxation = 1 => "global_relaxation",
        /// Layer B: the deterministic fallback, chosen by the decision core.
        Fallback = 2 => "fallback",
        /// The service's watchdog answered with the fallback because the deadline ran out.
        WatchdogFallback = 3 => "watchdog_fallback",
        /// The request was already older than its deadline when it arrived (by its
        /// `sent_at_ns`): the fallback at once, no solve of the old scene.
        StaleFallback = 4 => "stale_fallback",
    }
}

wire_enum! {
    /// Why a request was rejected. Codes 1..=9 are found on the wire alone
    /// ([`PlanRequest::check_wire`](crate::PlanRequest::check_wire)), 10..=29 mirror the decision
    /// core's input checks one to one, 30.. are conditions of the service.
    RejectReason, code module reject_reason_code {
        /// The request carries another protocol version; `field` is `version`.
        UnsupportedVersion = 1 => "unsupported_version",
        /// A list holds more elements than its capacity (only possible in corrupted shared
        /// memory or from a conversion); `field` names the list.
        CapacityExceeded = 2 => "capacity_exceeded",
        /// A number is NaN or infinite.
        NonFinite = 10 => "non_finite",
        /// A number is outside its plausible range.
        OutOfRange = 11 => "out_of_range",
        /// A speed is negative.
        NegativeSpeed = 12 => "negative_speed",
        /// The road has no lanes or more than the planner supports.
        LaneCount = 13 => "lane_count",
        /// A lane index or a lateral position is off the road.
        LaneOutOfRange = 14 => "lane_out_of_range",
        /// A longitudinal maneuver state is outside -1..=1.
        BetaOutOfRange = 15 => "beta_out_of_range",
        /// Two SVs share an id.
        DuplicateSvId = 16 => "duplicate_sv_id",
        /// More SVs than the planner's configured capacity.
        TooManyVehicles = 17 => "too_many_vehicles",
        /// The planner memory sent back is inconsistent.
        InvalidMemory = 18 => "invalid_memory",
        /// The request could not be decoded; vehicle id and sequence are 0 when unknown.
        Malformed = 30 => "malformed",
        /// The service is at capacity and did not queue the request.
        Overloaded = 31 => "overloaded",
        /// The planner failed internally (solver or configuration error).
        InternalError = 32 => "internal_error",
    }
}
