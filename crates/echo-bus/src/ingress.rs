//! The receive path of every typed subscription, without the network: size guard → JSON decode
//! → validation → robot id → per-source sequence order. Every rejection is counted in [`Stats`]
//! under `<edge>/<reason>` and logged (rate-limited).

use std::sync::Arc;

use echo_msgs::{decode, DecodeError, Message, SeqTracker, ValidationError};

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

/// Decoder for one edge.
#[derive(Debug)]
pub struct Ingress {
    edge: &'static str,
    robot: Option<RobotId>,
    seq: SeqTracker,
    stats: Arc<Stats>,
}

impl Ingress {
    /// An ingress for `edge` of `robot` (None: accept any robot, e.g. fleet monitors).
    pub fn new(edge: &'static str, robot: Option<RobotId>, stats: Arc<Stats>) -> Self {
        Ingress {
            edge,
            robot,
            seq: SeqTracker::new(),
            stats,
        }
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
}
