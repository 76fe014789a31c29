//! Ready-made input sequences for tests and benchmarks: what the robot interface and the pose
//! estimator would publish while the scripted interaction plays.

use echo_msgs::{frames, JointState, KeypointFrame};
use echo_robot::RobotModel;

use crate::perception::{MockPerception, MockPerceptionConfig};
use crate::robot::{SimRobot, SimRobotConfig};

/// Capture stamps start here (a fixed epoch keeps runs reproducible).
pub const T0_NS: u64 = 1_700_000_000_000_000_000;

/// `n` keypoint frames at the mock's rate, each preceded by the joint state at its capture time,
/// with the head sweeping. `cfg.bystander` adds the second person.
pub fn bridge_inputs(n: usize, cfg: MockPerceptionConfig) -> Vec<(JointState, KeypointFrame)> {
    let model = RobotModel::tiago_dual();
    let mut robot = SimRobot::new(
        SimRobotConfig {
            head_sweep_rad: 0.3,
            ..Default::default()
        },
        model.clone(),
    );
    let rate = cfg.rate_hz;
    let mut mock = MockPerception::new(cfg);
    let mut out = Vec::with_capacity(n);
    let mut i = 0u64;
    while out.len() < n {
        robot.step(1.0 / rate);
        let t = (i + 1) as f64 / rate;
        let stamp = T0_NS + (t * 1e9) as u64;
        i += 1;
        let Ok(cam) = robot.frame_pose(frames::HEAD_CAMERA_OPTICAL) else {
            continue;
        };
        if let Some(f) = mock.frame("tiago", mock.script_time(t), stamp, &cam) {
            out.push((robot.joint_state("tiago", stamp), f));
        }
    }
    out
}
