//! Typed validation errors.

/// Why a message was rejected. Each variant has a short stable [`reason`](Self::reason) label
/// used as a counter name in service status.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ValidationError {
    /// Header schema version differs from this build's.
    #[error("schema version {got} is not supported (expected {expected})")]
    SchemaVersion {
        /// Version found.
        got: u32,
        /// Version this build speaks.
        expected: u32,
    },
    /// A number is NaN or infinite.
    #[error("non-finite value in {field}")]
    NonFinite {
        /// Path of the offending field.
        field: String,
    },
    /// An array has the wrong length.
    #[error("{field} has {got} entries, expected {expected}")]
    WrongSize {
        /// Path of the offending field.
        field: String,
        /// Length found.
        got: usize,
        /// Length required.
        expected: usize,
    },
    /// A joint name is not known to the receiver.
    #[error("unknown joint '{name}' in {field}")]
    UnknownJoint {
        /// Path of the offending field.
        field: String,
        /// The unknown name.
        name: String,
    },
    /// A quaternion is not of unit length.
    #[error("{field} is not a unit quaternion (norm {norm:.6})")]
    NotUnitQuaternion {
        /// Path of the offending field.
        field: String,
        /// Its norm.
        norm: f64,
    },
    /// A value lies outside its allowed range.
    #[error("{field} = {value} is outside [{min}, {max}]")]
    OutOfRange {
        /// Path of the offending field.
        field: String,
        /// Value found.
        value: f64,
        /// Lower bound.
        min: f64,
        /// Upper bound.
        max: f64,
    },
    /// Sequence number did not increase.
    #[error("sequence number {got} from '{source_id}' is not after {last}")]
    OutOfOrder {
        /// Sender instance.
        source_id: String,
        /// Last accepted sequence number.
        last: u64,
        /// Sequence number received.
        got: u64,
    },
    /// Sequence number jumped further past the last one than any sender can have published
    /// since (a forged or corrupt number; see `SeqTracker`).
    #[error("sequence number {got} from '{source_id}' jumps implausibly far past {last}")]
    SeqJump {
        /// Sender instance.
        source_id: String,
        /// Last accepted sequence number.
        last: u64,
        /// Sequence number received.
        got: u64,
    },
    /// Times that must increase do not.
    #[error("{field} is not strictly increasing at index {index}")]
    NotIncreasing {
        /// Path of the offending field.
        field: String,
        /// First index that breaks the order.
        index: usize,
    },
    /// A required text field is empty or has characters that cannot appear in a key expression.
    #[error("{field} '{value}' is empty or not of [A-Za-z0-9_-]")]
    BadIdentifier {
        /// Path of the offending field.
        field: String,
        /// The value.
        value: String,
    },
    /// The message is older than the receiver accepts.
    #[error("message is stale: {age_ms:.1} ms old (limit {limit_ms:.1} ms)")]
    Stale {
        /// Age at receipt.
        age_ms: f64,
        /// Accepted maximum.
        limit_ms: f64,
    },
    /// Stamped further ahead of the receiver's clock than the clock skew it allows.
    #[error("stamped {ahead_ms:.1} ms ahead of the receiver's clock (limit {limit_ms:.1} ms)")]
    FromFuture {
        /// How far ahead of the receiver's clock, ms.
        ahead_ms: f64,
        /// Accepted maximum, ms.
        limit_ms: f64,
    },
    /// Message is addressed to another frame than the receiver expects.
    #[error("frame_id '{got}' is not the expected '{expected}'")]
    WrongFrame {
        /// Frame found.
        got: String,
        /// Frame required.
        expected: String,
    },
    /// Anything else, with an explanation.
    #[error("{0}")]
    Other(String),
}

impl ValidationError {
    /// Short stable label of the error kind, for counters.
    pub fn reason(&self) -> &'static str {
        match self {
            ValidationError::SchemaVersion { .. } => "schema_version",
            ValidationError::NonFinite { .. } => "non_finite",
            ValidationError::WrongSize { .. } => "wrong_size",
            ValidationError::UnknownJoint { .. } => "unknown_joint",
            ValidationError::NotUnitQuaternion { .. } => "not_unit_quaternion",
            ValidationError::OutOfRange { .. } => "out_of_range",
            ValidationError::OutOfOrder { .. } => "out_of_order",
            ValidationError::SeqJump { .. } => "seq_jump",
            ValidationError::NotIncreasing { .. } => "not_increasing",
            ValidationError::BadIdentifier { .. } => "bad_identifier",
            ValidationError::Stale { .. } => "stale",
            ValidationError::FromFuture { .. } => "from_future",
            ValidationError::WrongFrame { .. } => "wrong_frame",
            ValidationError::Other(_) => "invalid",
        }
    }
}
