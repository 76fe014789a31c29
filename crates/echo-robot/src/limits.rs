//! Per-joint kinematic limits: position (soft by default) and velocity from the URDF;
//! acceleration and jerk chosen here (no TIAGo++ description publishes them).
//!
//! Defaults and why:
//!
//! | joints | acceleration | jerk | reasoning |
//! |---|---|---|---|
//! | arm 1–2 (shoulder) | 1.5 rad/s² | 7.5 rad/s³ | heaviest links (43 N·m drives): full URDF speed 1.95 rad/s in 1.3 s |
//! | arm 3–4 (upper arm, elbow) | 2.0 rad/s² | 10 rad/s³ | 26 N·m drives, less inertia |
//! | arm 5–7 (wrist) | 3.0 rad/s² | 15 rad/s³ | light wrist (3–6.6 N·m) |
//! | head 1–2 | 3.0 rad/s² | 15 rad/s³ | light pan-tilt; gaze shifts of 0.5 rad in ≈ 0.8 s |
//! | torso lift | 0.1 m/s² | 0.5 m/s³ | slow column (0.07 m/s): full speed in 0.7 s |
//! | gripper fingers | 0.5 m/s² | 5 m/s³ | 0.05 m/s fingers |
//!
//! Jerk is 5 × acceleration everywhere: acceleration ramps in 0.2 s, the smooth profile of
//! human reaching (minimum-jerk-like), and a jerk-limited stop from 1 rad/s on a shoulder joint
//! takes v/A + A/J = 0.87 s.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::RobotModel;

/// Limits of one joint.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct JointKinematicLimits {
    /// Lowest position allowed.
    pub lower: f64,
    /// Highest position allowed.
    pub upper: f64,
    /// Speed limit.
    pub velocity: f64,
    /// Acceleration limit.
    pub acceleration: f64,
    /// Jerk limit.
    pub jerk: f64,
}

/// Overrides for one joint (any field may be omitted).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LimitOverride {
    /// Lower position.
    pub lower: Option<f64>,
    /// Upper position.
    pub upper: Option<f64>,
    /// Velocity.
    pub velocity: Option<f64>,
    /// Acceleration.
    pub acceleration: Option<f64>,
    /// Jerk.
    pub jerk: Option<f64>,
}

/// Default (acceleration, jerk) for a joint name.
pub fn default_acc_jerk(joint: &str) -> (f64, f64) {
    if joint.starts_with("arm_") {
        match joint.chars().nth(joint.len() - 7) {
            Some('1') | Some('2') => (1.5, 7.5),
            Some('3') | Some('4') => (2.0, 10.0),
            _ => (3.0, 15.0),
        }
    } else if joint.starts_with("head_") {
        (3.0, 15.0)
    } else if joint == "torso_lift_joint" {
        (0.1, 0.5)
    } else {
        (0.5, 5.0)
    }
}

/// Errors building limits.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LimitsError {
    /// A joint the model does not have (or that does not move).
    #[error("limits for unknown joint '{0}'")]
    UnknownJoint(String),
    /// A limit that is not a positive number, or an empty position range.
    #[error("joint '{joint}': {what}")]
    Invalid {
        /// Joint.
        joint: String,
        /// What is wrong.
        what: String,
    },
}

/// Limits of `joints` from `model` (soft position limits when `soft`), defaults above, and
/// `overrides` on top.
pub fn kinematic_limits(
    model: &RobotModel,
    joints: &[String],
    soft: bool,
    overrides: &BTreeMap<String, LimitOverride>,
) -> Result<Vec<JointKinematicLimits>, LimitsError> {
    if let Some(k) = overrides.keys().find(|k| !joints.contains(k)) {
        return Err(LimitsError::UnknownJoint(k.clone()));
    }
    joints
        .iter()
        .map(|j| {
            let l = model
                .limits(j)
                .ok_or_else(|| LimitsError::UnknownJoint(j.clone()))?;
            let (a, jk) = default_acc_jerk(j);
            let o = overrides.get(j).copied().unwrap_or_default();
            let lim = JointKinematicLimits {
                lower: o.lower.unwrap_or(if soft { l.soft_lower } else { l.lower }),
                upper: o.upper.unwrap_or(if soft { l.soft_upper } else { l.upper }),
                velocity: o.velocity.unwrap_or(l.velocity),
                acceleration: o.acceleration.unwrap_or(a),
                jerk: o.jerk.unwrap_or(jk),
            };
            let bad = |what: &str| LimitsError::Invalid {
                joint: j.clone(),
                what: what.into(),
            };
            for (name, v) in [
                ("velocity", lim.velocity),
                ("acceleration", lim.acceleration),
                ("jerk", lim.jerk),
            ] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(bad(&format!("{name} limit must be positive, not {v}")));
                }
            }
            let empty = lim.lower.partial_cmp(&lim.upper) != Some(std::cmp::Ordering::Less);
            if empty || lim.lower < l.lower - 1e-9 || lim.upper > l.upper + 1e-9 {
                return Err(bad(
                    "position range must be non-empty and inside the URDF's hard limits",
                ));
            }
            Ok(lim)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_by_joint_kind() {
        assert_eq!(default_acc_jerk("arm_left_1_joint"), (1.5, 7.5));
        assert_eq!(default_acc_jerk("arm_right_4_joint"), (2.0, 10.0));
        assert_eq!(default_acc_jerk("arm_right_7_joint"), (3.0, 15.0));
        assert_eq!(default_acc_jerk("torso_lift_joint"), (0.1, 0.5));
    }

    #[test]
    fn overrides_apply_and_bad_ones_are_named() {
        let m = RobotModel::tiago_dual();
        let joints = vec!["head_1_joint".to_string()];
        let mut o = BTreeMap::new();
        o.insert(
            "head_1_joint".into(),
            LimitOverride {
                velocity: Some(1.0),
                ..Default::default()
            },
        );
        let l = kinematic_limits(&m, &joints, true, &o).unwrap();
        assert_eq!(l[0].velocity, 1.0);
        assert!((l[0].upper - (1.3089969389957472 - 0.07)).abs() < 1e-12);
        o.insert("elbow".into(), LimitOverride::default());
        assert_eq!(
            kinematic_limits(&m, &joints, true, &o),
            Err(LimitsError::UnknownJoint("elbow".into()))
        );
        let mut o = BTreeMap::new();
        o.insert(
            "head_1_joint".into(),
            LimitOverride {
                upper: Some(3.0),
                ..Default::default()
            },
        );
        assert!(
            kinematic_limits(&m, &joints, true, &o).is_err(),
            "beyond the hard limit"
        );
    }
}
