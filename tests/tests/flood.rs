//! A flood of malformed, hostile and oversized messages on every input key of every service,
//! as separate processes over Zenoh: the services keep running, their memory stays bounded,
//! every bad input is counted in their status, and the pipeline still works afterwards.

use std::time::Duration;

use echo_bus::stats::process_rss_mib;
use echo_bus::{keys, topics, RobotId};
use echo_msgs::{Header, JointState, ServiceStatus};
use echo_system_tests::Harness;

/// Resident memory growth allowed per service during the flood, MiB.
const RSS_GROWTH_BOUND_MIB: f64 = 64.0;

/// Payloads that must all be rejected.
fn hostile(robot: &str) -> Vec<Vec<u8>> {
    let mut v: Vec<Vec<u8>> = vec![
        b"{".to_vec(),
        b"not json".to_vec(),
        b"null".to_vec(),
        b"[1,2,3]".to_vec(),
        br#"{"header":{"schema":1}}"#.to_vec(),
        // Out-of-range numbers (no NaN in JSON: this is how an overflow arrives).
        br#"{"header":{"schema":1,"seq":1,"stamp_ns":1,"robot_id":"x","frame_id":"","source":"f"},"position":[1e999]}"#.to_vec(),
        // Nesting deeper than any parser's stack should follow.
        [vec![b'['; 100_000], vec![b']'; 100_000]].concat(),
        vec![0xff, 0xfe, 0x00, 0x01],
    ];
    // Well-formed but invalid: unknown joint, sizes that disagree, another robot's id.
    let js = |name: Vec<&str>, pos: Vec<f64>, robot_id: &str| {
        serde_json::to_vec(&JointState {
            header: Header::new(robot_id, "flood", "base_footprint"),
            name: name.into_iter().map(String::from).collect(),
            position: pos,
            velocity: vec![],
            base: None,
        })
        .unwrap()
    };
    v.push(js(vec!["warp_drive_joint"], vec![0.1], robot));
    v.push(js(
        vec!["torso_lift_joint", "head_1_joint"],
        vec![0.1],
        robot,
    ));
    v.push(js(vec!["torso_lift_joint"], vec![0.1], "someone-else"));
    v
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn services_survive_a_flood_of_bad_input() -> anyhow::Result<()> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let fc_model = root.join("models/forecaster");
    let mut h = Harness::new("sys-flood", 6)?;
    h.spawn_services("single", &["mock-robot", "perception-bridge", "safety"])?;
    h.spawn(
        "forecaster",
        "forecaster",
        &[
            "--model",
            fc_model.to_str().unwrap(),
            "--backend",
            "zero-velocity",
        ],
    )?;
    h.spawn_services("single", &["retargeter"])?;
    h.spawn("mock-perception", "echoctl", &["mock-perception"])?;
    let bus = h.bus("flooder").await?;
    let robot: RobotId = bus.robot().clone();
    let services = ["perception-bridge", "safety", "forecaster", "retargeter"];
    h.wait_alive(
        &bus,
        &[&services[..], &["mock-robot", "mock-perception"]].concat(),
        Duration::from_secs(60),
    )
    .await?;
    let status = bus.subscribe(&topics::service_status_all(&robot)).await?;
    let humans = bus.subscribe(&topics::humans(&robot)).await?;
    tokio::time::sleep(Duration::from_secs(2)).await;
    let before: Vec<(String, f64)> = services
        .iter()
        .map(|s| {
            (
                s.to_string(),
                process_rss_mib(h.pid(s).unwrap()).unwrap_or(0.0),
            )
        })
        .collect();

    let inputs = [
        keys::perception_raw(&robot),
        keys::humans(&robot),
        keys::robot_state(&robot),
        keys::prompt(&robot),
        keys::forecast(&robot),
        keys::retarget(&robot),
        keys::estop(&robot),
    ];
    let bad = hostile(robot.as_str());
    let oversized = vec![b' '; 4 << 20];
    let started = tokio::time::Instant::now();
    let mut sent = 0u64;
    let mut round = 0u64;
    while started.elapsed() < Duration::from_secs(8) {
        for k in &inputs {
            for p in &bad {
                bus.session()
                    .put(k.as_str(), p.clone())
                    .await
                    .map_err(|e| anyhow::anyhow!("{e}"))?;
                sent += 1;
            }
            if round.is_multiple_of(10) {
                bus.session()
                    .put(k.as_str(), oversized.clone())
                    .await
                    .map_err(|e| anyhow::anyhow!("{e}"))?;
                sent += 1;
            }
        }
        if round.is_multiple_of(20) {
            // Malformed batch queries to the retargeter's queryable.
            let replies = bus
                .session()
                .get(keys::retarget_batch(&robot))
                .payload("{\"poses\": \"no\"}")
                .timeout(Duration::from_secs(2))
                .await
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            let _ = replies.recv_async().await;
        }
        round += 1;
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    eprintln!("sent {sent} hostile messages in 8 s");
    tokio::time::sleep(Duration::from_secs(2)).await;

    // Everyone still runs, memory is bounded, and the rejections are counted.
    for (s, rss0) in &before {
        assert!(h.is_running(s), "{s} died:\n{}", h.log_tail(s));
        let rss1 = process_rss_mib(h.pid(s).unwrap()).unwrap_or(0.0);
        eprintln!("{s}: RSS {rss0:.0} → {rss1:.0} MiB");
        assert!(
            rss1 - rss0 < RSS_GROWTH_BOUND_MIB,
            "{s} grew {:.0} MiB",
            rss1 - rss0
        );
    }
    let mut last: std::collections::BTreeMap<String, ServiceStatus> = Default::default();
    let end = tokio::time::Instant::now() + Duration::from_secs(5);
    while tokio::time::Instant::now() < end && last.len() < services.len() + 2 {
        if let Ok(Some(m)) = tokio::time::timeout(Duration::from_millis(200), status.recv()).await {
            last.insert(m.msg.service.clone(), m.msg);
        }
    }
    for s in services {
        let st = last.get(s).unwrap_or_else(|| panic!("no status from {s}"));
        let rejected: u64 = st.rejected.values().sum();
        eprintln!("{s}: rejected {:?}", st.rejected);
        assert!(rejected > 100, "{s} counted only {rejected} rejections");
    }
    let bridge = &last["perception-bridge"].rejected;
    assert!(
        bridge.keys().any(|k| k.contains("too_large")),
        "oversized raw frames are counted as such: {bridge:?}"
    );

    // The pipeline still works: valid frames still become skeletons.
    humans.drain();
    let got = tokio::time::timeout(Duration::from_secs(5), humans.recv()).await;
    assert!(matches!(got, Ok(Some(_))), "no skeletons after the flood");
    Ok(())
}
