//! Kinematic tree and forward kinematics.

use std::collections::HashMap;

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};

/// Errors loading a model or evaluating it.
#[derive(Debug, thiserror::Error)]
pub enum RobotError {
    /// The URDF text could not be parsed.
    #[error("URDF parse error: {0}")]
    Parse(String),
    /// The URDF parsed but is not a single tree.
    #[error("URDF structure: {0}")]
    Structure(String),
    /// A frame name that the model does not have.
    #[error("unknown frame '{0}'")]
    UnknownFrame(String),
    /// A joint name that the model does not have.
    #[error("unknown joint '{0}'")]
    UnknownJoint(String),
    /// Reading a file failed.
    #[error("reading {path}: {source}")]
    Io {
        /// File path.
        path: String,
        /// The error.
        source: std::io::Error,
    },
}

/// Joint type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about the axis, limited.
    Revolute,
    /// Rotation about the axis, unlimited.
    Continuous,
    /// Translation along the axis.
    Prismatic,
    /// No motion.
    Fixed,
}

/// Position and velocity limits of one joint (URDF), plus soft limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimits {
    /// Hard lower position limit.
    pub lower: f64,
    /// Hard upper position limit.
    pub upper: f64,
    /// Velocity limit (rad/s or m/s).
    pub velocity: f64,
    /// Soft lower limit (`safety_controller`), or the hard one when absent.
    pub soft_lower: f64,
    /// Soft upper limit.
    pub soft_upper: f64,
}

/// One joint of the tree.
#[derive(Debug, Clone)]
pub struct JointSpec {
    /// Joint name.
    pub name: String,
    /// Type.
    pub kind: JointKind,
    /// Index of the parent link.
    pub parent: usize,
    /// Index of the child link.
    pub child: usize,
    /// Fixed transform parent → joint frame.
    pub origin: Isometry3<f64>,
    /// Unit axis in the joint frame.
    pub axis: Unit<Vector3<f64>>,
    /// Limits for moving joints with limits.
    pub limits: Option<JointLimits>,
}

/// A kinematic tree rooted at one link.
#[derive(Debug, Clone)]
pub struct RobotModel {
    name: String,
    links: Vec<String>,
    link_index: HashMap<String, usize>,
    /// Joints in topological order (every parent link is reached before its children).
    joints: Vec<JointSpec>,
    /// For each link, the joint that creates it (None for the root).
    link_joint: Vec<Option<usize>>,
    /// Moving (non-fixed) joint names, in topological order.
    actuated: Vec<String>,
    actuated_index: HashMap<String, usize>,
}

/// Joint values by actuated-joint index (see [`RobotModel::actuated_joints`]); missing joints are 0.
#[derive(Debug, Clone, PartialEq)]
pub struct JointValues(pub Vec<f64>);

impl RobotModel {
    /// Echo's embedded TIAGo++ description.
    pub fn tiago_dual() -> RobotModel {
        // The embedded file is part of the build and covered by tests.
        Self::from_urdf_str(crate::TIAGO_DUAL_URDF).expect("embedded TIAGo++ URDF is valid")
    }

