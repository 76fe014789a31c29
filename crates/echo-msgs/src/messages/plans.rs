//! Messages on the edge forecaster / retargeter → safety.

use super::*;

/// One point of a robot plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanPoint {
    /// Seconds after `header.stamp_ns`.
    pub t: f64,
    /// Positions, one per `joint_names` entry.
    pub positions: Vec<f64>,
    /// Base pose in the odometry frame, if the plan moves the base.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<BasePose>,
}

/// A robot trajectory proposal. Not a command: only the safety service turns it into one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotPlan {
    /// Header (`frame_id` = frame of base poses, normally "odom").
    pub header: Header,
    /// Which mode produced it.
    pub mode: ControlMode,
    /// Joint names the plan controls.
    pub joint_names: Vec<String>,
    /// Points with strictly increasing `t`.
    pub points: Vec<PlanPoint>,
}
message!(RobotPlan, "robot_plan");

/// Most points a plan may carry.
pub const MAX_PLAN_POINTS: usize = 256;

impl Validate for RobotPlan {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.points.is_empty() || self.points.len() > MAX_PLAN_POINTS {
            return Err(ValidationError::OutOfRange {
                field: "points".into(),
                value: self.points.len() as f64,
                min: 1.0,
                max: MAX_PLAN_POINTS as f64,
            });
        }
        let times: Vec<f64> = self.points.iter().map(|p| p.t).collect();
        check_increasing("points[].t", &times)?;
        for (i, p) in self.points.iter().enumerate() {
            check_len(
                &format!("points[{i}].positions"),
                p.positions.len(),
                self.joint_names.len(),
            )?;
            check_finite(&format!("points[{i}].positions"), &p.positions)?;
            if let Some(b) = &p.base {
                check_finite(&format!("points[{i}].base"), &[b.x, b.y, b.yaw])?;
            }
        }
        Ok(())
    }
}

/// A forecast of the interaction: future partner motion and (in HRI mode) the robot's plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Forecast {
    /// Header (`stamp_ns` = time of the last observed frame; frame `base_footprint`).
    pub header: Header,
    /// Model identifier (checkpoint name).
    pub model: String,
    /// Frame rate of the forecast, Hz.
    pub rate_hz: f64,
    /// Partner track the forecast is about.
    pub partner_id: u32,
    /// Future partner joints, one 22-joint frame per step (step k is at (k+1)/rate_hz s).
    pub human: Vec<Vec<[f64; 3]>>,
    /// The robot's plan, when the model forecasts the robot too.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<RobotPlan>,
    /// Model inference time for this forecast, ms.
    pub inference_ms: f64,
}
message!(Forecast, "forecast");

impl Validate for Forecast {
    fn validate(&self) -> Result<(), ValidationError> {
        check_range("rate_hz", self.rate_hz, 0.1, 1000.0)?;
        check_range("inference_ms", self.inference_ms, 0.0, 1e6)?;
        if self.human.len() > MAX_PLAN_POINTS {
            return Err(ValidationError::OutOfRange {
                field: "human".into(),
                value: self.human.len() as f64,
                min: 0.0,
                max: MAX_PLAN_POINTS as f64,
            });
        }
        for (k, f) in self.human.iter().enumerate() {
            check_len(&format!("human[{k}]"), f.len(), NUM_JOINTS)?;
            check_finite3(&format!("human[{k}]"), f)?;
        }
        if let Some(r) = &self.robot {
            r.header.validate()?;
            r.validate()?;
        }
        Ok(())
    }
}
