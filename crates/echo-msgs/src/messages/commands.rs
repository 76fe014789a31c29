//! Messages on the edge safety → robot interface.

use super::*;

/// One point of a controller trajectory (trajectory_msgs/JointTrajectoryPoint).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrajectoryPoint {
    /// Seconds after the command's stamp.
    pub time_from_start: f64,
    /// Positions.
    pub positions: Vec<f64>,
    /// Velocities (same length as positions).
    pub velocities: Vec<f64>,
    /// Accelerations (same length as positions).
    pub accelerations: Vec<f64>,
}

/// A trajectory for one controller (names all of its joints).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControllerTrajectory {
    /// Controller name, e.g. "arm_left_controller".
    pub controller: String,
    /// The controller's joints.
    pub joint_names: Vec<String>,
    /// Points with strictly increasing `time_from_start`.
    pub points: Vec<TrajectoryPoint>,
}

/// Base velocity (geometry_msgs/Twist restricted to a differential drive).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BaseTwist {
    /// Forward speed, m/s.
    pub linear_x: f64,
    /// Turn rate, rad/s.
    pub angular_z: f64,
}

/// The only message that moves the robot; published by the safety service alone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotCommand {
    /// Header.
    pub header: Header,
    /// One trajectory per controller that moves.
    pub trajectories: Vec<ControllerTrajectory>,
    /// Base velocity, when the base moves (absent = zero).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_twist: Option<BaseTwist>,
}
message!(RobotCommand, "robot_command");

impl Validate for RobotCommand {
    fn validate(&self) -> Result<(), ValidationError> {
        for (c, tr) in self.trajectories.iter().enumerate() {
            let n = tr.joint_names.len();
            if tr.points.is_empty() || tr.points.len() > MAX_PLAN_POINTS {
                return Err(ValidationError::OutOfRange {
                    field: format!("trajectories[{c}].points"),
                    value: tr.points.len() as f64,
                    min: 1.0,
                    max: MAX_PLAN_POINTS as f64,
                });
            }
            let times: Vec<f64> = tr.points.iter().map(|p| p.time_from_start).collect();
            check_increasing(
                &format!("trajectories[{c}].points[].time_from_start"),
                &times,
            )?;
            for (i, p) in tr.points.iter().enumerate() {
                let f = format!("trajectories[{c}].points[{i}]");
                check_len(&format!("{f}.positions"), p.positions.len(), n)?;
                check_len(&format!("{f}.velocities"), p.velocities.len(), n)?;
                check_len(&format!("{f}.accelerations"), p.accelerations.len(), n)?;
                check_finite(&format!("{f}.positions"), &p.positions)?;
                check_finite(&format!("{f}.velocities"), &p.velocities)?;
                check_finite(&format!("{f}.accelerations"), &p.accelerations)?;
            }
        }
        if let Some(t) = &self.base_twist {
            check_finite("base_twist", &[t.linear_x, t.angular_z])?;
        }
        Ok(())
    }
}

/// State of the safety filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SafetyState {
    /// Following a valid plan unchanged.
    Following,
    /// Following, but a limit or separation scaled the motion down.
    Limiting,
    /// Executing a controlled stop.
    Stopping,
    /// Stopped and holding.
    Holding,
    /// Latched emergency stop: needs an explicit reset.
    EStopped,
}

/// Safety filter status, published every cycle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SafetyStatus {
    /// Header.
    pub header: Header,
    /// Current state.
    pub state: SafetyState,
    /// Why the state is what it is (empty when following).
    pub reasons: Vec<String>,
    /// Speed scale applied this cycle, [0, 1].
    pub speed_scale: f64,
    /// Smallest robot–human distance seen this cycle, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_separation_m: Option<f64>,
    /// Rejections and events by reason since start.
    pub counters: BTreeMap<String, u64>,
}
message!(SafetyStatus, "safety_status");

impl Validate for SafetyStatus {
    fn validate(&self) -> Result<(), ValidationError> {
        check_range("speed_scale", self.speed_scale, 0.0, 1.0)?;
        if let Some(d) = self.min_separation_m {
            check_finite("min_separation_m", &[d])?;
        }
        Ok(())
    }
}

/// E-stop action.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EStopAction {
    /// Stop now and latch.
    Engage,
    /// Release a latched stop.
    Reset,
}

/// Emergency stop request (latched until an explicit reset).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EStop {
    /// Header.
    pub header: Header,
    /// Engage or reset.
    pub action: EStopAction,
    /// Who and why.
    pub reason: String,
}
message!(EStop, "estop");

impl Validate for EStop {
    fn validate(&self) -> Result<(), ValidationError> {
        Ok(())
    }
}
