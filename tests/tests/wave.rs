//! The wave scenario end to end, as separate processes over Zenoh on loopback: mock perception
//! plays the partner of `echo_sim::mission` "wave" (person A of a test-split wave) → perception
//! bridge → HRI forecaster (the shipped `models/hri`, plans given a visible wave by
//! `echo_forecast::gesture`) → safety → simulated robot. The robot must wave back
//! recognisably — a gripper above its shoulder swinging sideways at least two full times
//! (`echo_eval::behaviour::wave`) — with every command inside the joint limits and no e-stop.
//! `ECHO_WAVE_DEBUG=1` prints the safety states, the plans' and the commands' left gripper
//! positions, and the waving hand's trace.

use std::time::Duration;

use echo_eval::behaviour::wave;
use echo_msgs::{now_ns, SafetyState};
use echo_robot::{RobotModel, GRASPING_FRAMES, SHOULDER_LINKS};
use echo_sim::mission::Mission;
use echo_system_tests::{announce, check_command_limits, start_hri_pipeline, HriTaps};

/// Time (s, the mission's clock), gripper and shoulder positions (base frame).
type HandSample = (f64, [f64; 3], [f64; 3]);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_robot_waves_back_recognisably_within_its_limits() -> anyhow::Result<()> {
    let model = RobotModel::tiago_dual();
    let mission = Mission::load("wave", &echo_system_tests::repo().join("deploy"))?;
    let seg = mission.segments[0].clone();
    assert_eq!(format!("{:?}", seg.interaction), "Wave");

    let (
        mut h,
        bus,
        HriTaps {
            prompt,
            states,
            humans,
            commands,
            safety,
            forecasts,
        },
    ) = start_hri_pipeline("sys-wave").await?;
    let robot = bus.robot().clone();
    let debug = std::env::var_os("ECHO_WAVE_DEBUG").is_some();
    // As in the demo: the partner stands for a lead-in (the forecaster's history fills, the
    // interaction is announced), then plays the scenario once.
    let lead_in_s = 4.0;
    let t0 = now_ns() + (lead_in_s * 1e9) as u64;
    h.spawn(
        "mock-perception",
        "echoctl",
        &[
            "mock-perception",
            "--scenario",
            "wave",
            "--t0-ns",
            &t0.to_string(),
        ],
    )?;

    // (t, gripper, shoulder) of each arm at every joint state, on the mission's clock.
    let mut arms: [Vec<HandSample>; 2] = [vec![], vec![]];
    let (mut frames, mut points, mut violations) = (0usize, 0usize, vec![]);
    let (mut accepted, mut estopped) = (0u64, false);
    let deadline =
        tokio::time::Instant::now() + Duration::from_secs_f64(lead_in_s + 1.5 + mission.duration());
    while tokio::time::Instant::now() < deadline {
        announce(&prompt, robot.as_str(), &seg).await?;
        for _ in 0..10 {
            tokio::time::sleep(Duration::from_millis(25)).await;
            for s in states.drain() {
                let q = model.known_values(
                    s.msg
                        .name
                        .iter()
                        .map(String::as_str)
                        .zip(s.msg.position.iter().copied()),
                );
                let t = (s.msg.header.stamp_ns as f64 - t0 as f64) / 1e9;
                if !(seg.start_s..=seg.end_s).contains(&t) {
                    continue;
                }
                for (a, arm) in arms.iter_mut().enumerate() {
                    let at = |f: &str| -> anyhow::Result<[f64; 3]> {
                        Ok(model.fk(&q, f)?.translation.vector.into())
                    };
                    arm.push((t, at(GRASPING_FRAMES[a])?, at(SHOULDER_LINKS[a])?));
                }
            }
            frames += humans.drain().len();
            for f in forecasts.drain() {
                let Some(plan) = f.msg.robot.as_ref().filter(|_| debug) else {
                    continue;
                };
                let t = (f.msg.header.stamp_ns as f64 - t0 as f64) / 1e9;
                let ys: Vec<String> = plan
                    .points
                    .iter()
                    .step_by(4)
                    .filter_map(|p| {
                        let q = model
                            .values_from(
                                plan.joint_names
                                    .iter()
                                    .map(|n| n.as_str())
                                    .zip(p.positions.iter().copied()),
                            )
                            .ok()?;
                        let g = model.fk(&q, GRASPING_FRAMES[0]).ok()?.translation.vector;
                        Some(format!("{:+.2}", g.y))
                    })
                    .collect();
                eprintln!("plan {t:.2}: left gripper y every 0.27 s {}", ys.join(" "));
            }
            for c in commands.drain() {
                if debug {
                    let mut names = vec![];
                    let mut pos = vec![];
                    for tr in &c.msg.trajectories {
                        if let Some(p) = tr.points.first() {
                            names.extend(tr.joint_names.iter().map(|n| n.as_str()));
                            pos.extend(p.positions.iter().copied());
                        }
                    }
                    if let Ok(q) = model.values_from(names.into_iter().zip(pos)) {
                        if let Ok(g) = model.fk(&q, GRASPING_FRAMES[0]) {
                            let t = (c.msg.header.stamp_ns as f64 - t0 as f64) / 1e9;
                            eprintln!(
                                "command {t:.2}: left gripper y {:+.2}",
                                g.translation.vector.y
                            );
                        }
                    }
                }
                points += check_command_limits(&model, &c.msg, &mut violations);
            }
            for s in safety.drain() {
                if debug {
                    eprintln!(
                        "safety {:?} scale {:.2} sep {:?} {:?}",
                        s.msg.state, s.msg.speed_scale, s.msg.min_separation_m, s.msg.reasons
                    );
                }
                accepted = accepted.max(s.msg.counters.get("plan/accepted").copied().unwrap_or(0));
                estopped |= s.msg.state == SafetyState::EStopped;
            }
        }
    }
    let waves = arms.each_ref().map(|a| wave(a));
    let best = if waves[0].oscillations >= waves[1].oscillations {
        &waves[0]
    } else {
        &waves[1]
    };
    eprintln!(
        "wave back: left {:?}; right {:?}; {frames} people frames, {accepted} plans accepted, \
         {points} command points checked",
        waves[0], waves[1]
    );
    // The waving hand's height above the shoulder and sideways position, every 0.25 s.
    let arm = usize::from(waves[1].oscillations > waves[0].oscillations);
    let trace: Vec<String> = arms[arm]
        .iter()
        .step_by(25)
        .map(|(t, g, s)| format!("{t:.2}:{:+.2}/{:+.2}", g[2] - s[2], g[1]))
        .collect();
    eprintln!("arm {arm} (t: above shoulder / y): {}", trace.join(" "));
    let expected = (mission.duration() * 15.0) as usize;
    assert!(
        frames > expected * 3 / 4,
        "only {frames} of {expected} frames"
    );
    assert!(
        accepted as usize > expected / 2,
        "safety accepted only {accepted} plans"
    );
    assert!(best.recognisable(), "no recognisable wave back: {best:?}");
    assert!(
        violations.is_empty(),
        "{} limit violations, first: {:?}",
        violations.len(),
        violations.first()
    );
    assert!(points > 50 * expected, "only {points} command points");
    assert!(!estopped);
    Ok(())
}
