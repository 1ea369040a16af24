//! The signature a [`crate::PlanResponse`] carries, and the hex form of keys and signatures:
//! what the messages, their serde form and the signing code share (a leaf of the crate).

use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// Length of an Ed25519 signature, bytes.
pub const SIGNATURE_LENGTH: usize = 64;

/// The signature of a [`crate::PlanResponse`]: 64 bytes, all zeros when unsigned.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[type_name("hmdp::Signature/v3")]
#[repr(C)]
pub struct Signature(pub [u8; SIGNATURE_LENGTH]);

impl Signature {
    /// No signature.
    pub const UNSIGNED: Self = Self([0; SIGNATURE_LENGTH]);

    pub fn is_unsigned(&self) -> bool {
        *self == Self::UNSIGNED
    }
}

impl Default for Signature {
    fn default() -> Self {
        Self::UNSIGNED
    }
}

/// Exactly `2 * N` hex digits (either case) as `N` bytes.
pub fn parse_hex<const N: usize>(text: &str) -> Option<[u8; N]> {
    let text = text.as_bytes();
    if text.len() != 2 * N {
        return None;
    }
    let digit = |c: u8| (c as char).to_digit(16).map(|d| d as u8);
    let mut out = [0u8; N];
    for (byte, pair) in out.iter_mut().zip(text.chunks_exact(2)) {
        *byte = digit(pair[0])? << 4 | digit(pair[1])?;
    }
    Some(out)
}

/// Lowercase hex.
pub fn to_hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}