    /// Load from a URDF file.
    pub fn from_urdf_file(path: &std::path::Path) -> Result<RobotModel, RobotError> {
        let text = std::fs::read_to_string(path).map_err(|source| RobotError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_urdf_str(&text)
    }

    /// Load from URDF text.
    pub fn from_urdf_str(text: &str) -> Result<RobotModel, RobotError> {
        let urdf = urdf_rs::read_from_string(text).map_err(|e| RobotError::Parse(e.to_string()))?;
        let links: Vec<String> = urdf.links.iter().map(|l| l.name.clone()).collect();
        let link_index: HashMap<String, usize> = links
            .iter()
            .enumerate()
            .map(|(i, n)| (n.clone(), i))
            .collect();
        let idx = |n: &str| {
            link_index
                .get(n)
                .copied()
                .ok_or_else(|| RobotError::Structure(format!("joint refers to unknown link '{n}'")))
        };
        let mut raw = Vec::with_capacity(urdf.joints.len());
        for j in &urdf.joints {
            let kind = match j.joint_type {
                urdf_rs::JointType::Revolute => JointKind::Revolute,
                urdf_rs::JointType::Continuous => JointKind::Continuous,
                urdf_rs::JointType::Prismatic => JointKind::Prismatic,
                urdf_rs::JointType::Fixed => JointKind::Fixed,
                ref other => {
                    return Err(RobotError::Structure(format!(
                        "joint '{}' has unsupported type {other:?}",
                        j.name
                    )))
                }
            };
            let [x, y, z] = j.origin.xyz.0;
            let [r, p, yaw] = j.origin.rpy.0;
            // URDF rpy is fixed-axis X-Y-Z: R = Rz(yaw) Ry(pitch) Rx(roll).
            let origin = Isometry3::from_parts(
                Translation3::new(x, y, z),
                UnitQuaternion::from_euler_angles(r, p, yaw),
            );
            let a = Vector3::from(j.axis.xyz.0);
            let axis = Unit::try_new(a, 1e-12).unwrap_or(Vector3::z_axis());
            let limits = match kind {
                JointKind::Revolute | JointKind::Prismatic => {
                    let (soft_lower, soft_upper) = match &j.safety_controller {
                        Some(s) => (s.soft_lower_limit, s.soft_upper_limit),
                        None => (j.limit.lower, j.limit.upper),
                    };
                    Some(JointLimits {
                        lower: j.limit.lower,
                        upper: j.limit.upper,
                        velocity: j.limit.velocity,
                        soft_lower: soft_lower.max(j.limit.lower),
                        soft_upper: soft_upper.min(j.limit.upper),
                    })
                }
                JointKind::Continuous => Some(JointLimits {
                    lower: f64::NEG_INFINITY,
                    upper: f64::INFINITY,
                    velocity: j.limit.velocity,
                    soft_lower: f64::NEG_INFINITY,
                    soft_upper: f64::INFINITY,
                }),
                JointKind::Fixed => None,
            };
            raw.push(JointSpec {
                name: j.name.clone(),
                kind,
                parent: idx(&j.parent.link)?,
                child: idx(&j.child.link)?,
                origin,
                axis,
                limits,
            });
        }
        // Topological order from the root.
        let mut link_joint: Vec<Option<usize>> = vec![None; links.len()];
        for (k, j) in raw.iter().enumerate() {
            if link_joint[j.child].is_some() {
                return Err(RobotError::Structure(format!(
                    "link '{}' has two parent joints",
                    links[j.child]
                )));
            }
            link_joint[j.child] = Some(k);
        }
        let roots: Vec<usize> = (0..links.len())
            .filter(|l| link_joint[*l].is_none())
            .collect();
        if roots.len() != 1 {
            return Err(RobotError::Structure(format!(
                "expected one root link, found {}",
                roots.len()
            )));
        }
        let mut order = Vec::with_capacity(raw.len());
        let mut stack = vec![roots[0]];
        while let Some(l) = stack.pop() {
            for (k, j) in raw.iter().enumerate() {
                if j.parent == l {
                    order.push(k);
                    stack.push(j.child);
                }
            }
        }
        if order.len() != raw.len() {
            return Err(RobotError::Structure(
                "the joints do not form a tree".into(),
            ));
        }
        let joints: Vec<JointSpec> = order.iter().map(|k| raw[*k].clone()).collect();
        let mut link_joint = vec![None; links.len()];
        for (k, j) in joints.iter().enumerate() {
            link_joint[j.child] = Some(k);
        }
        let actuated: Vec<String> = joints
            .iter()
            .filter(|j| j.kind != JointKind::Fixed)
            .map(|j| j.name.clone())
            .collect();
        let actuated_index = actuated
            .iter()
            .enumerate()
            .map(|(i, n)| (n.clone(), i))
            .collect();
        Ok(RobotModel {
            name: urdf.name,
            links,
            link_index,
            joints,
            link_joint,
            actuated,
            actuated_index,
        })
    }

    /// Robot name from the URDF.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Root link name.
    pub fn root(&self) -> &str {
        let root = (0..self.links.len())
            .find(|l| self.link_joint[*l].is_none())
            .unwrap_or(0);
        &self.links[root]
    }

    /// Moving joints in topological order; [`JointValues`] index into this list.
    pub fn actuated_joints(&self) -> &[String] {
        &self.actuated
    }

    /// Index of an actuated joint.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.actuated_index.get(name).copied()
    }

    /// A joint by name.
    pub fn joint(&self, name: &str) -> Option<&JointSpec> {
        self.joints.iter().find(|j| j.name == name)
    }

    /// Limits of an actuated joint.
    pub fn limits(&self, name: &str) -> Option<JointLimits> {
        self.joint(name).and_then(|j| j.limits)
    }

    /// Whether the model has a frame (link) called `name`.
    pub fn has_frame(&self, name: &str) -> bool {
        self.link_index.contains_key(name)
    }

    /// All-zero joint values.
    pub fn zero(&self) -> JointValues {
        JointValues(vec![0.0; self.actuated.len()])
    }

