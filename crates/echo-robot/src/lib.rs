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

/// PAL's play_motion "home" arm pose (joints 1–7, both arms), as published (1.5708, not π/2).
#[allow(clippy::approx_constant)]
pub const HOME_ARM: [f64; 7] = [-1.1, 1.4679, 2.714, 1.7095, -1.5708, 1.3898, 0.0];

/// Torso height of the home pose, metres.
pub const HOME_TORSO: f64 = 0.15;

/// The links at the base of each arm (left, right): the robot's shoulders.
pub const SHOULDER_LINKS: [&str; 2] = ["arm_left_1_link", "arm_right_1_link"];

/// The grippers' grasping frames (left, right): where a hand is held.
pub const GRASPING_FRAMES: [&str; 2] = [
    "gripper_left_grasping_frame",
    "gripper_right_grasping_frame",
];

/// The 14 arm joints in the order every model uses: left 1–7, then right 1–7.
pub fn arm_joints() -> Vec<String> {
    ["left", "right"]
        .iter()
        .flat_map(|s| (1..=7).map(move |i| format!("arm_{s}_{i}_joint")))
        .collect()
}

/// The joints a forecaster's robot agent reads and writes, in feature order: the 14 arm
/// joints ([`arm_joints`]), torso, head pan, head tilt.
pub fn robot_agent_joints() -> Vec<String> {
    let mut v = arm_joints();
    v.extend(["torso_lift_joint", "head_1_joint", "head_2_joint"].map(String::from));
    v
}

/// (joint, value) pairs of the home pose: both arms at [`HOME_ARM`], torso at [`HOME_TORSO`].
pub fn home_pose() -> Vec<(String, f64)> {
    let mut v = vec![("torso_lift_joint".to_string(), HOME_TORSO)];
    for side in ["left", "right"] {
        for (i, q) in HOME_ARM.iter().enumerate() {
            v.push((format!("arm_{side}_{}_joint", i + 1), *q));
        }
    }
    v
}

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
