//! Prints one example of every message as JSON (the examples in docs/PROTOCOL.md).
//! `cargo run -p echo-msgs --example protocol_examples`

use std::collections::BTreeMap;

use echo_msgs::*;

fn h(frame: &str, source: &str, seq: u64) -> Header {
    Header {
        schema: SCHEMA_VERSION,
        seq,
        stamp_ns: 1_763_683_200_000_000_000,
        robot_id: "tiago".into(),
        frame_id: frame.into(),
        source: source.into(),
    }
}

fn show<M: Message>(m: &M) {
    m.validate().expect("example is valid");
    println!(
        "### {}\n```json\n{}\n```\n",
        M::KIND,
        serde_json::to_string(m).unwrap()
    );
}

fn main() {
    let q = [0.0, 0.0, 0.0, 1.0];
    show(&KeypointFrame {
        header: h(frames::HEAD_CAMERA_OPTICAL, "pose-estimator-1", 42),
        format: KeypointFormat::Coco17,
        joint_names: None,
        camera: Some(CameraIntrinsics {
            fx: 522.0,
            fy: 522.0,
            cx: 320.0,
            cy: 240.0,
            width: 640,
            height: 480,
        }),
        depth_image: None,
        people: vec![DetectedPerson {
            detection_id: Some(1),
            keypoints: Keypoints::PixelsDepth {
                uv: (0..17)
                    .map(|i| [300.0 + i as f64, 100.0 + 20.0 * i as f64])
                    .collect(),
                depth_m: Some(vec![2.1; 17]),
            },
            confidence: vec![0.9; 17],
        }],
    });
    let pose = HumanPose {
        joints: vec![[1.2, 0.1, 0.95]; 22],
        root_position: [1.2, 0.1, 0.95],
        root_orientation: [0.0, 0.0, 1.0, 0.0],
        local_positions: vec![[0.0; 3]; 22],
        local_rotations: vec![q; 22],
        confidence: vec![0.95; 22],
    };
    show(&HumanSkeletons {
        header: h(frames::BASE_FOOTPRINT, "perception-bridge-4242-1a2b", 310),
        rate_hz: 15.0,
        tracks: vec![HumanTrack {
            track_id: 0,
            pose,
            root_velocity: [-0.8, 0.0, 0.0],
            age_frames: 57,
            filled_joints: vec![10, 11],
        }],
        partner_id: Some(0),
    });
    show(&JointState {
        header: h("", "mock-robot-4240-0c0d", 1200),
        name: vec![
            "torso_lift_joint".into(),
            "head_1_joint".into(),
            "head_2_joint".into(),
        ],
        position: vec![0.15, 0.1, -0.2],
        velocity: vec![0.0, 0.05, 0.0],
        base: Some(BasePose {
            x: 0.0,
            y: 0.0,
            yaw: 0.0,
        }),
    });
    show(&InteractionIntent {
        header: h("", "operator", 3),
        text: "One person extends a handshake with their right hand, while the other reciprocates with their own.".into(),
        interaction: Interaction::Handshake,
        mode: ControlMode::Forecast,
    });
    let plan = RobotPlan {
        header: h("odom", "forecaster-77-aa01", 88),
        mode: ControlMode::Forecast,
        joint_names: vec!["arm_right_1_joint".into(), "arm_right_2_joint".into()],
        points: vec![
            PlanPoint {
                t: 0.0667,
                positions: vec![0.2, 0.1],
                base: None,
            },
            PlanPoint {
                t: 0.1333,
                positions: vec![0.25, 0.12],
                base: Some(BasePose {
                    x: 0.01,
                    y: 0.0,
                    yaw: 0.0,
                }),
            },
        ],
    };
    show(&Forecast {
        header: h(frames::BASE_FOOTPRINT, "forecaster-77-aa01", 88),
        model: "hhi-default".into(),
        rate_hz: 15.0,
        partner_id: 0,
        human: vec![vec![[1.1, 0.1, 0.95]; 22]; 2],
        robot: Some(plan.clone()),
        inference_ms: 4.2,
    });
    show(&RobotPlan {
        header: h("odom", "retargeter-78-bb02", 5),
        mode: ControlMode::Imitation,
        ..plan
    });
    show(&RobotCommand {
        header: h("", "safety-79-cc03", 900),
        trajectories: vec![ControllerTrajectory {
            controller: "head_controller".into(),
            joint_names: vec!["head_1_joint".into(), "head_2_joint".into()],
            points: vec![TrajectoryPoint {
                time_from_start: 0.01,
                positions: vec![0.1, -0.2],
                velocities: vec![0.0, 0.0],
                accelerations: vec![0.0, 0.0],
            }],
        }],
        base_twist: Some(BaseTwist {
            linear_x: 0.0,
            angular_z: 0.0,
        }),
    });
    show(&SafetyStatus {
        header: h("", "safety-79-cc03", 901),
        state: SafetyState::Limiting,
        reasons: vec!["separation 0.62 m < 0.80 m: speed scaled to 0.40".into()],
        speed_scale: 0.4,
        min_separation_m: Some(0.62),
        counters: BTreeMap::from([("plan/not_increasing".to_string(), 1)]),
    });
    show(&EStop {
        header: h("", "operator", 1),
        action: EStopAction::Engage,
        reason: "operator button".into(),
    });
    show(&ServiceStatus {
        header: h("", "perception-bridge-4242-1a2b", 61),
        service: "perception-bridge".into(),
        uptime_s: 60.2,
        received: BTreeMap::from([
            ("perception_raw".to_string(), 903),
            ("robot_state".to_string(), 6020),
        ]),
        published: BTreeMap::from([("humans".to_string(), 900)]),
        rejected: BTreeMap::from([("perception_raw/stale".to_string(), 2)]),
        dropped: BTreeMap::new(),
        last_error: Some("perception_raw: frame is 812 ms old (limit 500 ms)".into()),
        latency: Some(LatencySummary {
            median_ms: 0.008,
            p99_ms: 0.012,
            samples: 903,
        }),
        notes: vec![],
    });
}
