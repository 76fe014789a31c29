//! The CDR encoder reproduces the golden samples of an independent ROS 2 serializer byte for
//! byte, and decodes them back (../shared/ros2; skipped when absent).

use echo_ros2::*;

fn golden(name: &str) -> Option<Vec<u8>> {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/ros2")
        .join(name);
    match std::fs::read(&p) {
        Ok(b) => Some(b),
        Err(_) => {
            eprintln!("skipping: {} not present", p.display());
            None
        }
    }
}

#[test]
fn joint_state_matches_golden_bytes() {
    let msg = RosJointState {
        header: RosHeader {
            stamp: Time { sec: 1, nanosec: 2 },
            frame_id: String::new(),
        },
        name: vec!["head_1_joint".into(), "head_2_joint".into()],
        position: vec![0.1, -0.2],
        velocity: vec![],
        effort: vec![],
    };
    let bytes = encode(&msg).unwrap();
    assert_eq!(&bytes[..4], &[0, 1, 0, 0], "little-endian encapsulation");
    if let Some(g) = golden("joint_state_le.bin") {
        assert_eq!(bytes, g);
        assert_eq!(decode::<RosJointState>(&g).unwrap(), msg);
    }
}

#[test]
fn joint_trajectory_matches_golden_bytes() {
    let msg = RosJointTrajectory {
        header: RosHeader::default(),
        joint_names: vec!["torso_lift_joint".into()],
        points: vec![RosTrajectoryPoint {
            positions: vec![0.15],
            time_from_start: Time::from_secs(2.5),
            ..Default::default()
        }],
    };
    let bytes = encode(&msg).unwrap();
    if let Some(g) = golden("joint_trajectory_le.bin") {
        assert_eq!(bytes, g);
        assert_eq!(decode::<RosJointTrajectory>(&g).unwrap(), msg);
    }
}

#[test]
fn truncated_samples_are_errors_not_panics() {
    let bytes = encode(&RosJointState {
        name: vec!["a".into()],
        position: vec![1.0],
        ..Default::default()
    })
    .unwrap();
    for n in 0..bytes.len() {
        assert!(decode::<RosJointState>(&bytes[..n]).is_err() || n >= bytes.len() - 3);
    }
    assert!(decode::<RosJointState>(&[0xff; 64]).is_err());
}

#[test]
fn keys_follow_the_bridge_conventions() {
    assert_eq!(
        ros_key("", "/arm_left_controller/joint_trajectory"),
        "arm_left_controller/joint_trajectory"
    );
    assert_eq!(
        ros_key("/tiago_1", &trajectory_topic("head_controller")),
        "tiago_1/head_controller/joint_trajectory"
    );
    assert_eq!(
        ros_key("/tiago_1", JOINT_STATES_TOPIC),
        "tiago_1/joint_states"
    );
}
