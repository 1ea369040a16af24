//! Authenticated answers: the planner signs every [`PlanResponse`] with an Ed25519 key, a
//! vehicle configured with the matching public key rejects what does not verify.
//!
//! The signed bytes are the response's bincode encoding without its trailing `signature`
//! field (a prefix of the encoding), whatever form carried it (bincode, JSON, shared memory):
//! they include the version, the vehicle id and the sequence, so an answer replayed for
//! another request does not verify. Keys are files of 64 hex digits (32 bytes): the secret
//! seed for the planner, the public key for the vehicles (`planner keygen` writes both).

use std::path::{Path, PathBuf};

use ed25519_dalek::{Signer, SigningKey, VerifyingKey};
use thiserror::Error;

use crate::codec::encode_bincode;
use crate::messages::PlanResponse;
use crate::signature::{parse_hex, to_hex, Signature, SIGNATURE_LENGTH};

/// Length of a key (secret seed or public key), bytes.
pub const KEY_LENGTH: usize = 32;

/// A key file that cannot be used.
#[derive(Debug, Error)]
pub enum KeyError {
    #[error("reading the key file {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("the key file {path} does not hold 64 hex digits (a 32-byte Ed25519 key)")]
    Format { path: PathBuf },
    #[error("the key file {path} does not hold a valid Ed25519 public key")]
    InvalidPublicKey { path: PathBuf },
}

/// Why a vehicle refuses an answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum VerifyError {
    /// The answer carries no signature (all zeros).
    #[error("the answer is not signed")]
    Unsigned,
    /// The signature is not the planner's signature of these bytes: a forgery, an answer
    /// altered on the way, or one signed with another key.
    #[error("the answer's signature does not verify with the planner's key")]
    BadSignature,
}

/// The bytes a signature covers: the bincode encoding up to the signature.
pub fn signed_bytes(response: &PlanResponse) -> Vec<u8> {
    let mut bytes = encode_bincode(response);
    bytes.truncate(bytes.len().saturating_sub(SIGNATURE_LENGTH));
    bytes
}

/// The planner's side: signs answers.
#[derive(Clone)]
pub struct ResponseSigner {
    key: SigningKey,
}

impl std::fmt::Debug for ResponseSigner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Never print the secret.
        f.debug_struct("ResponseSigner")
            .field("public_key", &to_hex(self.key.verifying_key().as_bytes()))
            .finish()
    }
}

impl ResponseSigner {
    /// A signer from a 32-byte secret seed.
    pub fn from_seed(seed: &[u8; KEY_LENGTH]) -> Self {
        Self {
            key: SigningKey::from_bytes(seed),
        }
    }

    /// Reads the secret seed from a key file.
    pub fn from_file(path: &Path) -> Result<Self, KeyError> {
        Ok(Self::from_seed(&read_key(path)?))
    }

    /// Sets `response.signature` to the signature of its [`signed_bytes`].
    pub fn sign(&self, response: &mut PlanResponse) {
        response.signature = Signature(self.key.sign(&signed_bytes(response)).to_bytes());
    }

    /// The public key vehicles verify with.
    pub fn verifier(&self) -> ResponseVerifier {
        ResponseVerifier {
            key: self.key.verifying_key(),
        }
    }

    /// The secret seed as 64 hex digits (the key file's content).
    pub fn seed_hex(&self) -> String {
        to_hex(&self.key.to_bytes())
    }
}

/// The vehicle's side: checks answers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ResponseVerifier {
    key: VerifyingKey,
}

impl ResponseVerifier {
    /// A verifier from a 32-byte public key; `None` if the bytes are not a curve point.
    pub fn from_bytes(bytes: &[u8; KEY_LENGTH]) -> Option<Self> {
        VerifyingKey::from_bytes(bytes).ok().map(|key| Self { key })
    }

    /// Reads the public key from a key file.
    pub fn from_file(path: &Path) -> Result<Self, KeyError> {
        Self::from_bytes(&read_key(path)?).ok_or_else(|| KeyError::InvalidPublicKey { path: path.into() })
    }

