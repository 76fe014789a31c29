//! Where the camera was when an image was taken: a short history of robot joint states and
//! the camera → `base_footprint` transform from the robot model at the capture time.

use std::collections::VecDeque;

use echo_msgs::JointState;
use echo_robot::{JointValues, RobotModel};
use nalgebra::Isometry3;

/// Joint states kept (2 s at 100 Hz).
const HISTORY: usize = 200;

/// Recent joint states of the joints that move the camera, by stamp.
#[derive(Debug, Clone)]
pub struct JointStateHistory {
    /// Names of the joints between the root and the camera (the only ones that matter).
    chain: Vec<String>,
    states: VecDeque<(u64, Vec<f64>)>,
}

/// Why no camera pose could be found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CameraPoseError {
    /// No joint state received yet.
    #[error("no robot joint state received yet")]
    NoState,
    /// The nearest joint state is too far in time from the image.
    #[error("nearest robot joint state is {gap_ms:.0} ms from the image (limit {limit_ms:.0} ms)")]
    TooFar {
        /// Gap.
        gap_ms: f64,
        /// Limit.
        limit_ms: f64,
    },
    /// The camera frame is not in the robot model.
    #[error("frame '{0}' is not in the robot model")]
    UnknownFrame(String),
}

impl JointStateHistory {
    /// History for the chain of joints above `camera_frame` in `model`.
    pub fn new(model: &RobotModel, camera_frame: &str) -> Result<Self, CameraPoseError> {
        if !model.has_frame(camera_frame) {
            return Err(CameraPoseError::UnknownFrame(camera_frame.into()));
        }
        // A joint moves the camera if changing it changes the camera pose.
        let base = model
            .fk(&model.zero(), camera_frame)
            .map_err(|_| CameraPoseError::UnknownFrame(camera_frame.into()))?;
        let chain = model
            .actuated_joints()
            .iter()
            .filter(|n| {
                let q = model
                    .values_from([(n.as_str(), 0.3)])
                    .unwrap_or(model.zero());
                model
                    .fk(&q, camera_frame)
                    .map(|p| {
                        (p.translation.vector - base.translation.vector).norm() > 1e-9
                            || p.rotation.angle_to(&base.rotation) > 1e-9
                    })
                    .unwrap_or(false)
            })
            .cloned()
            .collect();
        Ok(JointStateHistory {
            chain,
            states: VecDeque::with_capacity(HISTORY),
        })
    }

    /// Joints that move the camera (e.g. torso_lift_joint, head_1_joint, head_2_joint).
    pub fn chain(&self) -> &[String] {
        &self.chain
    }

    /// Record a joint state (any joint order; joints absent from it keep their last value).
    pub fn push(&mut self, js: &JointState) {
        let last = self.states.back().map(|(_, v)| v.clone());
        let values: Vec<f64> = self
            .chain
            .iter()
            .enumerate()
            .map(|(i, n)| {
                js.position_of(n)
                    .or_else(|| last.as_ref().map(|v| v[i]))
                    .unwrap_or(0.0)
            })
            .collect();
        let stamp = js.header.stamp_ns;
        // Keep the history sorted by stamp; drop exact repeats.
        let pos = self.states.partition_point(|(t, _)| *t < stamp);
        if self.states.get(pos).is_some_and(|(t, _)| *t == stamp) {
            return;
        }
        self.states.insert(pos, (stamp, values));
        while self.states.len() > HISTORY {
            self.states.pop_front();
        }
    }

    /// Chain joint values at `stamp_ns`: linear interpolation between the bracketing states, or
    /// the nearest one if `stamp_ns` is outside the history, provided it is within `max_gap_ms`.
    pub fn at(&self, stamp_ns: u64, max_gap_ms: f64) -> Result<Vec<f64>, CameraPoseError> {
        if self.states.is_empty() {
            return Err(CameraPoseError::NoState);
        }
        let pos = self.states.partition_point(|(t, _)| *t < stamp_ns);
        let gap = |t: u64| (t as f64 - stamp_ns as f64).abs() / 1e6;
        let (a, b) = (
            pos.checked_sub(1).and_then(|i| self.states.get(i)),
            self.states.get(pos),
        );
        let (values, gap_ms) = match (a, b) {
            (Some((ta, va)), Some((tb, vb))) => {
                let w = (stamp_ns - ta) as f64 / (tb - ta).max(1) as f64;
                let v = va.iter().zip(vb).map(|(x, y)| x + w * (y - x)).collect();
                (v, gap(*ta).min(gap(*tb)))
            }
            (Some((t, v)), None) | (None, Some((t, v))) => (v.clone(), gap(*t)),
            (None, None) => return Err(CameraPoseError::NoState),
        };
        if gap_ms > max_gap_ms {
            return Err(CameraPoseError::TooFar {
                gap_ms,
                limit_ms: max_gap_ms,
            });
        }
        Ok(values)
    }

    /// Camera pose in the model root at `stamp_ns`.
    pub fn camera_pose(
        &self,
        model: &RobotModel,
        camera_frame: &str,
        stamp_ns: u64,
        max_gap_ms: f64,
    ) -> Result<Isometry3<f64>, CameraPoseError> {
        let v = self.at(stamp_ns, max_gap_ms)?;
        let q: JointValues = model
            .values_from(self.chain.iter().map(|n| n.as_str()).zip(v))
            .map_err(|_| CameraPoseError::UnknownFrame(camera_frame.into()))?;
        model
            .fk(&q, camera_frame)
            .map_err(|_| CameraPoseError::UnknownFrame(camera_frame.into()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use echo_msgs::Header;

    fn js(stamp_ns: u64, pan: f64) -> JointState {
        let mut header = Header::new("r", "s", "");
        header.stamp_ns = stamp_ns;
        JointState {
            header,
            name: vec!["head_1_joint".into(), "torso_lift_joint".into()],
            position: vec![pan, 0.1],
            velocity: vec![],
            base: None,
        }
    }

    #[test]
    fn chain_is_torso_and_head() {
        let m = RobotModel::tiago_dual();
        let h = JointStateHistory::new(&m, "head_front_camera_optical_frame").unwrap();
        assert_eq!(
            h.chain(),
            ["torso_lift_joint", "head_1_joint", "head_2_joint"]
        );
    }

    #[test]
    fn interpolates_between_states_and_bounds_the_gap() {
        let m = RobotModel::tiago_dual();
        let mut h = JointStateHistory::new(&m, "head_front_camera_optical_frame").unwrap();
        assert_eq!(h.at(0, 50.0), Err(CameraPoseError::NoState));
        h.push(&js(1_000_000_000, 0.0));
        h.push(&js(1_010_000_000, 0.1));
        let v = h.at(1_005_000_000, 50.0).unwrap();
        assert!((v[1] - 0.05).abs() < 1e-12);
        assert!(matches!(
            h.at(2_000_000_000, 50.0),
            Err(CameraPoseError::TooFar { .. })
        ));
    }

    #[test]
    fn camera_turns_with_the_head() {
        let m = RobotModel::tiago_dual();
        let mut h = JointStateHistory::new(&m, "head_front_camera_optical_frame").unwrap();
        h.push(&js(0, 0.5));
        let cam = h
            .camera_pose(&m, "head_front_camera_optical_frame", 0, 10.0)
            .unwrap();
        // The optical z axis points forward and 0.5 rad to the left.
        let z = cam.rotation * nalgebra::Vector3::z();
        assert!((z.y.atan2(z.x) - 0.5).abs() < 1e-9, "{z:?}");
    }
}
