//! ROS 2 (Humble) interop through zenoh-bridge-ros2dds conventions.
//!
//! * Messages in ROS field order, encoded as plain CDR (XCDR1, little endian) with the 4-byte
//!   encapsulation header — the raw DDS sample the bridge routes (`cdr` crate).
//! * Key names: a ROS topic `/ns/foo` is the Zenoh key `ns/foo` (no leading slash, no `rt/`).
//! * Conversions from Echo's commands to `trajectory_msgs/JointTrajectory` per controller and
//!   `geometry_msgs/Twist`, and from `sensor_msgs/JointState` to Echo's joint state.
//! * The head camera's `sensor_msgs/Image` and `sensor_msgs/CameraInfo` ([`image`]).

use cdr::{CdrLe, Infinite};
use serde::{Deserialize, Serialize};

mod bounded;
pub mod image;
pub use image::{RosCameraInfo, RosImage};

/// builtin_interfaces/Time and Duration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct Time {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds.
    pub nanosec: u32,
}

impl Time {
    /// From seconds (non-negative, finite).
    pub fn from_secs(s: f64) -> Time {
        let s = if s.is_finite() { s.max(0.0) } else { 0.0 };
        let sec = s.floor();
        Time {
            sec: sec as i32,
            nanosec: ((s - sec) * 1e9).round().min(999_999_999.0) as u32,
        }
    }

    /// Nanoseconds since the epoch (negative seconds clamp to 0).
    pub fn to_ns(self) -> u64 {
        self.sec.max(0) as u64 * 1_000_000_000 + self.nanosec as u64
    }

    /// From nanoseconds since the epoch.
    pub fn from_ns(ns: u64) -> Time {
        Time {
            sec: (ns / 1_000_000_000) as i32,
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }
}

/// std_msgs/Header.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct RosHeader {
    /// Stamp (0 = "start now" for trajectories).
    pub stamp: Time,
    /// Frame.
    #[serde(deserialize_with = "bounded::string")]
    pub frame_id: String,
}

/// sensor_msgs/msg/JointState.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct RosJointState {
    /// Header.
    pub header: RosHeader,
    /// Names.
    #[serde(deserialize_with = "bounded::strings")]
    pub name: Vec<String>,
    /// Positions.
    pub position: Vec<f64>,
    /// Velocities.
    pub velocity: Vec<f64>,
    /// Efforts.
    pub effort: Vec<f64>,
}

/// trajectory_msgs/msg/JointTrajectoryPoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct RosTrajectoryPoint {
    /// Positions.
    pub positions: Vec<f64>,
    /// Velocities.
    pub velocities: Vec<f64>,
    /// Accelerations.
    pub accelerations: Vec<f64>,
    /// Efforts.
    pub effort: Vec<f64>,
    /// Time from the trajectory start.
    pub time_from_start: Time,
}

/// trajectory_msgs/msg/JointTrajectory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct RosJointTrajectory {
    /// Header.
    pub header: RosHeader,
    /// Joints.
    #[serde(deserialize_with = "bounded::strings")]
    pub joint_names: Vec<String>,
    /// Points.
    pub points: Vec<RosTrajectoryPoint>,
}

/// geometry_msgs/msg/Vector3.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// geometry_msgs/msg/Twist.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct Twist {
    /// Linear velocity.
    pub linear: Vector3,
    /// Angular velocity.
    pub angular: Vector3,
}

/// CDR errors.
#[derive(Debug, thiserror::Error)]
pub enum CdrError {
    /// Encoding failed.
    #[error("CDR encode: {0}")]
    Encode(String),
    /// Decoding failed (truncated, wrong type, bad header …).
    #[error("CDR decode: {0}")]
    Decode(String),
}

/// Encode as little-endian CDR with the encapsulation header.
pub fn encode<T: Serialize>(msg: &T) -> Result<Vec<u8>, CdrError> {
    cdr::serialize::<_, _, CdrLe>(msg, Infinite).map_err(|e| CdrError::Encode(e.to_string()))
}

/// Decode CDR (either endianness, per the encapsulation header; trailing padding tolerated).
/// Length fields are never trusted: strings and byte sequences are read through
/// `bounded`, so a forged length is an error after at most the sample's own size.
pub fn decode<T: for<'de> Deserialize<'de>>(bytes: &[u8]) -> Result<T, CdrError> {
    if bytes.len() > 16 << 20 {
        return Err(CdrError::Decode("sample over 16 MiB".into()));
    }
    cdr::deserialize::<T>(bytes).map_err(|e| CdrError::Decode(e.to_string()))
}

/// Zenoh key of a ROS topic under zenoh-bridge-ros2dds with `namespace` ("" or "/ns").
pub fn ros_key(namespace: &str, topic: &str) -> String {
    let ns = namespace.trim_matches('/');
    let t = topic.trim_start_matches('/');
    if ns.is_empty() {
        t.to_string()
    } else {
        format!("{ns}/{t}")
    }
}

/// The trajectory topic of a controller (`/<controller>/joint_trajectory`).
pub fn trajectory_topic(controller: &str) -> String {
    format!("/{controller}/joint_trajectory")
}

/// The base velocity input of the TIAGo++ twist_mux used for autonomous motion.
pub const BASE_TWIST_TOPIC: &str = "/nav_vel";

/// The joint-state topic.
pub const JOINT_STATES_TOPIC: &str = "/joint_states";

/// One JointTrajectory per controller of an Echo command (stamp 0: start now).
pub fn trajectories(cmd: &echo_msgs::RobotCommand) -> Vec<(String, RosJointTrajectory)> {
    cmd.trajectories
        .iter()
        .map(|t| {
            (
                t.controller.clone(),
                RosJointTrajectory {
                    header: RosHeader::default(),
                    joint_names: t.joint_names.clone(),
                    points: t
                        .points
                        .iter()
                        .map(|p| RosTrajectoryPoint {
                            positions: p.positions.clone(),
                            velocities: p.velocities.clone(),
                            accelerations: p.accelerations.clone(),
                            effort: vec![],
                            time_from_start: Time::from_secs(p.time_from_start),
                        })
                        .collect(),
                },
            )
        })
        .collect()
}

/// The base twist of an Echo command (zero when absent).
pub fn twist(cmd: &echo_msgs::RobotCommand) -> Twist {
    let t = cmd.base_twist.unwrap_or(echo_msgs::BaseTwist {
        linear_x: 0.0,
        angular_z: 0.0,
    });
    Twist {
        linear: Vector3 {
            x: t.linear_x,
            ..Default::default()
        },
        angular: Vector3 {
            z: t.angular_z,
            ..Default::default()
        },
    }
}

/// A ROS joint state as Echo's (validated like any other input).
pub fn joint_state(
    js: &RosJointState,
    robot_id: &str,
    source: &str,
) -> Result<echo_msgs::JointState, echo_msgs::ValidationError> {
    let mut header = echo_msgs::Header::new(robot_id, source, &js.header.frame_id);
    header.stamp_ns = js.header.stamp.to_ns();
    let msg = echo_msgs::JointState {
        header,
        name: js.name.clone(),
        position: js.position.clone(),
        velocity: if js.velocity.len() == js.name.len() {
            js.velocity.clone()
        } else {
            vec![]
        },
        base: None,
    };
    use echo_msgs::Validate;
    msg.validate()?;
    Ok(msg)
}