    /// Whether `response` carries the planner's signature of its own bytes. Strict
    /// verification: no malleable or small-order encodings.
    pub fn verify(&self, response: &PlanResponse) -> Result<(), VerifyError> {
        if response.signature.is_unsigned() {
            return Err(VerifyError::Unsigned);
        }
        let signature = ed25519_dalek::Signature::from_bytes(&response.signature.0);
        self.key
            .verify_strict(&signed_bytes(response), &signature)
            .map_err(|_| VerifyError::BadSignature)
    }

    /// The public key as 64 hex digits (the key file's content).
    pub fn to_hex(&self) -> String {
        to_hex(self.key.as_bytes())
    }
}

fn read_key(path: &Path) -> Result<[u8; KEY_LENGTH], KeyError> {
    let text = std::fs::read_to_string(path).map_err(|source| KeyError::Io {
        path: path.into(),
        source,
    })?;
    parse_hex(text.trim()).ok_or_else(|| KeyError::Format { path: path.into() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::messages::Rejected;
    use crate::RejectReason;

    fn response() -> PlanResponse {
        PlanResponse::rejected(7, 42, Rejected::new(RejectReason::NegativeSpeed, "ego.v_mps"), 5)
    }

    #[test]
    fn a_signed_answer_verifies_and_any_change_breaks_it() {
        let signer = ResponseSigner::from_seed(&[7; KEY_LENGTH]);
        let verifier = signer.verifier();
        let mut r = response();
        assert_eq!(verifier.verify(&r), Err(VerifyError::Unsigned));
        signer.sign(&mut r);
        assert_eq!(verifier.verify(&r), Ok(()));
        // The same answer for another request (a replay) or changed in transit.
        for change in [
            |r: &mut PlanResponse| r.sequence += 1,
            |r: &mut PlanResponse| r.vehicle_id = 8,
            |r: &mut PlanResponse| r.queue_us += 1,
            |r: &mut PlanResponse| r.signature.0[0] ^= 1,
        ] {
            let mut altered = r.clone();
            change(&mut altered);
            assert_eq!(verifier.verify(&altered), Err(VerifyError::BadSignature));
        }
        // Another planner's key.
        let other = ResponseSigner::from_seed(&[8; KEY_LENGTH]);
        let mut forged = response();
        other.sign(&mut forged);
        assert_eq!(verifier.verify(&forged), Err(VerifyError::BadSignature));
    }

    #[test]
    fn the_signed_bytes_are_the_encoding_up_to_the_signature() {
        let mut r = response();
        ResponseSigner::from_seed(&[1; KEY_LENGTH]).sign(&mut r);
        let full = encode_bincode(&r);
        assert_eq!(signed_bytes(&r), full[..full.len() - SIGNATURE_LENGTH]);
        assert_eq!(full[full.len() - SIGNATURE_LENGTH..], r.signature.0);
    }

    #[test]
    fn key_files_round_trip_and_bad_ones_are_typed_errors() {
        let dir = std::env::temp_dir().join(format!("hmdp-keys-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let signer = ResponseSigner::from_seed(&[3; KEY_LENGTH]);
        let (secret, public) = (dir.join("planner.key"), dir.join("planner.pub"));
        std::fs::write(&secret, signer.seed_hex() + "\n").unwrap();
        std::fs::write(&public, signer.verifier().to_hex()).unwrap();
        let read = ResponseSigner::from_file(&secret).unwrap();
        assert_eq!(read.verifier(), ResponseVerifier::from_file(&public).unwrap());
        std::fs::write(&public, "not hex").unwrap();
        assert!(matches!(
            ResponseVerifier::from_file(&public),
            Err(KeyError::Format { .. })
        ));
        assert!(matches!(
            ResponseVerifier::from_file(&dir.join("missing")),
            Err(KeyError::Io { .. })
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn hex_parses_exact_lengths_only() {
        assert_eq!(parse_hex::<2>("0aFf"), Some([0x0a, 0xff]));
        assert_eq!(parse_hex::<2>("0aF"), None);
        assert_eq!(parse_hex::<2>("0aFg"), None);
        assert_eq!(to_hex(&[0x0a, 0xff]), "0aff");
    }
}
