//! Capsules and spheres for self-collision and human-proximity distances.
//!
//! A capsule is a segment with a radius (a sphere is a capsule of zero length). The TIAGo++
//! model attaches capsules between link frames:
//!
//! | part | from | to | radius |
//! |---|---|---|---|
//! | base | base_footprint (0, 0, 0.15) | base_footprint (0, 0, 0.25) | 0.28 m |
//! | torso column | torso_fixed_link (−0.02, 0, 0.1) | torso_lift_link (−0.05, 0, −0.25) | 0.14 m |
//! | torso shoulders | torso_lift_link (−0.04, 0.1, −0.12) | torso_lift_link (−0.04, −0.1, −0.12) | 0.13 m |
//! | head | head_2_link (0.03, 0.06, 0) (sphere) | — | 0.14 m |
//! | shoulder (×2) | arm_*_1_link | arm_*_3_link | 0.07 m |
//! | upper arm (×2) | arm_*_3_link | arm_*_4_link | 0.06 m |
//! | forearm (×2) | arm_*_4_link | arm_*_6_link | 0.055 m |
//! | wrist (×2) | arm_*_6_link | arm_*_tool_link | 0.05 m |
//! | gripper (×2) | gripper_*_link | gripper_*_grasping_frame | 0.05 m |
//!
//! Points are in the link's own frame. The radii cover the real links with a few centimetres to
//! spare; the safety margins come on top.

use nalgebra::{Isometry3, Point3, Vector3};

use crate::{JointValues, RobotModel};

/// Which body part a capsule belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Part {
    /// Mobile base.
    Base,
    /// Torso (column and shoulders).
    Torso,
    /// Head.
    Head,
    /// Shoulder of an arm (left = true).
    Shoulder(bool),
    /// Upper arm.
    UpperArm(bool),
    /// Forearm.
    Forearm(bool),
    /// Wrist.
    Wrist(bool),
    /// Gripper (end effector).
    Gripper(bool),
}

impl Part {
    /// The arm side, for arm parts.
    pub fn side(self) -> Option<bool> {
        match self {
            Part::Shoulder(s)
            | Part::UpperArm(s)
            | Part::Forearm(s)
            | Part::Wrist(s)
            | Part::Gripper(s) => Some(s),
            _ => None,
        }
    }
}

pub use echo_geometry::{segment_distance, Capsule};

/// A capsule attached to the robot's links.
#[derive(Debug, Clone)]
pub struct LinkCapsule {
    /// Body part.
    pub part: Part,
    /// (link index, point in the link frame) of each end.
    pub ends: [(usize, Vector3<f64>); 2],
    /// Radius.
    pub radius: f64,
}

/// The robot's capsule model.
#[derive(Debug, Clone)]
pub struct RobotBody {
    capsules: Vec<LinkCapsule>,
}

impl RobotBody {
    /// The TIAGo++ capsule model (see the module table). Errors if `model` lacks a link.
    pub fn tiago(model: &RobotModel) -> Result<RobotBody, crate::RobotError> {
        let link = |n: &str| {
            model
                .link_names()
                .iter()
                .position(|l| l == n)
                .ok_or_else(|| crate::RobotError::UnknownFrame(n.to_string()))
        };
        let v = Vector3::new;
        let z = Vector3::zeros();
        let mut capsules = vec![
            LinkCapsule {
                part: Part::Base,
                ends: [
                    (link("base_footprint")?, v(0.0, 0.0, 0.15)),
                    (link("base_footprint")?, v(0.0, 0.0, 0.25)),
                ],
                radius: 0.28,
            },
            LinkCapsule {
                part: Part::Torso,
                ends: [
                    (link("torso_fixed_link")?, v(-0.02, 0.0, 0.1)),
                    (link("torso_lift_link")?, v(-0.05, 0.0, -0.25)),
                ],
                radius: 0.14,
            },
            LinkCapsule {
                part: Part::Torso,
                ends: [
                    (link("torso_lift_link")?, v(-0.04, 0.1, -0.12)),
                    (link("torso_lift_link")?, v(-0.04, -0.1, -0.12)),
                ],
                radius: 0.13,
            },
            LinkCapsule {
                part: Part::Head,
                ends: [
                    (link("head_2_link")?, v(0.03, 0.06, 0.0)),
                    (link("head_2_link")?, v(0.03, 0.06, 0.0)),
                ],
                radius: 0.14,
            },
        ];
        for (side, left) in [("left", true), ("right", false)] {
            let l = |s: &str| link(&s.replace('*', side));
            capsules.push(LinkCapsule {
                part: Part::Shoulder(left),
                ends: [(l("arm_*_1_link")?, z), (l("arm_*_3_link")?, z)],
                radius: 0.07,
            });
            capsules.push(LinkCapsule {
                part: Part::UpperArm(left),
                ends: [(l("arm_*_3_link")?, z), (l("arm_*_4_link")?, z)],
                radius: 0.06,
            });
            capsules.push(LinkCapsule {
                part: Part::Forearm(left),
                ends: [(l("arm_*_4_link")?, z), (l("arm_*_6_link")?, z)],
                radius: 0.055,
            });
            capsules.push(LinkCapsule {
                part: Part::Wrist(left),
                ends: [(l("arm_*_6_link")?, z), (l("arm_*_tool_link")?, z)],
                radius: 0.05,
            });
            capsules.push(LinkCapsule {
                part: Part::Gripper(left),
                ends: [
                    (l("gripper_*_link")?, z),
                    (l("gripper_*_grasping_frame")?, z),
                ],
                radius: 0.05,
            });
        }
        Ok(RobotBody { capsules })
    }

