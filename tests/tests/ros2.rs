//! The safety service speaking ROS 2 through zenoh-bridge-ros2dds conventions: it reads CDR
//! sensor_msgs/JointState from `<ns>/joint_states` and publishes CDR trajectory_msgs/JointTrajectory
//! per controller and a geometry_msgs/Twist — the test plays the bridge.

use std::time::Duration;

use echo_robot::groups::motion_groups;
use echo_ros2::*;
use echo_system_tests::Harness;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn safety_reads_and_writes_ros2_cdr() -> anyhow::Result<()> {
    let mut h = Harness::new("sys-ros2", 1)?;
    h.spawn_service(
        "robot",
        "safety",
        &echo_system_tests::profile_vars(),
        &["--ros2-namespace", "/tiago_sim"],
    )?;
    let bus = h.bus("ros2-bridge").await?;
    h.wait_alive(&bus, &["safety"], Duration::from_secs(30))
        .await?;
    let s = bus.session();
    let traj = s
        .declare_subscriber(ros_key(
            "/tiago_sim",
            &trajectory_topic("arm_left_controller"),
        ))
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let twist = s
        .declare_subscriber(ros_key("/tiago_sim", BASE_TWIST_TOPIC))
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let states = s
        .declare_publisher(ros_key("/tiago_sim", JOINT_STATES_TOPIC))
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let home = echo_robot::home_pose();
    let names: Vec<String> = motion_groups()
        .iter()
        .flat_map(|g| g.joints.clone())
        .collect();
    let position: Vec<f64> = names
        .iter()
        .map(|n| home.iter().find(|(j, _)| j == n).map_or(0.0, |(_, v)| *v))
        .collect();
    let mut got = None;
    for _ in 0..100 {
        let js = RosJointState {
            header: RosHeader {
                stamp: Time::from_ns(echo_msgs::now_ns()),
                frame_id: String::new(),
            },
            name: names.clone(),
            position: position.clone(),
            velocity: vec![],
            effort: vec![],
        };
        states
            .put(encode(&js)?)
            .await
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        // Garbage on the same key must be rejected, not crash the service.
        states
            .put(vec![0u8, 1, 0, 0, 9, 9])
            .await
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        if let Ok(Ok(sample)) =
            tokio::time::timeout(Duration::from_millis(50), traj.recv_async()).await
        {
            got = Some(sample.payload().to_bytes().to_vec());
            break;
        }
    }
    let bytes = got.expect("a CDR trajectory for arm_left_controller");
    assert_eq!(
        &bytes[..4],
        &[0, 1, 0, 0],
        "little-endian CDR with the encapsulation header"
    );
    let t: RosJointTrajectory = decode(&bytes)?;
    assert_eq!(
        t.joint_names,
        (1..=7)
            .map(|i| format!("arm_left_{i}_joint"))
            .collect::<Vec<_>>()
    );
    assert!(!t.points.is_empty());
    // Without a plan the robot holds where it is: every point at the measured home pose, at rest.
    for p in &t.points {
        for (k, q) in p.positions.iter().enumerate() {
            assert!((q - echo_robot::HOME_ARM[k]).abs() < 1e-9);
        }
    }
    let sample = tokio::time::timeout(Duration::from_secs(2), twist.recv_async())
        .await?
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let tw: Twist = decode(&sample.payload().to_bytes())?;
    assert_eq!(tw, Twist::default());
    assert!(h.is_running("safety"));
    Ok(())
}
