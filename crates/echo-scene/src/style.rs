//! Colours: the person blue, the forecast a light ghost, the robot grey with orange arms, the
//! safety state from green (following) to red (e-stopped).

use echo_msgs::SafetyState;
use echo_robot::collision::Part;

use crate::scene::Rgba;

/// The interaction partner.
pub const PARTNER: Rgba = Rgba::rgb8(30, 90, 210);
/// Other people.
pub const PERSON: Rgba = Rgba::rgb8(110, 140, 190);
/// The partner's forecast (drawn with falling opacity).
pub const FORECAST: Rgba = Rgba::rgb8(120, 180, 255);
/// The robot's forecast plan (drawn with falling opacity).
pub const ROBOT_PLAN: Rgba = Rgba::rgb8(255, 180, 110);
/// The head camera's field of view.
pub const CAMERA: Rgba = Rgba::rgb8(150, 70, 170);
/// Overlay text.
pub const TEXT: Rgba = Rgba::rgb8(40, 40, 40);
/// Safety state unknown or stale.
pub const UNKNOWN: Rgba = Rgba::rgb8(120, 120, 120);

/// Robot base.
pub const ROBOT_BASE: Rgba = Rgba::rgb8(85, 85, 90);
/// Robot torso.
pub const ROBOT_TORSO: Rgba = Rgba::rgb8(150, 150, 155);
/// Robot head.
pub const ROBOT_HEAD: Rgba = Rgba::rgb8(185, 185, 190);
/// Left arm.
pub const ROBOT_ARM_LEFT: Rgba = Rgba::rgb8(240, 130, 30);
/// Right arm.
pub const ROBOT_ARM_RIGHT: Rgba = Rgba::rgb8(205, 100, 20);
/// Grippers.
pub const ROBOT_GRIPPER: Rgba = Rgba::rgb8(110, 70, 40);

/// The colour of a robot body part.
pub fn robot_part(p: Part) -> Rgba {
    match p {
        Part::Base => ROBOT_BASE,
        Part::Torso => ROBOT_TORSO,
        Part::Head => ROBOT_HEAD,
        Part::Gripper(_) => ROBOT_GRIPPER,
        Part::Shoulder(left) | Part::UpperArm(left) | Part::Forearm(left) | Part::Wrist(left) => {
            if left {
                ROBOT_ARM_LEFT
            } else {
                ROBOT_ARM_RIGHT
            }
        }
    }
}

/// The colour of a safety state.
pub fn safety(s: SafetyState) -> Rgba {
    match s {
        SafetyState::Following => Rgba::rgb8(40, 160, 70),
        SafetyState::Limiting => Rgba::rgb8(215, 160, 0),
        SafetyState::Stopping => Rgba::rgb8(230, 90, 20),
        SafetyState::Holding => Rgba::rgb8(90, 110, 150),
        SafetyState::EStopped => Rgba::rgb8(210, 20, 20),
    }
}