    /// The capsule definitions.
    pub fn capsules(&self) -> &[LinkCapsule] {
        &self.capsules
    }

    /// Capsules in the root frame for joint values `q`.
    pub fn at(&self, model: &RobotModel, q: &JointValues) -> Vec<(Part, Capsule)> {
        self.at_pose(model, q, &Isometry3::identity())
    }

    /// Capsules in the world for joint values `q` with the root at `root` (the base's pose).
    pub fn at_pose(
        &self,
        model: &RobotModel,
        q: &JointValues,
        root: &Isometry3<f64>,
    ) -> Vec<(Part, Capsule)> {
        let poses = model.fk_all(q);
        self.capsules
            .iter()
            .map(|c| {
                let [(la, pa), (lb, pb)] = &c.ends;
                let a = (root * poses[*la] * Point3::from(*pa)).coords;
                let b = (root * poses[*lb] * Point3::from(*pb)).coords;
                (
                    c.part,
                    Capsule {
                        a,
                        b,
                        radius: c.radius,
                    },
                )
            })
            .collect()
    }
}

/// Pairs of parts checked for self-collision: arm against arm, and each arm's forearm, wrist
/// and gripper against torso, head and base (shoulders and upper arms are mounted on the torso
/// and cannot reach it).
pub fn self_collision_pair(a: Part, b: Part) -> bool {
    match (a.side(), b.side()) {
        (Some(sa), Some(sb)) => sa != sb,
        (Some(_), None) => matches!(a, Part::Forearm(_) | Part::Wrist(_) | Part::Gripper(_)),
        (None, Some(_)) => self_collision_pair(b, a),
        (None, None) => false,
    }
}

/// Smallest self-collision distance among the checked pairs.
pub fn min_self_distance(capsules: &[(Part, Capsule)]) -> f64 {
    let mut d = f64::INFINITY;
    for (i, (pa, ca)) in capsules.iter().enumerate() {
        for (pb, cb) in &capsules[i + 1..] {
            if self_collision_pair(*pa, *pb) {
                d = d.min(ca.distance(cb));
            }
        }
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn home_pose_is_free_and_crossed_arms_are_not() {
        let m = RobotModel::tiago_dual();
        let body = RobotBody::tiago(&m).unwrap();
        let pairs = crate::home_pose();
        let q = m
            .values_from(pairs.iter().map(|(n, v)| (n.as_str(), *v)))
            .unwrap();
        let d_home = min_self_distance(&body.at(&m, &q));
        assert!(d_home > 0.0, "home pose self distance {d_home}");
        // Swing both arms across the body (joint 1 toward the other side): the grippers meet.
        let mut crossed = q.clone();
        for side in ["left", "right"] {
            let i = m.joint_index(&format!("arm_{side}_1_joint")).unwrap();
            crossed.0[i] = 1.5;
        }
        let d_crossed = min_self_distance(&body.at(&m, &crossed));
        eprintln!("self distance: home {d_home:.3} m, crossed {d_crossed:.3} m");
        assert!(d_crossed < 0.0, "{d_crossed} vs {d_home}");
    }
}
