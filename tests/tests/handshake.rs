//! The handshake scenario end to end, as separate processes over Zenoh on loopback: mock
//! perception plays the partner of `echo_sim::mission` "handshake" (person A of a test-split
//! handshake, who holds the hand out; the robot stands where person B stood) → perception bridge
//! → HRI forecaster (the shipped `models/hri`, plans refined to reach an offered hand) → safety
//! → simulated robot. The robot's gripper must reach the partner's hand — surfaces touching
//! (`S_0`) and within 1 cm for at least 0.5 s — through the safety service's contact mode, with
//! every command inside the joint limits, no robot part inside half the head clearance or half
//! the body clearance of the regions a handshake does not touch, and no e-stop.

use std::time::Duration;

use echo_eval::behaviour::{contact, CONTACT_HOLD_S};
use echo_motion::sensors::{body_capsules, BodyPart};
use echo_msgs::{now_ns, SafetyState};
use echo_retarget::hri::gripper_reach;
use echo_robot::collision::RobotBody;
use echo_robot::RobotModel;
use echo_safety::config::SeparationConfig;
use echo_sim::mission::Mission;
use echo_system_tests::{announce, check_command_limits, start_hri_pipeline, HriTaps};
use nalgebra::{Isometry3, Vector3};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_robot_shakes_the_offered_hand_within_its_limits_and_clearances() -> anyhow::Result<()>
{
    let model = RobotModel::tiago_dual();
    let body = RobotBody::tiago(&model)?;
    let mission = Mission::load("handshake", &echo_system_tests::repo().join("deploy"))?;
    let seg = mission.segments[0].clone();
    assert_eq!(format!("{:?}", seg.interaction), "Handshake");
    let clearances = SeparationConfig::default();

    let (
        mut h,
        bus,
        HriTaps {
            prompt,
            states,
            humans,
            commands,
            safety,
            forecasts: _,
        },
    ) = start_hri_pipeline("sys-handshake").await?;
    let robot = bus.robot().clone();
    // The partner starts once everything listens, and plays the scenario once.
    let t0 = now_ns() + 1_000_000_000;
    h.spawn(
        "mock-perception",
        "echoctl",
        &[
            "mock-perception",
            "--scenario",
            "handshake",
            "--t0-ns",
            &t0.to_string(),
        ],
    )?;

    let mut q = None;
    let mut surface: Vec<(f64, f64)> = vec![];
    let (mut head_m, mut body_m, mut frames) = (f64::INFINITY, f64::INFINITY, 0usize);
    let (mut points, mut violations, mut accepted, mut estopped) = (0usize, vec![], 0u64, false);
    let deadline = tokio::time::Instant::now() + Duration::from_secs_f64(1.5 + mission.duration());
    while tokio::time::Instant::now() < deadline {
        announce(&prompt, robot.as_str(), &seg).await?;
        for _ in 0..10 {
            tokio::time::sleep(Duration::from_millis(25)).await;
            for s in states.drain() {
                q = Some(
                    model.known_values(
                        s.msg
                            .name
                            .iter()
                            .map(String::as_str)
                            .zip(s.msg.position.iter().copied()),
                    ),
                );
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
                let time = (s.msg.header.stamp_ns as f64 - t0 as f64) / 1e9;
                let reach = gripper_reach(&model, &body, q, &Isometry3::identity(), &j)?;
                surface.push((time, reach.surface_m));
                let robot_caps = body.at(&model, q);
                for (part, hc) in body_capsules(&j) {
                    let d = robot_caps
                        .iter()
                        .map(|(_, c)| c.distance(&hc))
                        .fold(f64::INFINITY, f64::min);
                    match part {
                        BodyPart::Head => head_m = head_m.min(d),
                        BodyPart::Hand(_) | BodyPart::Forearm(_) => {}
                        _ => body_m = body_m.min(d),
                    }
                }
                frames += 1;
            }
            for c in commands.drain() {
                points += check_command_limits(&model, &c.msg, &mut violations);
            }
            for s in safety.drain() {
                accepted = accepted.max(s.msg.counters.get("plan/accepted").copied().unwrap_or(0));
                estopped |= s.msg.state == SafetyState::EStopped;
            }
        }
    }
    let made = contact(&surface, seg.start_s);
    eprintln!(
        "handshake: {made:?}; closest robot part to the partner's head {head_m:.3} m, to the \
         regions a handshake does not touch {body_m:.3} m; {frames} partner frames, {accepted} \
         plans accepted, {points} command points checked"
    );
    let expected = (mission.duration() * 15.0) as usize;
    assert!(
        frames > expected * 3 / 4,
        "only {frames} of {expected} partner frames"
    );
    assert!(
        accepted as usize > expected / 2,
        "safety accepted only {accepted} plans"
    );
    assert!(
        made.made && made.held_s >= CONTACT_HOLD_S,
        "no handshake: {made:?}"
    );
    assert!(
        violations.is_empty(),
        "{} limit violations, first: {:?}",
        violations.len(),
        violations.first()
    );
    assert!(points > 50 * expected, "only {points} command points");
    assert!(
        head_m >= clearances.head_clearance_m / 2.0,
        "a robot part came within {head_m:.3} m of the head"
    );
    assert!(
        body_m >= clearances.body_clearance_m / 2.0,
        "a robot part came within {body_m:.3} m of the partner's body"
    );
    assert!(!estopped);
    Ok(())
}
