//! Imitation mode end to end, as separate processes over Zenoh on loopback: mock perception
//! replays an imitation game → perception bridge → retargeter → safety → simulated robot. With
//! the prompt in imitation mode the safety service accepts the retargeter's plans and the
//! robot's arms move; the batch queryable answers over the network.

use std::time::Duration;

use echo_bus::{keys, topics};
use echo_msgs::{now_ns, ControlMode, Header, Interaction, InteractionIntent, SafetyState};
use echo_system_tests::Harness;

/// One reply of the retargeter's batch queryable.
async fn query(
    bus: &echo_bus::Bus,
    robot: &echo_bus::RobotId,
    payload: String,
) -> anyhow::Result<zenoh::query::Reply> {
    let replies = bus
        .session()
        .get(keys::retarget_batch(robot))
        .payload(payload)
        .timeout(Duration::from_secs(5))
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    replies
        .recv_async()
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_robot_imitates_the_partner_through_the_safety_filter() -> anyhow::Result<()> {
    let mut h = Harness::new("sys-imitation", 5)?;
    h.spawn_services(
        "single",
        &["mock-robot", "perception-bridge", "retargeter", "safety"],
    )?;
    let t0 = now_ns() + 2_000_000_000;
    h.spawn(
        "mock-perception",
        "echoctl",
        &[
            "mock-perception",
            "--clip",
            "test:9",
            "--t0-ns",
            &t0.to_string(),
        ],
    )?;
    let bus = h.bus("system-test").await?;
    let robot = bus.robot().clone();
    let prompt = bus.publisher(&topics::prompt(&robot)).await?;
    let plans = bus.subscribe(&topics::retarget(&robot)).await?;
    let states = bus.subscribe(&topics::robot_state(&robot)).await?;
    let safety = bus.subscribe(&topics::safety_status(&robot)).await?;
    h.wait_alive(
        &bus,
        &[
            "mock-robot",
            "perception-bridge",
            "retargeter",
            "safety",
            "mock-perception",
        ],
        Duration::from_secs(60),
    )
    .await?;

    let arm: Vec<String> = ["left", "right"]
        .iter()
        .flat_map(|s| (1..=7).map(move |i| format!("arm_{s}_{i}_joint")))
        .collect();
    let (mut first, mut moved, mut plan_n, mut accepted, mut estopped) =
        (None, 0f64, 0, 0u64, false);
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    while tokio::time::Instant::now() < deadline {
        prompt
            .put(InteractionIntent {
                header: Header::new(robot.as_str(), "", ""),
                text: "One person copies the other's arm movements like a mirror.".into(),
                interaction: Interaction::Imitation,
                mode: ControlMode::Imitation,
            })
            .await?;
        tokio::time::sleep(Duration::from_millis(250)).await;
        plan_n += plans.drain().len();
        for s in states.drain() {
            let q: Vec<f64> = arm
                .iter()
                .map(|n| s.msg.position_of(n).unwrap_or(0.0))
                .collect();
            let f = first.get_or_insert_with(|| q.clone());
            for (a, b) in q.iter().zip(f.iter()) {
                moved = moved.max((a - b).abs());
            }
        }
        for s in safety.drain() {
            accepted = accepted.max(s.msg.counters.get("plan/accepted").copied().unwrap_or(0));
            estopped |= s.msg.state == SafetyState::EStopped;
        }
    }
    eprintln!(
        "{plan_n} imitation plans, {accepted} accepted by safety, arm moved up to {moved:.2} rad"
    );
    assert!(plan_n > 40, "only {plan_n} imitation plans in 10 s");
    assert!(accepted > 20, "safety accepted only {accepted} plans");
    assert!(moved > 0.2, "the arms moved only {moved} rad");
    assert!(!estopped);

    // The batch queryable over the network.
    let clip = echo_motion::synth::generate(&echo_motion::synth::Split::Test.clip(0));
    let pose: Vec<[f64; 3]> = clip.joints(3, 0).iter().map(|p| [p.x, p.y, p.z]).collect();
    let req = serde_json::json!({ "poses": [pose] }).to_string();
    let reply = query(&bus, &robot, req).await?;
    let sample = reply
        .result()
        .map_err(|e| anyhow::anyhow!("error reply: {e:?}"))?;
    let v: serde_json::Value = serde_json::from_slice(&sample.payload().to_bytes())?;
    assert_eq!(v["poses"][0].as_array().map(|a| a.len()), Some(17));
    // A malformed request gets an error reply, and the service keeps running.
    let reply = query(&bus, &robot, "{\"poses\": 3}".into()).await?;
    assert!(reply.result().is_err());
    assert!(h.is_running("retargeter"));
    Ok(())
}
