//! The receive path of every typed subscription, without the network: size guard → JSON decode
//! → validation → robot id → clock skew → per-source sequence order. Every rejection is counted
//! in [`Stats`] under `<edge>/<reason>` and logged (rate-limited).
//!
//! Clock skew: every message type's `header.stamp_ns` is a wall-clock time (capture or
//! production, ns since the UNIX epoch, the sender's clock; ROS stamps on a simulation clock
//! and the fixed stamps of tests lie in the past). A stamp more than the allowed skew
//! ([`DEFAULT_MAX_CLOCK_SKEW_MS`] unless configured) ahead of this host's clock is refused
//! (`from_future`) before any receiver state is touched, so one message stamped at the end of
//! time cannot make every later real message look old. Stamps in the past all pass: how old is
//! too old is for each receiver to judge.

use std::sync::Arc;

use echo_msgs::{decode, now_ns, DecodeError, Message, SeqTracker, ValidationError};

use crate::{RobotId, Stats};

/// Why an input was rejected.
#[derive(Debug, thiserror::Error)]
pub enum Rejection {
    /// Could not be decoded or failed validation.
    #[error(transparent)]
    Decode(#[from] DecodeError),
    /// Decoded but failed a receiver-side check.
    #[error(transparent)]
    Invalid(#[from] ValidationError),
    /// Addressed to another robot.
    #[error("message for robot '{got}' arrived on robot '{expected}' key")]
    WrongRobot {
        /// Robot id in the header.
        got: String,
        /// Robot of this key.
        expected: String,
    },
}

impl Rejection {
    /// Short label for counters.
    pub fn reason(&self) -> &'static str {
        match self {
            Rejection::Decode(e) => e.reason(),
            Rejection::Invalid(e) => e.reason(),
            Rejection::WrongRobot { .. } => "wrong_robot",
        }
    }
}

/// How far ahead of the receiver's clock a stamp may lie by default, ms: hosts are expected to
/// keep their clocks within this of each other (NTP / chrony).
pub const DEFAULT_MAX_CLOCK_SKEW_MS: u64 = 500;

/// Decoder for one edge.
#[derive(Debug)]
pub struct Ingress {
    edge: &'static str,
    robot: Option<RobotId>,
    seq: SeqTracker,
    max_ahead_ns: u64,
    stats: Arc<Stats>,
}

impl Ingress {
    /// An ingress for `edge` of `robot` (None: accept any robot, e.g. fleet monitors), allowing
    /// [`DEFAULT_MAX_CLOCK_SKEW_MS`] of clock skew.
    pub fn new(edge: &'static str, robot: Option<RobotId>, stats: Arc<Stats>) -> Self {
        Ingress {
            edge,
            robot,
            seq: SeqTracker::new(),
            max_ahead_ns: DEFAULT_MAX_CLOCK_SKEW_MS * 1_000_000,
            stats,
        }
    }

    /// Allow stamps up to `ms` ahead of this host's clock.
    pub fn with_max_clock_skew_ms(mut self, ms: u64) -> Self {
        self.max_ahead_ns = ms.saturating_mul(1_000_000);
        self
    }

    /// Accept `bytes` as an `M`, or reject (counted and logged).
    pub fn accept<M: Message>(&mut self, bytes: &[u8]) -> Result<M, Rejection> {
        self.stats.received(self.edge);
        let result = self.check::<M>(bytes);
        if let Err(e) = &result {
            self.stats.rejected(self.edge, e.reason(), &e.to_string());
        }
        result
    }

