//! Recording Echo's bus traffic to MCAP and playing it back.
//!
//! * [`mcap_file`]: the file format side — one MCAP channel per key expression, messages with
//!   their receive time as `log_time`, JSON payloads kept byte for byte; reading a recording back.
//! * [`live`]: the bus side — subscribe to key expressions and record ([`live::record`]), or
//!   publish a recording at its original rate or faster ([`live::replay`]).

pub mod live;
pub mod mcap_file;

pub use mcap_file::{read_recording, Recorded, Recorder, RecordingError};
