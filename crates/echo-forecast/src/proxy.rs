//! The robot as the second agent of a human-human forecaster.
//!
//! Until the robot's own (HRI) model exists, the forecaster pairs the partner with the robot
//! seen as a person: its kinematic points — shoulders (`arm_*_1_link`), elbows (`arm_*_4_link`),
//! wrists (`arm_*_7_link`), head (`head_2_link`) — computed by FK from the measured joint state,
//! and the rest of a standing skeleton filled in with human proportions below the shoulders.
//! Frame: `base_footprint` (the skeletons' frame); the robot faces +x, its left is +y.

use echo_motion::skeleton::NUM_JOINTS;
use echo_msgs::JointState;
use echo_robot::{JointValues, RobotModel};
use nalgebra::Vector3;

/// Pelvis height over shoulder height for an adult (≈ 0.53 / 0.82 of stature).
const PELVIS_OVER_SHOULDER: f64 = 0.65;

/// Builds the robot's 22-joint stand-in from joint states.
#[derive(Debug, Clone)]
pub struct RobotProxy {
    model: RobotModel,
    q: JointValues,
}

impl RobotProxy {
    /// At the model's home pose until a joint state arrives.
    pub fn new(model: RobotModel) -> RobotProxy {
        let home = echo_robot::home_pose();
        let q = model
            .values_from(home.iter().map(|(n, v)| (n.as_str(), *v)))
            .unwrap_or_else(|_| model.zero());
        RobotProxy { model, q }
    }

    /// Take the measured joint positions; unknown joint names are ignored (a robot may report
    /// joints this model does not have, e.g. wheels).
    pub fn update(&mut self, js: &JointState) {
        for (n, v) in js.name.iter().zip(&js.position) {
            if let Some(i) = self.model.joint_index(n) {
                if v.is_finite() {
                    self.q.0[i] = *v;
                }
            }
        }
    }

    /// The 22 joints of the stand-in, in `base_footprint`.
    pub fn joints(&self) -> [Vector3<f64>; NUM_JOINTS] {
        let p = |frame: &str| -> Vector3<f64> {
            self.model
                .fk(&self.q, frame)
                .map(|t| t.translation.vector)
                .unwrap_or_else(|_| Vector3::zeros())
        };
        let (ls, rs) = (p("arm_left_1_link"), p("arm_right_1_link"));
        let (le, re) = (p("arm_left_4_link"), p("arm_right_4_link"));
        let (lw, rw) = (p("arm_left_7_link"), p("arm_right_7_link"));
        let head = p("head_2_link");
        let mid = (ls + rs) / 2.0;
        let pelvis = Vector3::new(mid.x, mid.y, mid.z * PELVIS_OVER_SHOULDER);
        let neck = mid + Vector3::new(0.0, 0.0, 0.05);
        let lerp = |a: &Vector3<f64>, b: &Vector3<f64>, t: f64| a + (b - a) * t;
        let hip = |s: f64| pelvis + Vector3::new(0.0, 0.09 * s, -0.05);
        let knee = |s: f64| Vector3::new(pelvis.x, pelvis.y + 0.09 * s, pelvis.z * 0.5);
        let ankle = |s: f64| Vector3::new(pelvis.x, pelvis.y + 0.09 * s, 0.08);
        let foot = |s: f64| Vector3::new(pelvis.x + 0.12, pelvis.y + 0.09 * s, 0.02);
        [
            pelvis,
            hip(1.0),
            hip(-1.0),
            lerp(&pelvis, &neck, 0.25),
            knee(1.0),
            knee(-1.0),
            lerp(&pelvis, &neck, 0.5),
            ankle(1.0),
            ankle(-1.0),
            lerp(&pelvis, &neck, 0.75),
            foot(1.0),
            foot(-1.0),
            neck,
            lerp(&neck, &ls, 0.5),
            lerp(&neck, &rs, 0.5),
            head,
            ls,
            rs,
            le,
            re,
            lw,
            rw,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use echo_motion::skeleton::heading;

    #[test]
    fn stand_in_faces_forward_and_follows_the_arm() {
        let model = RobotModel::tiago_dual();
        let mut p = RobotProxy::new(model);
        let j = p.joints();
        // Facing +x: the heading of the stand-in is (close to) the identity.
        let h = heading(&j);
        assert!(h.angle() < 0.2, "heading {}", h.angle());
        // Left is +y, as for a person facing +x.
        assert!(j[16].y > j[17].y && j[1].y > j[2].y);
        assert!(j[15].z > j[12].z && j[12].z > j[0].z && j[0].z > j[4].z);
        // Moving the left shoulder joint moves the left wrist only.
        let before = j;
        let js = JointState {
            header: echo_msgs::Header::new("r", "t", "base_footprint"),
            name: vec!["arm_left_1_joint".into(), "no_such_joint".into()],
            position: vec![1.2, 3.0],
            velocity: vec![],
            base: None,
        };
        p.update(&js);
        let after = p.joints();
        assert!((after[20] - before[20]).norm() > 0.05);
        assert!((after[21] - before[21]).norm() < 1e-9);
    }
}
