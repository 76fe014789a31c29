//! Echo's message contract.
//!
//! Every message that travels on the bus is defined here, with one encode/decode entry point
//! ([`encode`], [`decode`]) and a validation step ([`Validate`]) that every decoded message
//! passes before any service sees it. Units are SI (metres, radians, seconds); frames follow
//! REP-103 (x forward, y left, z up); the robot root frame is [`frames::BASE_FOOTPRINT`].
//!
//! Wire format: JSON (UTF-8). Every message carries a [`Header`] whose `schema` must equal
//! [`SCHEMA_VERSION`]; a receiver rejects other versions instead of guessing.

mod error;
mod header;
mod messages;
mod seq;
pub mod skeleton;
pub mod validate;

pub use error::ValidationError;
pub use header::{now_ns, Header, SCHEMA_VERSION};
pub use messages::*;
pub use seq::{SeqCheck, SeqTracker};
pub use validate::Validate;

/// Well-known frame ids.
pub mod frames {
    /// Robot root frame, on the floor between the wheels (REP-103).
    pub const BASE_FOOTPRINT: &str = "base_footprint";
    /// The head camera's optical frame (z forward, x right, y down; REP-103 optical convention).
    pub const HEAD_CAMERA_OPTICAL: &str = "head_front_camera_optical_frame";
}

/// Errors from [`decode`].
#[derive(Debug, thiserror::Error)]
pub enum DecodeError {
    /// Payload is not valid JSON for the expected message type.
    #[error("malformed {kind} message: {source}")]
    Malformed {
        /// Message kind that was expected.
        kind: &'static str,
        /// The JSON error (line/column and what was wrong).
        source: serde_json::Error,
    },
    /// Payload parsed but failed validation.
    #[error("invalid {kind} message: {source}")]
    Invalid {
        /// Message kind that was expected.
        kind: &'static str,
        /// What was wrong.
        source: ValidationError,
    },
    /// Payload is larger than the receiver accepts.
    #[error("{kind} message of {size} bytes exceeds the {limit}-byte limit")]
    TooLarge {
        /// Message kind that was expected.
        kind: &'static str,
        /// Payload size.
        size: usize,
        /// Accepted maximum.
        limit: usize,
    },
}

impl DecodeError {
    /// A short, stable label for counters ("malformed", "too_large", or the validation reason).
    pub fn reason(&self) -> &'static str {
        match self {
            DecodeError::Malformed { .. } => "malformed",
            DecodeError::TooLarge { .. } => "too_large",
            DecodeError::Invalid { source, .. } => source.reason(),
        }
    }
}

/// Largest payload any Echo receiver accepts (1 MiB): bigger payloads are rejected unparsed.
pub const MAX_PAYLOAD_BYTES: usize = 1 << 20;

/// A message type of the contract.
pub trait Message:
    serde::Serialize + serde::de::DeserializeOwned + Validate + Send + 'static
{
    /// Stable name of the message kind (used in logs, counters and docs).
    const KIND: &'static str;
    /// The message header.
    fn header(&self) -> &Header;
    /// Mutable header (publishers stamp sequence numbers and times).
    fn header_mut(&mut self) -> &mut Header;
}

/// Encode a message as JSON bytes.
pub fn encode<M: Message>(msg: &M) -> Vec<u8> {
    // Serialising plain data structs with string keys cannot fail.
    serde_json::to_vec(msg).unwrap_or_default()
}

/// Decode and validate a message from JSON bytes.
pub fn decode<M: Message>(bytes: &[u8]) -> Result<M, DecodeError> {
    if bytes.len() > MAX_PAYLOAD_BYTES {
        return Err(DecodeError::TooLarge {
            kind: M::KIND,
            size: bytes.len(),
            limit: MAX_PAYLOAD_BYTES,
        });
    }
    let msg: M = serde_json::from_slice(bytes).map_err(|source| DecodeError::Malformed {
        kind: M::KIND,
        source,
    })?;
    msg.header()
        .validate()
        .and_then(|_| msg.validate())
        .map_err(|source| DecodeError::Invalid {
            kind: M::KIND,
            source,
        })?;
    Ok(msg)
}