    fn check<M: Message>(&mut self, bytes: &[u8]) -> Result<M, Rejection> {
        let msg: M = decode(bytes)?;
        if let Some(r) = &self.robot {
            if msg.header().robot_id != r.as_str() {
                return Err(Rejection::WrongRobot {
                    got: msg.header().robot_id.clone(),
                    expected: r.to_string(),
                });
            }
        }
        msg.header().check_not_ahead(now_ns(), self.max_ahead_ns)?;
        self.seq.check(msg.header())?;
        Ok(msg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use echo_msgs::{encode, EStop, EStopAction, Header};

    fn estop(robot: &str, seq: u64) -> Vec<u8> {
        let mut h = Header::new(robot, "op", "");
        h.seq = seq;
        encode(&EStop {
            header: h,
            action: EStopAction::Engage,
            reason: "test".into(),
        })
    }

    #[test]
    fn counts_every_kind_of_rejection() {
        let stats = Arc::new(Stats::new("t"));
        let mut ing = Ingress::new("estop", Some(RobotId::new("r1").unwrap()), stats.clone());
        assert!(ing.accept::<EStop>(&estop("r1", 1)).is_ok());
        assert_eq!(
            ing.accept::<EStop>(&estop("r1", 1)).unwrap_err().reason(),
            "out_of_order"
        );
        assert_eq!(
            ing.accept::<EStop>(&estop("r2", 9)).unwrap_err().reason(),
            "wrong_robot"
        );
        assert_eq!(
            ing.accept::<EStop>(b"{nope").unwrap_err().reason(),
            "malformed"
        );
        assert!(ing.accept::<EStop>(&estop("r1", 2)).is_ok());
        assert_eq!(stats.received_count("estop"), 5);
        assert_eq!(stats.rejected_count("estop", "out_of_order"), 1);
        assert_eq!(stats.rejected_count("estop", "wrong_robot"), 1);
        assert_eq!(stats.rejected_count("estop", "malformed"), 1);
    }

    fn estop_at(source: &str, seq: u64, stamp_ns: u64) -> Vec<u8> {
        let mut h = Header::new("r1", source, "");
        h.seq = seq;
        h.stamp_ns = stamp_ns;
        encode(&EStop {
            header: h,
            action: EStopAction::Engage,
            reason: "test".into(),
        })
    }

    #[test]
    fn a_message_stamped_ahead_of_the_clock_is_refused_and_changes_nothing() {
        let stats = Arc::new(Stats::new("t"));
        let mut ing = Ingress::new("estop", Some(RobotId::new("r1").unwrap()), stats.clone());
        let now = echo_msgs::now_ns();
        assert!(ing.accept::<EStop>(&estop_at("op", 1, now)).is_ok());
        // The end of time, and ten seconds ahead, from the live source and from a new one.
        for (source, seq, stamp) in [
            ("op", 1_000, u64::MAX),
            ("op", 2, now + 10_000_000_000),
            ("forger", 7, u64::MAX),
        ] {
            assert_eq!(
                ing.accept::<EStop>(&estop_at(source, seq, stamp))
                    .unwrap_err()
                    .reason(),
                "from_future"
            );
        }
        assert_eq!(stats.rejected_count("estop", "from_future"), 3);
        // Nothing was remembered from them: the live source goes on with gap 0 and the forger's
        // first real message is new.
        assert!(ing.accept::<EStop>(&estop_at("op", 2, now)).is_ok());
        assert!(ing.accept::<EStop>(&estop_at("forger", 0, now)).is_ok());
        // Within the skew bound, and any time in the past (a simulation clock, stamp 0), passes:
        // age is for each receiver to judge.
        assert!(ing
            .accept::<EStop>(&estop_at("op", 3, now + 100_000_000))
            .is_ok());
        assert!(ing.accept::<EStop>(&estop_at("op", 4, 0)).is_ok());
    }

    #[test]
    fn the_clock_skew_allowed_is_configurable() {
        let stats = Arc::new(Stats::new("t"));
        let mut ing = Ingress::new("estop", None, stats.clone()).with_max_clock_skew_ms(3_000);
        let now = echo_msgs::now_ns();
        assert!(ing
            .accept::<EStop>(&estop_at("op", 1, now + 2_000_000_000))
            .is_ok());
        let e = ing
            .accept::<EStop>(&estop_at("op", 2, now + 60_000_000_000))
            .unwrap_err();
        assert_eq!(e.reason(), "from_future");
        assert!(e.to_string().contains("limit 3000.0 ms"), "{e}");
    }

    #[test]
    fn a_forged_sequence_number_does_not_silence_the_source() {
        let stats = Arc::new(Stats::new("t"));
        let mut ing = Ingress::new("estop", None, stats.clone());
        let now = echo_msgs::now_ns();
        assert!(ing.accept::<EStop>(&estop_at("op", 1, now)).is_ok());
        assert_eq!(
            ing.accept::<EStop>(&estop_at("op", u64::MAX, now))
                .unwrap_err()
                .reason(),
            "seq_jump"
        );
        assert!(ing.accept::<EStop>(&estop_at("op", 2, now)).is_ok());
        assert_eq!(stats.rejected_count("estop", "seq_jump"), 1);
    }
}
