//! Representative scenes for benchmarks: the robot waving its right arm at 15 Hz plans while a
//! person stands 1.5 m in front with a forecast, or a handshake partner 0.7 m in front.

use std::time::Instant;

use echo_msgs::{
    frames, ControlMode, Forecast, Header, HumanPose, HumanSkeletons, HumanTrack, JointState,
    PlanPoint, RobotPlan,
};
use echo_robot::RobotModel;

use crate::{SafetyConfig, Supervisor};

/// A person standing at (x, 0) in base_footprint, arms down.
fn person(x: f64) -> Vec<[f64; 3]> {
    let rel: [[f64; 3]; 22] = [
        [0.0, 0.0, 0.95],
        [0.0, -0.09, 0.86],
        [0.0, 0.09, 0.86],
        [0.0, 0.0, 1.06],
        [0.0, -0.1, 0.46],
        [0.0, 0.1, 0.46],
        [0.0, 0.0, 1.2],
        [0.0, -0.1, 0.06],
        [0.0, 0.1, 0.06],
        [0.0, 0.0, 1.28],
        [-0.12, -0.1, 0.0],
        [-0.12, 0.1, 0.0],
        [0.0, 0.0, 1.52],
        [0.0, -0.07, 1.41],
        [0.0, 0.07, 1.41],
        [0.0, 0.0, 1.63],
        [0.0, -0.18, 1.43],
        [0.0, 0.18, 1.43],
        [0.0, -0.2, 1.15],
        [0.0, 0.2, 1.15],
        [0.0, -0.2, 0.9],
        [0.0, 0.2, 0.9],
    ];
    rel.iter().map(|p| [x + p[0], p[1], p[2]]).collect()
}

/// A skeletons message with one tracked partner at `joints` (base_footprint, facing the robot).
pub fn partner_skeletons(joints: Vec<[f64; 3]>) -> HumanSkeletons {
    HumanSkeletons {
        header: Header::new("tiago", "bridge", frames::BASE_FOOTPRINT),
        rate_hz: 15.0,
        tracks: vec![HumanTrack {
            track_id: 0,
            pose: HumanPose {
                root_position: joints[0],
                joints,
                root_orientation: [0.0, 0.0, 1.0, 0.0],
                local_positions: vec![[0.0; 3]; 22],
                local_rotations: vec![[0.0, 0.0, 0.0, 1.0]; 22],
                confidence: vec![1.0; 22],
            },
            root_velocity: [0.0; 3],
            age_frames: 1,
            filled_joints: vec![],
        }],
        partner_id: Some(0),
    }
}

/// Where the person of a bench scene stands and what the intent says.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Scene {
    /// A person 1.5 m in front, no interaction announced (speed and separation monitoring).
    PersonInView,
    /// A handshake partner 0.7 m in front (contact mode: clearances and the speed cap).
    HandshakePartner,
}

/// The supervisor and a closure that feeds it one cycle of inputs (state every cycle, a plan
/// and skeletons every third cycle).
pub fn moving_scene(scene: Scene) -> (Supervisor, impl FnMut(&mut Supervisor, Instant)) {
    let model = RobotModel::tiago_dual();
    let mut sup = Supervisor::new(SafetyConfig::default(), model).expect("default config");
    let distance = match scene {
        Scene::PersonInView => 1.5,
        Scene::HandshakePartner => {
            sup.on_intent(&echo_msgs::InteractionIntent {
                header: Header::new("tiago", "bench", ""),
                text: "A handshake.".into(),
                interaction: echo_msgs::Interaction::Handshake,
                mode: ControlMode::Forecast,
            });
            0.7
        }
    };
    let joints = sup.filter().joints().to_vec();
    let home = echo_robot::home_pose();
    let q0: Vec<f64> = joints
        .iter()
        .map(|j| home.iter().find(|(n, _)| n == j).map_or(0.0, |(_, v)| *v))
        .collect();
    let js = move |names: &[String], q: &[f64]| JointState {
        header: Header::new("tiago", "robot", ""),
        name: names.to_vec(),
        position: q.to_vec(),
        velocity: vec![],
        base: None,
    };
    let _ = sup.on_joint_state(&js(&joints, &q0), Instant::now());
    let i = joints
        .iter()
        .position(|j| j == "arm_right_1_joint")
        .unwrap_or(0);
    let mut cycle = 0u64;
    let feed = move |s: &mut Supervisor, now: Instant| {
        let q: Vec<f64> = s.filter().state().iter().map(|x| x.q).collect();
        let _ = s.on_joint_state(&js(&joints, &q), now);
        if cycle.is_multiple_of(3) {
            let t = cycle as f64 * 0.02;
            let mut h = Header::new("tiago", "forecaster", "odom");
            h.stamp_ns = cycle + 1;
            let plan = RobotPlan {
                header: h,
                mode: ControlMode::Forecast,
                joint_names: joints.clone(),
                points: (0..16)
                    .map(|k| {
                        let mut p = q.clone();
                        if k > 0 {
                            p[i] = -1.1
                                + 0.4
                                    * (2.0 * std::f64::consts::PI * (t + k as f64 / 15.0) / 3.0)
                                        .sin();
                        }
                        PlanPoint {
                            t: k as f64 / 15.0,
                            positions: p,
                            base: None,
                        }
                    })
                    .collect(),
            };
            let body = person(distance);
            let _ = s.on_forecast(
                &Forecast {
                    header: Header::new("tiago", "forecaster", frames::BASE_FOOTPRINT),
                    model: "bench".into(),
                    rate_hz: 15.0,
                    partner_id: 0,
                    human: vec![body.clone(); 15],
                    robot: Some(plan),
                    inference_ms: 0.0,
                },
                now,
            );
            s.on_humans(&partner_skeletons(body), now);
        }
        cycle += 1;
    };
    (sup, feed)
}
