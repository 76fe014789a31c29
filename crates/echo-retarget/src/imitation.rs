//! Live imitation ("the imitation game"): the partner's pose, mirrored by default (the robot
//! faces the person, so its left arm copies the person's right), retargeted and sent as a short
//! plan that starts at the robot's measured state — the safety service then limits how fast the
//! robot gets there.

use std::sync::Arc;

use echo_motion::skeleton::{j, NUM_JOINTS};
use echo_msgs::{ControlMode, Header, HumanSkeletons, JointState, PlanPoint, RobotPlan};
use echo_robot::RobotModel;
use nalgebra::Vector3;

use crate::human::body_frame;
use crate::retargeter::Retargeter;

/// Left/right pairs of the 22-joint skeleton.
const MIRROR_PAIRS: [(usize, usize); 8] = [
    (j::L_HIP, j::R_HIP),
    (j::L_KNEE, j::R_KNEE),
    (j::L_ANKLE, j::R_ANKLE),
    (j::L_FOOT, j::R_FOOT),
    (j::L_COLLAR, j::R_COLLAR),
    (j::L_SHOULDER, j::R_SHOULDER),
    (j::L_ELBOW, j::R_ELBOW),
    (j::L_WRIST, j::R_WRIST),
];

/// The pose as seen in a mirror placed in the person's sagittal plane: reflected across it and
/// with left and right exchanged.
pub fn mirror(p: &[Vector3<f64>; NUM_JOINTS]) -> Option<[Vector3<f64>; NUM_JOINTS]> {
    let r = body_frame(p)?;
    let left = r.inverse() * Vector3::y();
    let o = p[j::PELVIS];
    let mut m: [Vector3<f64>; NUM_JOINTS] =
        std::array::from_fn(|k| p[k] - 2.0 * (p[k] - o).dot(&left) * left);
    for (a, b) in MIRROR_PAIRS {
        m.swap(a, b);
    }
    Some(m)
}

/// Settings.
#[derive(Debug, Clone)]
pub struct ImitationConfig {
    /// Mirror the partner (true) or copy side for side.
    pub mirror: bool,
    /// Share of each joint's velocity limit the plan asks for.
    pub speed_fraction: f64,
    /// Shortest time to the target, s.
    pub min_time_s: f64,
    /// Without a partner from the bridge, the nearest person closer than this is imitated, m.
    pub partner_range_m: f64,
}

impl Default for ImitationConfig {
    fn default() -> Self {
        ImitationConfig {
            mirror: true,
            speed_fraction: 0.6,
            min_time_s: 0.3,
            partner_range_m: 4.0,
        }
    }
}

/// Why no plan came out of a frame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ImitationError {
    /// No joint state yet: a plan must start where the robot is.
    #[error("no robot joint state yet")]
    NoState,
    /// Nobody to imitate.
    #[error("no partner in the frame")]
    NoPartner,
    /// The partner's pose cannot be retargeted (degenerate shoulders).
    #[error("partner pose cannot be retargeted")]
    Degenerate,
    /// The joint state lacks a joint the plan needs.
    #[error("joint state has no '{0}'")]
    MissingJoint(String),
    /// The network failed.
    #[error("retargeter: {0}")]
    Model(String),
}

impl ImitationError {
    /// Short reason for counters.
    pub fn reason(&self) -> &'static str {
        match self {
            ImitationError::NoState => "no_state",
            ImitationError::NoPartner => "no_partner",
            ImitationError::Degenerate => "degenerate",
            ImitationError::MissingJoint(_) => "missing_joint",
            ImitationError::Model(_) => "model",
        }
    }
}

/// Partner skeletons → imitation plans.
pub struct Imitator {
    retargeter: Arc<Retargeter>,
    model: RobotModel,
    cfg: ImitationConfig,
    state: Option<JointState>,
}

impl Imitator {
    /// With a trained retargeter.
    pub fn new(retargeter: Arc<Retargeter>, model: RobotModel, cfg: ImitationConfig) -> Imitator {
        Imitator {
            retargeter,
            model,
            cfg,
            state: None,
        }
    }

    /// The retargeter.
    pub fn retargeter(&self) -> &Retargeter {
        &self.retargeter
    }

    /// The robot's measured state.
    pub fn on_joint_state(&mut self, js: &JointState) {
        self.state = Some(js.clone());
    }

    /// A plan toward the partner's (mirrored) pose, starting at the measured state.
    pub fn on_skeletons(&mut self, msg: &HumanSkeletons) -> Result<RobotPlan, ImitationError> {
        let state = self.state.as_ref().ok_or(ImitationError::NoState)?;
        // The bridge's partner; without one, the nearest person within reach of the scene.
        let dist = |t: &&echo_msgs::HumanTrack| {
            let r = t.pose.root_position;
            (r[0] * r[0] + r[1] * r[1]).sqrt()
        };
        let track = match msg.partner_id {
            Some(id) => msg.tracks.iter().find(|t| t.track_id == id),
            None => msg
                .tracks
                .iter()
                .filter(|t| dist(t) < self.cfg.partner_range_m)
                .min_by(|a, b| dist(a).total_cmp(&dist(b))),
        }
        .ok_or(ImitationError::NoPartner)?;
        let p: [Vector3<f64>; NUM_JOINTS] = std::array::from_fn(|k| {
            track
                .pose
                .joints
                .get(k)
                .map(|v| Vector3::new(v[0], v[1], v[2]))
                .unwrap_or_else(Vector3::zeros)
        });
        let p = if self.cfg.mirror {
            mirror(&p).ok_or(ImitationError::Degenerate)?
        } else {
            p
        };
        let pose = self
            .retargeter
            .retarget(&[p])
            .map_err(|e| ImitationError::Model(e.to_string()))?
            .pop()
            .flatten()
            .ok_or(ImitationError::Degenerate)?;
        let mut now = Vec::with_capacity(pose.names.len());
        let mut t: f64 = self.cfg.min_time_s;
        for (n, target) in pose.names.iter().zip(&pose.positions) {
            let q = state
                .position_of(n)
                .ok_or_else(|| ImitationError::MissingJoint(n.clone()))?;
            let v = self
                .model
                .limits(n)
                .map(|l| l.velocity * self.cfg.speed_fraction)
                .unwrap_or(0.5)
                .max(1e-3);
            t = t.max((target - q).abs() / v);
            now.push(q);
        }
        let mut header = Header::new(&msg.header.robot_id, "", "odom");
        header.stamp_ns = msg.header.stamp_ns;
        Ok(RobotPlan {
            header,
            mode: ControlMode::Imitation,
            joint_names: pose.names.clone(),
            points: vec![
                PlanPoint {
                    t: 0.0,
                    positions: now,
                    base: None,
                },
                PlanPoint {
                    t,
                    positions: pose.positions,
                    base: None,
                },
            ],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use echo_motion::synth::{generate, Split};

    #[test]
    fn mirroring_twice_is_the_identity_and_swaps_sides() {
        let clip = generate(&Split::Test.clip(9));
        let p = clip.joints(20, 0);
        let m = mirror(&p).unwrap();
        let back = mirror(&m).unwrap();
        for k in 0..NUM_JOINTS {
            assert!((back[k] - p[k]).norm() < 1e-9);
        }
        // The mirrored left wrist sits where the reflected right wrist is.
        let r = body_frame(&p).unwrap();
        let (lw, rw) = (r * (m[j::L_WRIST] - p[0]), r * (p[j::R_WRIST] - p[0]));
        assert!((lw.y + rw.y).abs() < 1e-9 && (lw.x - rw.x).abs() < 1e-9);
    }
}
