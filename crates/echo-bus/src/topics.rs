//! Each edge of the data flow as a typed topic: key expression, message type and delivery policy.

use std::marker::PhantomData;

use echo_msgs::*;
use zenoh::qos::{CongestionControl, Priority};

use crate::keys::{self, RobotId};

/// How an edge delivers messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Delivery {
    /// Sensor stream: the network drops under congestion, and the receiver keeps the newest
    /// `depth` messages, dropping (and counting) the oldest.
    SensorDropOldest {
        /// Receiver queue depth.
        depth: usize,
    },
    /// Command: RealTime priority, express, blocking congestion control; the receiver queue
    /// applies back-pressure instead of dropping.
    CommandBlock {
        /// Receiver queue depth before back-pressure.
        depth: usize,
    },
    /// Status / low-rate information: Data priority, dropped under congestion, newest kept.
    Status {
        /// Receiver queue depth.
        depth: usize,
    },
}

impl Delivery {
    /// Zenoh congestion control for publishers on this edge.
    pub fn congestion_control(self) -> CongestionControl {
        match self {
            Delivery::CommandBlock { .. } => CongestionControl::Block,
            _ => CongestionControl::Drop,
        }
    }

    /// Zenoh priority for publishers on this edge.
    pub fn priority(self) -> Priority {
        match self {
            Delivery::CommandBlock { .. } => Priority::RealTime,
            Delivery::SensorDropOldest { .. } => Priority::InteractiveHigh,
            Delivery::Status { .. } => Priority::Data,
        }
    }

    /// Whether messages skip batching.
    pub fn express(self) -> bool {
        !matches!(self, Delivery::Status { .. })
    }

    /// Receiver queue depth.
    pub fn depth(self) -> usize {
        match self {
            Delivery::SensorDropOldest { depth }
            | Delivery::CommandBlock { depth }
            | Delivery::Status { depth } => depth.max(1),
        }
    }
}

/// A typed edge: messages of type `M` on `key` with `delivery`.
#[derive(Debug, Clone)]
pub struct Topic<M> {
    /// Key expression.
    pub key: String,
    /// Short name used in counters ("humans", "robot_state" …).
    pub name: &'static str,
    /// Delivery policy.
    pub delivery: Delivery,
    /// Robot whose messages this topic carries (`None` for fleet-wide wildcards).
    pub robot: Option<RobotId>,
    _msg: PhantomData<fn() -> M>,
}

impl<M: Message> Topic<M> {
    fn new(key: String, name: &'static str, delivery: Delivery) -> Self {
        Topic {
            key,
            name,
            delivery,
            robot: None,
            _msg: PhantomData,
        }
    }

    fn of(mut self, robot: &RobotId) -> Self {
        self.robot = Some(robot.clone());
        self
    }
}

const SENSOR: Delivery = Delivery::SensorDropOldest { depth: 8 };
const COMMAND: Delivery = Delivery::CommandBlock { depth: 64 };
const STATUS: Delivery = Delivery::Status { depth: 16 };

/// Pose-estimator keypoints → perception bridge. Sensor stream.
pub fn perception_raw(r: &RobotId) -> Topic<KeypointFrame> {
    Topic::new(keys::perception_raw(r), "perception_raw", SENSOR).of(r)
}

/// Perception bridge → forecaster, retargeter, safety. Sensor stream.
pub fn humans(r: &RobotId) -> Topic<HumanSkeletons> {
    Topic::new(keys::humans(r), "humans", SENSOR).of(r)
}

/// Robot interface → everyone. Sensor stream (100 Hz; a deeper queue keeps a burst).
pub fn robot_state(r: &RobotId) -> Topic<JointState> {
    Topic::new(
        keys::robot_state(r),
        "robot_state",
        Delivery::SensorDropOldest { depth: 32 },
    )
    .of(r)
}

/// Operator → forecaster, safety. Command-like: an intent change must not be lost.
pub fn prompt(r: &RobotId) -> Topic<InteractionIntent> {
    Topic::new(keys::prompt(r), "prompt", COMMAND).of(r)
}

/// Forecaster → safety, monitors. Sensor stream: only the newest forecast matters.
pub fn forecast(r: &RobotId) -> Topic<Forecast> {
    Topic::new(keys::forecast(r), "forecast", SENSOR).of(r)
}

/// Retargeter → safety (imitation mode). Sensor stream.
pub fn retarget(r: &RobotId) -> Topic<RobotPlan> {
    Topic::new(keys::retarget(r), "retarget", SENSOR).of(r)
}

/// Safety → robot interface. Command: blocks, never silently dropped.
pub fn command(r: &RobotId) -> Topic<RobotCommand> {
    Topic::new(keys::command(r), "command", COMMAND).of(r)
}

/// Safety → monitors. Status.
pub fn safety_status(r: &RobotId) -> Topic<SafetyStatus> {
    Topic::new(keys::safety_status(r), "safety_status", STATUS).of(r)
}

/// Anyone → safety. Command: blocks, never silently dropped.
pub fn estop(r: &RobotId) -> Topic<EStop> {
    Topic::new(keys::estop(r), "estop", COMMAND).of(r)
}

/// A service → monitors. Status.
pub fn service_status(r: &RobotId, service: &str) -> Topic<ServiceStatus> {
    Topic::new(keys::service_status(r, service), "service_status", STATUS).of(r)
}

/// Every service's status (for monitors).
pub fn service_status_all(r: &RobotId) -> Topic<ServiceStatus> {
    Topic::new(keys::service_status_all(r), "service_status", STATUS).of(r)
}
