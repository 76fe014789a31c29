//! Human–robot mode end to end, as separate processes over Zenoh on loopback: mock perception
//! replays person A of a handshake of the test split, placed so the robot stands where person B
//! stood when the two were closest; the HRI forecaster plans for the robot; safety filters; the simulated robot moves.
//! The robot's gripper gets closer to the partner's hand than the retargeted reference (person B
//! turned into the robot, base where B started) does, with no safety violation.

use std::time::Duration;

use echo_bus::topics;
use echo_motion::skeleton::j;
use echo_motion::synth::{generate, Split};
use echo_msgs::{now_ns, SafetyState};
use echo_robot::RobotModel;
use echo_system_tests::Harness;
use nalgebra::Vector3;

fn grippers(model: &RobotModel, names: &[String], pos: &[f64]) -> Vec<Vector3<f64>> {
    let q = model
        .values_from(
            names
                .iter()
                .zip(pos)
                .filter(|(n, _)| model.joint_index(n).is_some())
                .map(|(n, p)| (n.as_str(), *p)),
        )
        .expect("known joints");
    [
        "gripper_left_grasping_frame",
        "gripper_right_grasping_frame",
    ]
    .iter()
    .map(|f| model.fk(&q, f).expect("frame").translation.vector)
    .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_robot_reaches_for_the_offered_hand() -> anyhow::Result<()> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let hri = root.join("models/hri");
    let model = RobotModel::tiago_dual();

    // The retargeted reference of the same clip, base fixed where the robot stands.
    let clip = generate(&Split::Test.clip(0));
    let r = echo_retarget::Retargeter::load(&root.join("models/retargeter"), model.clone())?;
    let b0 = clip.joints(echo_sim::perception::closest_frame(&clip), 1);
    let yaw = echo_motion::skeleton::heading(&b0).euler_angles().2;
    let rot = nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -yaw);
    let o = Vector3::new(b0[0].x, b0[0].y, 0.0);
    let mut reference_min = f64::INFINITY;
    for f in (0..clip.frames.len()).step_by(2) {
        let Some(pose) = r.retarget(&[clip.joints(f, 1)])?.pop().flatten() else {
            continue;
        };
        let back = Vector3::new(echo_sim::perception::ROBOT_SETBACK_M, 0.0, 0.0);
        let a = clip.joints(f, 0).map(|p| rot * (p - o) + back);
        for g in grippers(&model, &pose.names, &pose.positions) {
            for w in [j::L_WRIST, j::R_WRIST] {
                reference_min = reference_min.min((g - a[w]).norm());
            }
        }
    }

    let mut h = Harness::new("sys-hri", 5)?;
    h.spawn("mock-robot", "echoctl", &["mock-robot"])?;
    h.spawn("perception-bridge", "perception-bridge", &[])?;
    h.spawn(
        "forecaster",
        "forecaster",
        &["--model", hri.to_str().unwrap_or_default()],
    )?;
    h.spawn("safety", "safety", &["--require", "mock-robot"])?;
    let t0 = now_ns() + 3_000_000_000;
    h.spawn(
        "mock-perception",
        "echoctl",
        &[
            "mock-perception",
            "--clip",
            "test:0",
            "--robot-plays-b",
            "--t0-ns",
            &t0.to_string(),
        ],
    )?;
    let bus = h.bus("system-test").await?;
    let robot = bus.robot().clone();
    let states = bus.subscribe(&topics::robot_state(&robot)).await?;
    let humans = bus.subscribe(&topics::humans(&robot)).await?;
    let safety = bus.subscribe(&topics::safety_status(&robot)).await?;
    h.wait_alive(
        &bus,
        &[
            "mock-robot",
            "perception-bridge",
            "forecaster",
            "safety",
            "mock-perception",
        ],
        Duration::from_secs(60),
    )
    .await?;
    let (mut latest, mut robot_min, mut accepted, mut estopped) =
        (None, f64::INFINITY, 0u64, false);
    let deadline =
        tokio::time::Instant::now() + Duration::from_secs(3 + clip.duration().ceil() as u64);
    while tokio::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(50)).await;
        if let Some(s) = states.drain().pop() {
            latest = Some(grippers(&model, &s.msg.name, &s.msg.position));
        }
        for s in humans.drain() {
            let (Some(g), Some(pid)) = (&latest, s.msg.partner_id) else {
                continue;
            };
            let Some(t) = s.msg.tracks.iter().find(|t| t.track_id == pid) else {
                continue;
            };
            for w in [j::L_WRIST, j::R_WRIST] {
                let p = Vector3::from(t.pose.joints[w]);
                for e in g {
                    robot_min = robot_min.min((e - p).norm());
                }
            }
        }
        for s in safety.drain() {
            accepted = accepted.max(s.msg.counters.get("plan/accepted").copied().unwrap_or(0));
            estopped |= s.msg.state == SafetyState::EStopped;
        }
    }
    eprintln!(
        "closest gripper to the partner's hand: robot {robot_min:.3} m, retargeted reference {reference_min:.3} m; {accepted} plans accepted"
    );
    assert!(accepted > 20, "safety accepted only {accepted} plans");
    assert!(!estopped);
    assert!(
        robot_min < reference_min,
        "the robot ({robot_min:.3} m) must come closer to the offered hand than the reference ({reference_min:.3} m)"
    );
    Ok(())
}
