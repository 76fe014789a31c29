//! Plan validation and the reference a plan gives over time.
//!
//! A plan's point times are seconds after its **receipt** on the safety service's monotonic
//! clock — never after the sender's stamp, so clock skew between hosts cannot stretch or
//! shorten a plan.

use std::time::Instant;

use echo_msgs::{BasePose, RobotPlan};

/// Why a plan was rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// A joint the filter does not control.
    #[error("plan names unknown or uncontrolled joint '{0}'")]
    UnknownJoint(String),
    /// The first point is far from where the robot is.
    #[error("plan starts {distance:.3} from the measured position of {joint} (limit {limit:.3})")]
    FarFromState {
        /// Joint.
        joint: String,
        /// Distance.
        distance: f64,
        /// Tolerance.
        limit: f64,
    },
    /// Produced for another control mode than the active one.
    #[error("plan for mode {got:?} while the robot is in {active:?}")]
    WrongMode {
        /// Plan's mode.
        got: echo_msgs::ControlMode,
        /// Active mode.
        active: echo_msgs::ControlMode,
    },
    /// Older than the plan already followed from the same source.
    #[error("plan stamped {stamp_ns} is not newer than the active plan ({last_ns})")]
    OutOfOrder {
        /// This plan's stamp.
        stamp_ns: u64,
        /// The active plan's stamp.
        last_ns: u64,
    },
    /// The robot state is unknown, so the plan cannot be checked.
    #[error("no robot joint state yet: plan cannot be checked")]
    NoState,
    /// A value that validation should have caught (defence in depth).
    #[error("plan has a non-finite value")]
    NonFinite,
}

impl PlanError {
    /// Short label for counters.
    pub fn reason(&self) -> &'static str {
        match self {
            PlanError::UnknownJoint(_) => "unknown_joint",
            PlanError::FarFromState { .. } => "far_from_state",
            PlanError::WrongMode { .. } => "wrong_mode",
            PlanError::OutOfOrder { .. } => "out_of_order",
            PlanError::NoState => "no_state",
            PlanError::NonFinite => "non_finite",
        }
    }
}

/// An accepted plan.
#[derive(Debug, Clone)]
pub struct ActivePlan {
    /// The plan.
    pub plan: RobotPlan,
    /// Filter index of each plan joint.
    pub index: Vec<usize>,
    /// Receipt time (time base of the points).
    pub received: Instant,
}

/// Check `plan` against the filter's joints and the measured positions (by filter index).
pub fn accept(
    plan: &RobotPlan,
    joints: &[String],
    measured: &[Option<f64>],
    tolerance: f64,
    now: Instant,
) -> Result<ActivePlan, PlanError> {
    let mut index = Vec::with_capacity(plan.joint_names.len());
    for n in &plan.joint_names {
        let i = joints
            .iter()
            .position(|j| j == n)
            .ok_or_else(|| PlanError::UnknownJoint(n.chars().take(64).collect()))?;
        index.push(i);
    }
    if plan
        .points
        .iter()
        .any(|p| !p.t.is_finite() || p.positions.iter().any(|x| !x.is_finite()))
    {
        return Err(PlanError::NonFinite);
    }
    let first = &plan.points[0];
    for (k, &i) in index.iter().enumerate() {
        let Some(q) = measured.get(i).copied().flatten() else {
            return Err(PlanError::NoState);
        };
        let d = (first.positions[k] - q).abs();
        if d > tolerance {
            return Err(PlanError::FarFromState {
                joint: joints[i].clone(),
                distance: d,
                limit: tolerance,
            });
        }
    }
    Ok(ActivePlan {
        plan: plan.clone(),
        index,
        received: now,
    })
}

impl ActivePlan {
    /// Seconds since receipt at `now`.
    pub fn age(&self, now: Instant) -> f64 {
        now.saturating_duration_since(self.received).as_secs_f64()
    }

    /// Position and velocity of plan joint `k` at plan time `t` (linear between points, held
    /// before the first and after the last).
    pub fn sample(&self, k: usize, t: f64) -> (f64, f64) {
        let p = &self.plan.points;
        let i = p.partition_point(|x| x.t < t);
        if i == 0 {
            return (p[0].positions[k], 0.0);
        }
        if i >= p.len() {
            return (p[p.len() - 1].positions[k], 0.0);
        }
        let (a, b) = (&p[i - 1], &p[i]);
        let w = (t - a.t) / (b.t - a.t);
        let v = (b.positions[k] - a.positions[k]) / (b.t - a.t);
        (a.positions[k] + w * (b.positions[k] - a.positions[k]), v)
    }

    /// Base pose at plan time `t`, if the plan moves the base.
    pub fn base(&self, t: f64) -> Option<BasePose> {
        let p = &self.plan.points;
        let i = p.partition_point(|x| x.t < t).min(p.len() - 1);
        p[i].base
    }

    /// Whether plan time `t` is past the last point.
    pub fn finished(&self, t: f64) -> bool {
        self.plan.points.last().is_none_or(|p| t > p.t)
    }
}
