//! Serde adapters for the fixed-capacity iceoryx2 containers.
//!
//! `StaticVec` and `StaticString` ship serde impls in iceoryx2-bb-container 0.10, but their
//! errors cannot be told apart from other failures and `StaticString` panics when asked to
//! serialize bytes that are not UTF-8. These adapters keep the same wire form (a sequence of
//! the live elements, a string) with typed refusals ([`crate::error::refuse`]) and no panics.

use core::fmt;
use core::marker::PhantomData;

use iceoryx2_bb_container::string::{StaticString, String as _};
use iceoryx2_bb_container::vector::{StaticVec, Vector};
use serde::de::{self, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::error::{refuse, Failure};

/// `StaticVec<T, N>` as a sequence of its live elements; more than `N` is an error.
pub(crate) mod bounded_vec {
    use super::*;

    pub fn serialize<T: Serialize, const N: usize, S: Serializer>(
        v: &StaticVec<T, N>,
        serializer: S,
    ) -> Result<S::Ok, S::Error> {
        serializer.collect_seq(v.as_slice())
    }

    pub fn deserialize<'de, T: Deserialize<'de>, const N: usize, D: Deserializer<'de>>(
        deserializer: D,
    ) -> Result<StaticVec<T, N>, D::Error> {
        deserializer.deserialize_seq(BoundedVisitor::<T, N>(PhantomData))
    }

    struct BoundedVisitor<T, const N: usize>(PhantomData<T>);

    impl<'de, T: Deserialize<'de>, const N: usize> Visitor<'de> for BoundedVisitor<T, N> {
        type Value = StaticVec<T, N>;

        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "a list of at most {N} elements")
        }

        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
            // bincode announces the length up front: refuse before reading any element.
            if let Some(len) = seq.size_hint() {
                if len > N {
                    return Err(refuse(
                        Failure::Capacity,
                        format_args!("a list of {len} elements, at most {N}"),
                    ));
                }
            }
            let mut out = StaticVec::<T, N>::new();
            while let Some(element) = seq.next_element()? {
                if out.push(element).is_err() {
                    return Err(refuse(
                        Failure::Capacity,
                        format_args!("a list of more than {N} elements"),
                    ));
                }
            }
            Ok(out)
        }
    }
}

/// `StaticString<N>` as a string of at most `N` ASCII characters (no NUL).
pub(crate) mod bounded_str {
    use super::*;

    pub fn serialize<const N: usize, S: Serializer>(s: &StaticString<N>, serializer: S) -> Result<S::Ok, S::Error> {
        // Constructed strings are ASCII; bytes written by a faulty peer are replaced, not a panic.
        serializer.serialize_str(&std::string::String::from_utf8_lossy(s.as_bytes()))
    }

    pub fn deserialize<'de, const N: usize, D: Deserializer<'de>>(
        deserializer: D,
    ) -> Result<StaticString<N>, D::Error> {
        deserializer.deserialize_str(StrVisitor::<N>)
    }

    struct StrVisitor<const N: usize>;

    impl<const N: usize> Visitor<'_> for StrVisitor<N> {
        type Value = StaticString<N>;

        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "an ASCII string of at most {N} characters")
        }

        fn visit_str<E: de::Error>(self, v: &str) -> Result<Self::Value, E> {
            if v.len() > N {
                return Err(refuse(
                    Failure::Capacity,
                    format_args!("a string of {} bytes, at most {N}", v.len()),
                ));
            }
            if !v.bytes().all(|b| (1..128).contains(&b)) {
                return Err(E::custom("string contains non-ASCII or NUL characters"));
            }
            StaticString::from_bytes(v.as_bytes()).map_err(|e| E::custom(format_args!("invalid string: {e:?}")))
        }
    }
}

/// [`Signature`](crate::Signature): its 64 bytes as they are in binary formats (no length),
/// 128 lowercase hex digits in human-readable ones, the empty string when unsigned.
pub(crate) mod signature_bytes {
    use super::*;
    use crate::signature::{Signature, SIGNATURE_LENGTH};
    use serde::ser::SerializeTuple;

    pub fn serialize<S: Serializer>(signature: &Signature, serializer: S) -> Result<S::Ok, S::Error> {
        if serializer.is_human_readable() {
            if signature.is_unsigned() {
                return serializer.serialize_str("");
            }
            serializer.serialize_str(&crate::signature::to_hex(&signature.0))
        } else {
            let mut tuple = serializer.serialize_tuple(SIGNATURE_LENGTH)?;
            for byte in &signature.0 {
                tuple.serialize_element(byte)?;
            }
            tuple.end()
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Signature, D::Error> {
        if deserializer.is_human_readable() {
            deserializer.deserialize_str(SignatureVisitor)
        } else {
            deserializer.deserialize_tuple(SIGNATURE_LENGTH, SignatureVisitor)
        }
    }

    struct SignatureVisitor;

    impl<'de> Visitor<'de> for SignatureVisitor {
        type Value = Signature;

        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "{SIGNATURE_LENGTH} signature bytes (128 hex digits, or empty)")
        }

        fn visit_str<E: de::Error>(self, v: &str) -> Result<Signature, E> {
            if v.is_empty() {
                return Ok(Signature::UNSIGNED);
            }
            crate::signature::parse_hex::<SIGNATURE_LENGTH>(v)
                .map(Signature)
                .ok_or_else(|| E::invalid_value(de::Unexpected::Str(v), &self))
        }

        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Signature, A::Error> {
            let mut out = [0u8; SIGNATURE_LENGTH];
            for (i, byte) in out.iter_mut().enumerate() {
                *byte = seq.next_element()?.ok_or_else(|| de::Error::invalid_length(i, &self))?;
            }
            Ok(Signature(out))
        }
    }
}
