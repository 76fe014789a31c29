//! The header every message carries.

use serde::{Deserialize, Serialize};

use crate::validate::check_identifier;
use crate::ValidationError;

/// Version of the wire schema. Bump on any incompatible change to a message.
pub const SCHEMA_VERSION: u32 = 1;

/// Common header of every message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Wire schema version ([`SCHEMA_VERSION`]).
    pub schema: u32,
    /// Per-sender monotonic sequence number, starting at 0 for each new sender instance.
    pub seq: u64,
    /// Time the data was captured or produced, nanoseconds since the UNIX epoch (sender's clock).
    /// Receivers use their own monotonic clock for deadlines; this stamp is for latency and alignment.
    /// Every receiver refuses a stamp further ahead of its own clock than the allowed clock skew
    /// ([`Header::check_not_ahead`]).
    pub stamp_ns: u64,
    /// Robot this message concerns (`[A-Za-z0-9_-]+`, the same id as in the key expression).
    pub robot_id: String,
    /// Coordinate frame of the geometric content ("" when none applies).
    #[serde(default)]
    pub frame_id: String,
    /// Sender instance (service name plus a per-process suffix); sequence numbers are per source.
    pub source: String,
}

impl Header {
    /// A header for `robot_id` from `source`, sequence 0, stamped now.
    pub fn new(robot_id: &str, source: &str, frame_id: &str) -> Self {
        Header {
            schema: SCHEMA_VERSION,
            seq: 0,
            stamp_ns: now_ns(),
            robot_id: robot_id.to_string(),
            frame_id: frame_id.to_string(),
            source: source.to_string(),
        }
    }

    /// Header checks common to all messages.
    pub fn validate(&self) -> Result<(), ValidationError> {
        if self.schema != SCHEMA_VERSION {
            return Err(ValidationError::SchemaVersion {
                got: self.schema,
                expected: SCHEMA_VERSION,
            });
        }
        check_identifier("header.robot_id", &self.robot_id)?;
        if self.source.is_empty() {
            return Err(ValidationError::BadIdentifier {
                field: "header.source".into(),
                value: self.source.clone(),
            });
        }
        Ok(())
    }

    /// `Ok` unless the stamp lies more than `max_ahead_ns` after `now_ns` (the receiver's wall
    /// clock): then [`ValidationError::FromFuture`]. Any stamp in the past passes (0, a
    /// simulation clock, a recording): how old is too old is for each receiver to judge.
    pub fn check_not_ahead(&self, now_ns: u64, max_ahead_ns: u64) -> Result<(), ValidationError> {
        if self.stamp_ns <= now_ns.saturating_add(max_ahead_ns) {
            return Ok(());
        }
        Err(ValidationError::FromFuture {
            ahead_ms: (self.stamp_ns - now_ns) as f64 / 1e6,
            limit_ms: max_ahead_ns as f64 / 1e6,
        })
    }

    /// Age of the stamp relative to `now_ns` in milliseconds (negative if from the future).
    pub fn age_ms(&self, now_ns: u64) -> f64 {
        (now_ns as f64 - self.stamp_ns as f64) / 1e6
    }
}

/// Wall-clock time in nanoseconds since the UNIX epoch.
pub fn now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}