    /// Joint values from (name, value) pairs; unnamed joints stay 0, unknown names are an error.
    pub fn values_from<'a>(
        &self,
        pairs: impl IntoIterator<Item = (&'a str, f64)>,
    ) -> Result<JointValues, RobotError> {
        let mut q = self.zero();
        for (n, v) in pairs {
            let i = self
                .joint_index(n)
                .ok_or_else(|| RobotError::UnknownJoint(n.to_string()))?;
            q.0[i] = v;
        }
        Ok(q)
    }

    /// Joint values from (name, value) pairs of a measured state that may name joints this
    /// model does not have (grippers' fingers, wheels, another robot's extras): those are
    /// skipped; unnamed joints stay 0.
    pub fn known_values<'a>(&self, pairs: impl IntoIterator<Item = (&'a str, f64)>) -> JointValues {
        let mut q = self.zero();
        for (n, v) in pairs {
            if let Some(i) = self.joint_index(n) {
                q.0[i] = v;
            }
        }
        q
    }

    fn joint_transform(&self, j: &JointSpec, q: &JointValues) -> Isometry3<f64> {
        let v = self
            .actuated_index
            .get(&j.name)
            .and_then(|i| q.0.get(*i))
            .copied()
            .unwrap_or(0.0);
        match j.kind {
            JointKind::Fixed => j.origin,
            JointKind::Revolute | JointKind::Continuous => {
                j.origin * UnitQuaternion::from_axis_angle(&j.axis, v)
            }
            JointKind::Prismatic => j.origin * Translation3::from(j.axis.into_inner() * v),
        }
    }

    /// Pose of `frame` in the root frame for joint values `q`.
    pub fn fk(&self, q: &JointValues, frame: &str) -> Result<Isometry3<f64>, RobotError> {
        let mut link = *self
            .link_index
            .get(frame)
            .ok_or_else(|| RobotError::UnknownFrame(frame.to_string()))?;
        let mut pose = Isometry3::identity();
        while let Some(k) = self.link_joint[link] {
            let j = &self.joints[k];
            pose = self.joint_transform(j, q) * pose;
            link = j.parent;
        }
        Ok(pose)
    }

    /// The joints from the root to `frame`, root first (fixed joints included).
    pub fn chain(&self, frame: &str) -> Result<Vec<&JointSpec>, RobotError> {
        let mut link = *self
            .link_index
            .get(frame)
            .ok_or_else(|| RobotError::UnknownFrame(frame.to_string()))?;
        let mut out = vec![];
        while let Some(k) = self.link_joint[link] {
            out.push(&self.joints[k]);
            link = self.joints[k].parent;
        }
        out.reverse();
        Ok(out)
    }

    /// Poses of every link in the root frame (indexed like [`Self::link_names`]).
    pub fn fk_all(&self, q: &JointValues) -> Vec<Isometry3<f64>> {
        let mut poses = vec![Isometry3::identity(); self.links.len()];
        for j in &self.joints {
            poses[j.child] = poses[j.parent] * self.joint_transform(j, q);
        }
        poses
    }

    /// Link names.
    pub fn link_names(&self) -> &[String] {
        &self.links
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_model_has_the_chains() {
        let m = RobotModel::tiago_dual();
        assert_eq!(m.root(), "base_footprint");
        for f in [
            "torso_lift_link",
            "head_front_camera_optical_frame",
            "arm_left_tool_link",
            "gripper_right_grasping_frame",
        ] {
            assert!(m.has_frame(f), "{f}");
        }
        // 1 torso + 2 head + 14 arm + 4 finger joints.
        assert_eq!(m.actuated_joints().len(), 21);
        let l = m.limits("arm_left_3_joint").unwrap();
        assert!((l.soft_upper - (l.upper - 0.07)).abs() < 1e-9);
    }

    #[test]
    fn bad_urdf_is_an_error_not_a_panic() {
        assert!(RobotModel::from_urdf_str("<robot").is_err());
        let two_roots = r#"<robot name="x"><link name="a"/><link name="b"/></robot>"#;
        assert!(matches!(
            RobotModel::from_urdf_str(two_roots),
            Err(RobotError::Structure(_))
        ));
        let m = RobotModel::tiago_dual();
        assert!(m.fk(&m.zero(), "nope").is_err());
        assert!(m.values_from([("nope", 1.0)]).is_err());
    }

    #[test]
    fn known_values_skip_joints_the_model_lacks() {
        let m = RobotModel::tiago_dual();
        let q = m.known_values([("nope", 1.0), ("torso_lift_joint", 0.2)]);
        let torso = m.joint_index("torso_lift_joint").unwrap();
        assert_eq!(q.0[torso], 0.2);
        assert_eq!(q.0.iter().filter(|v| **v != 0.0).count(), 1);
    }
}
