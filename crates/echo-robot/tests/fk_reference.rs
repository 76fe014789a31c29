//! Forward kinematics against the hand-checked poses and the independent FK vectors in
//! ../shared/robots (skipped with a message when that directory is absent).

// The reference values are printed to 5 decimals in the robot documentation; keep them verbatim.
#![allow(clippy::approx_constant)]

use echo_robot::RobotModel;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

fn check(
    m: &RobotModel,
    q: &echo_robot::JointValues,
    frame: &str,
    p: [f64; 3],
    qxyzw: [f64; 4],
    tol_p: f64,
    tol_r: f64,
) {
    let pose = m.fk(q, frame).unwrap();
    let dp = (pose.translation.vector - Vector3::from(p)).norm();
    assert!(
        dp < tol_p,
        "{frame}: position off by {dp} m: {:?}",
        pose.translation.vector
    );
    let expected =
        UnitQuaternion::from_quaternion(Quaternion::new(qxyzw[3], qxyzw[0], qxyzw[1], qxyzw[2]));
    let dr = pose.rotation.angle_to(&expected);
    assert!(dr < tol_r, "{frame}: rotation off by {dr} rad");
}

#[test]
fn hand_checked_poses() {
    let m = RobotModel::tiago_dual();
    let z = m.zero();
    check(
        &m,
        &z,
        "torso_lift_link",
        [-0.062, 0.0, 0.8885],
        [0.0, 0.0, 0.0, 1.0],
        1e-5,
        1e-6,
    );
    check(
        &m,
        &z,
        "head_2_link",
        [0.125, 0.0, 0.9865],
        [0.70711, 0.0, 0.0, 0.70711],
        1e-5,
        1e-5,
    );
    check(
        &m,
        &z,
        "arm_left_tool_link",
        [-0.05444, 0.9845, 0.6865],
        [0.0, 0.0, 0.70711, 0.70711],
        1e-5,
        1e-5,
    );
    check(
        &m,
        &z,
        "arm_right_tool_link",
        [-0.05744, -0.9845, 0.6865],
        [0.70711, -0.70711, 0.0, 0.0],
        1e-5,
        1e-5,
    );
    let pairs = echo_robot::home_pose();
    let home = m
        .values_from(pairs.iter().map(|(n, v)| (n.as_str(), *v)))
        .unwrap();
    check(
        &m,
        &home,
        "arm_left_tool_link",
        [0.15379, 0.22826, 0.56438],
        [0.53318, -0.48685, 0.44297, 0.53149],
        1e-5,
        1e-4,
    );
    check(
        &m,
        &home,
        "arm_right_tool_link",
        [0.15243, -0.22558, 0.56438],
        [0.53149, -0.44297, 0.48685, 0.53318],
        1e-5,
        1e-4,
    );
    check(
        &m,
        &home,
        "gripper_left_grasping_frame",
        [0.1739, 0.22099, 0.71343],
        [-0.75283, 0.03103, -0.65748, 0.00119],
        1e-5,
        1e-4,
    );
}

#[test]
fn agrees_with_independent_fk_vectors() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/robots/tiago_dual_fk_vectors.csv");
    let Ok(text) = std::fs::read_to_string(&path) else {
        eprintln!("skipping: {} not present", path.display());
        return;
    };
    let m = RobotModel::tiago_dual();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let joints: Vec<&str> = head
        .iter()
        .copied()
        .filter(|h| h.ends_with("_joint"))
        .collect();
    let frames: Vec<&str> = head.iter().filter_map(|h| h.strip_suffix("_x")).collect();
    let mut rows = 0;
    let (mut worst_p, mut worst_r) = (0.0f64, 0.0f64);
    for line in lines.filter(|l| !l.trim().is_empty()) {
        let v: Vec<f64> = line.split(',').map(|s| s.trim().parse().unwrap()).collect();
        let col = |name: &str| v[head.iter().position(|h| *h == name).unwrap()];
        let q = m.values_from(joints.iter().map(|j| (*j, col(j)))).unwrap();
        for f in &frames {
            let pose = m.fk(&q, f).unwrap();
            let p = Vector3::new(
                col(&format!("{f}_x")),
                col(&format!("{f}_y")),
                col(&format!("{f}_z")),
            );
            let qe = UnitQuaternion::from_quaternion(Quaternion::new(
                col(&format!("{f}_qw")),
                col(&format!("{f}_qx")),
                col(&format!("{f}_qy")),
                col(&format!("{f}_qz")),
            ));
            worst_p = worst_p.max((pose.translation.vector - p).norm());
            // Grasping frames use PAL's rounded 1.5708 in both models; compare all frames exactly.
            worst_r = worst_r.max(pose.rotation.angle_to(&qe));
        }
        rows += 1;
    }
    assert_eq!(rows, 64);
    assert!(worst_p < 1e-6, "worst position error {worst_p} m");
    assert!(worst_r < 1e-6, "worst rotation error {worst_r} rad");
}
