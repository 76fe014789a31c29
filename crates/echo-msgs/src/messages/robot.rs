//! Messages on the edge robot interface → everyone.

use super::*;

/// Planar base pose in the odometry frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BasePose {
    /// x, metres.
    pub x: f64,
    /// y, metres.
    pub y: f64,
    /// Heading about z, radians.
    pub yaw: f64,
}

/// Measured joint state of the robot (like sensor_msgs/JointState: map by name, order is not fixed).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    /// Header.
    pub header: Header,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions, radians or metres (prismatic).
    pub position: Vec<f64>,
    /// Velocities; empty or one per name.
    #[serde(default)]
    pub velocity: Vec<f64>,
    /// Base pose from odometry, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<BasePose>,
}
message!(JointState, "joint_state");

impl JointState {
    /// Position of joint `name`, if present.
    pub fn position_of(&self, name: &str) -> Option<f64> {
        self.name
            .iter()
            .position(|n| n == name)
            .map(|i| self.position[i])
    }
}

impl Validate for JointState {
    fn validate(&self) -> Result<(), ValidationError> {
        check_len("position", self.position.len(), self.name.len())?;
        check_finite("position", &self.position)?;
        if !self.velocity.is_empty() {
            check_len("velocity", self.velocity.len(), self.name.len())?;
            check_finite("velocity", &self.velocity)?;
        }
        if let Some(b) = &self.base {
            check_finite("base", &[b.x, b.y, b.yaw])?;
        }
        for (i, n) in self.name.iter().enumerate() {
            if n.is_empty() || self.name[..i].contains(n) {
                return Err(ValidationError::Other(format!(
                    "name[{i}] '{n}' is empty or repeated"
                )));
            }
        }
        Ok(())
    }
}
