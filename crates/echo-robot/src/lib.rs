//! The TIAGo++ robot model: a kinematic tree loaded from URDF (urdf-rs), joint groups, joint
//! limits (position and velocity from the URDF, acceleration and jerk chosen in [`limits`]),
//! forward kinematics with nalgebra (f64), and a capsule model for collision distances.
//!
//! The embedded description is `robots/tiago_dual/tiago_dual.urdf`; any other URDF (e.g. a robot's
//! own calibrated `/robot_description`) loads the same way with [`RobotModel::from_urdf_str`].

pub mod collision;
pub mod groups;
pub mod limits;
mod model;

pub use model::{JointKind, JointLimits, JointSpec, JointValues, RobotError, RobotModel};

/// The project's TIAGo++ description, embedded at build time.
pub const TIAGO_DUAL_URDF: &str = include_str!("../../../robots/tiago_dual/tiago_dual.urdf");

/// Frame names used across Echo.
pub mod frames {
    /// Robot root on the floor.
    pub const BASE_FOOTPRINT: &str = "base_footprint";
    /// Head camera optical frame.
    pub const HEAD_CAMERA_OPTICAL: &str = "head_front_camera_optical_frame";
    /// Left arm tool flange.
    pub const ARM_LEFT_TOOL: &str = "arm_left_tool_link";
    /// Right arm tool flange.
    pub const ARM_RIGHT_TOOL: &str = "arm_right_tool_link";
    /// Left gripper grasping frame.
    pub const GRIPPER_LEFT_GRASP: &str = "gripper_left_grasping_frame";
    /// Right gripper grasping frame.
    pub const GRIPPER_RIGHT_GRASP: &str = "gripper_right_grasping_frame";
}
