//! A scripted handshake end to end, as separate processes over Zenoh on loopback: mock
//! perception plays person A of a test-split handshake to the robot (which stands where person B
//! stood) → perception bridge → HRI forecaster (the shipped `models/hri`) → safety → simulated
//! robot. The robot's gripper must come closer to the partner's hand than the retargeted
//! reference alone would (B's motion retargeted and played from the same spot), and no command
//! may break a joint limit or move a robot part into the partner's head clearance.

use std::time::Duration;

use echo_bus::topics;
use echo_motion::synth::{generate, Split};
use echo_msgs::{now_ns, ControlMode, Header, Interaction, InteractionIntent, SafetyState};
use echo_retarget::hri::{convert, gripper_reach, reference_reach, Reach};
use echo_retarget::retargeter::Retargeter;
use echo_robot::collision::RobotBody;
use echo_robot::RobotModel;
use echo_system_tests::Harness;
use nalgebra::{Isometry3, Vector3};

/// A handshake of the test split (seeds never trained on).
const CLIP: (Split, u64) = (Split::Test, 0);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_robot_reaches_for_the_offered_hand_closer_than_the_reference() -> anyhow::Result<()> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let model = RobotModel::tiago_dual();
    let clip = generate(&CLIP.0.clip(CLIP.1));
    assert_eq!(
        format!("{:?}", clip.params.kind),
        "Handshake",
        "the scripted clip"
    );

    // The retargeted reference alone, played from where the robot stands.
    let retargeter = Retargeter::load(&root.join("models/retargeter"), model.clone())?;
    let hri = convert(&clip, &retargeter)?;
    let base = echo_sim::perception::robot_base_in_clip(&clip);
    let body = RobotBody::tiago(&model)?;
    let reference = reference_reach(&hri, &retargeter, &model, &body, &base)?;

    let mut h = Harness::new("sys-handshake", 5)?;
    h.spawn("mock-robot", "echoctl", &["mock-robot"])?;
    h.spawn("perception-bridge", "perception-bridge", &[])?;
    let hri_model = root.join("models/hri");
    h.spawn(
        "forecaster",
        "forecaster",
        &["--model", hri_model.to_str().unwrap_or_default()],
    )?;
    h.spawn("safety", "safety", &["--require", "mock-robot"])?;
    let bus = h.bus("system-test").await?;
    let robot = bus.robot().clone();
    let prompt = bus.publisher(&topics::prompt(&robot)).await?;
    let states = bus.subscribe(&topics::robot_state(&robot)).await?;
    let humans = bus.subscribe(&topics::humans(&robot)).await?;
    let commands = bus.subscribe(&topics::command(&robot)).await?;
    let safety = bus.subscribe(&topics::safety_status(&robot)).await?;
    h.wait_alive(
        &bus,
        &["mock-robot", "perception-bridge", "forecaster", "safety"],
        Duration::from_secs(60),
    )
    .await?;
    // The partner starts once everything listens, and plays the clip once.
    let t0 = now_ns() + 1_000_000_000;
    h.spawn(
        "mock-perception",
        "echoctl",
        &[
            "mock-perception",
            "--clip",
            &format!("test:{}", CLIP.1),
            "--robot-plays-b",
            "--t0-ns",
            &t0.to_string(),
        ],
    )?;

    let mut q = None;
    let (mut reach, mut head_m, mut frames) = (Reach::NONE, f64::INFINITY, 0usize);
    let (mut points, mut violations, mut accepted, mut estopped) = (0usize, vec![], 0u64, false);
    // From now: 1 s to the partner's start, the clip, then 0.5 s.
    let clip_s = clip.frames.len() as f64 / echo_motion::synth::FPS;
    let deadline = tokio::time::Instant::now() + Duration::from_secs_f64(1.5 + clip_s);
    while tokio::time::Instant::now() < deadline {
        prompt
            .put(InteractionIntent {
                header: Header::new(robot.as_str(), "", ""),
                text: "One person extends a handshake with their right hand, while the other \
                       reciprocates with their own."
                    .into(),
                interaction: Interaction::Handshake,
                mode: ControlMode::Forecast,
            })
            .await?;
        for _ in 0..10 {
            tokio::time::sleep(Duration::from_millis(25)).await;
            for s in states.drain() {
                let pairs: Vec<(&str, f64)> = s
                    .msg
                    .name
                    .iter()
                    .zip(&s.msg.position)
                    .filter(|(n, _)| model.joint_index(n).is_some())
                    .map(|(n, p)| (n.as_str(), *p))
                    .collect();
                q = Some(model.values_from(pairs)?);
            }
            for s in humans.drain() {
                let (Some(q), Some(pid)) = (&q, s.msg.partner_id) else {
                    continue;
                };
                let Some(t) = s.msg.tracks.iter().find(|t| t.track_id == pid) else {
                    continue;
                };
                let j: Vec<Vector3<f64>> =
                    t.pose.joints.iter().map(|p| Vector3::from(*p)).collect();
                reach = reach.min(gripper_reach(&model, &body, q, &Isometry3::identity(), &j)?);
                let head = echo_motion::sensors::body_capsules(&j)
                    .into_iter()
                    .find(|(p, _)| *p == echo_motion::sensors::BodyPart::Head);
                if let Some((_, hc)) = head {
                    for (_, c) in body.at(&model, q) {
                        head_m = head_m.min(c.distance(&hc));
                    }
                }
                frames += 1;
            }
            for c in commands.drain() {
                for tr in &c.msg.trajectories {
                    for p in &tr.points {
                        points += 1;
                        for (k, n) in tr.joint_names.iter().enumerate() {
                            let Some(l) = model.limits(n) else {
                                violations.push(format!("unknown joint {n}"));
                                continue;
                            };
                            let (x, v) = (p.positions[k], p.velocities[k]);
                            if x < l.lower - 1e-9 || x > l.upper + 1e-9 {
                                violations.push(format!("{n} at {x:.4} outside its limits"));
                            }
                            if v.abs() > l.velocity * (1.0 + 1e-6) {
                                violations.push(format!("{n} at {v:.4}/s over its limit"));
                            }
                        }
                    }
                }
            }
            for s in safety.drain() {
                accepted = accepted.max(s.msg.counters.get("plan/accepted").copied().unwrap_or(0));
                estopped |= s.msg.state == SafetyState::EStopped;
            }
        }
    }
    eprintln!(
        "handshake: grasping frame within {:.3} m of the partner's wrist, gripper–hand surfaces \
         {:.3} m (reference alone {:.3} m, {:.3} m); closest robot part to the partner's head \
         {head_m:.3} m; {frames} partner frames, {accepted} plans accepted, {points} command \
         points checked",
        reach.grasp_to_wrist_m, reach.surface_m, reference.grasp_to_wrist_m, reference.surface_m
    );
    // 15 Hz perception over the clip; the forecaster plans at the same rate.
    let expected = (clip_s * 15.0) as usize;
    assert!(
        frames > expected * 3 / 4,
        "only {frames} of {expected} partner frames"
    );
    assert!(
        accepted as usize > expected / 2,
        "safety accepted only {accepted} plans"
    );
    assert!(
        reach.grasp_to_wrist_m < reference.grasp_to_wrist_m
            && reach.surface_m < reference.surface_m,
        "the robot's gripper reached {reach:?}, the reference alone {reference:?}"
    );
    assert!(
        violations.is_empty(),
        "{} limit violations, first: {:?}",
        violations.len(),
        violations.first()
    );
    assert!(points > 50 * expected, "only {points} command points");
    assert!(
        head_m >= 0.15,
        "a robot part came within {head_m:.3} m of the head"
    );
    assert!(!estopped);
    Ok(())
}
