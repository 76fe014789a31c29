//! The examples against a real pipeline on loopback (mock robot, perception bridge, forecaster,
//! safety — each its own process and Zenoh session): keypoints published by
//! `publish_keypoints` come back as forecasts that `subscribe_forecasts` prints, `send_estop`
//! latches the safety service's e-stop, and `read_recording` reads what was recorded.

use std::time::Duration;

use echo_bus::{keys, topics};
use echo_msgs::{encode, SafetyState};
use echo_system_tests::Harness;

const ROBOT: &str = "sys-examples";

/// Wait for a one-shot program to end; its exit status and log.
async fn finished(h: &mut Harness, label: &str, within: Duration) -> (bool, String) {
    let deadline = tokio::time::Instant::now() + within;
    while tokio::time::Instant::now() < deadline {
        if let Some(status) = h.exit_status(label) {
            return (status.success(), h.log_tail(label));
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    (
        false,
        format!("still running after {within:?}\n{}", h.log_tail(label)),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn examples_drive_a_live_pipeline_and_read_its_recording() -> anyhow::Result<()> {
    let mut h = Harness::new(ROBOT, 7)?;
    h.spawn("mock-robot", "echoctl", &["mock-robot"])?;
    h.spawn("perception-bridge", "perception-bridge", &[])?;
    h.spawn("forecaster", "forecaster", &[])?;
    h.spawn("safety", "safety", &[])?;
    let bus = h.bus("system-test").await?;
    let robot = bus.robot().clone();
    let forecasts = bus.subscribe(&topics::forecast(&robot)).await?;
    let status = bus.subscribe(&topics::safety_status(&robot)).await?;
    h.wait_alive(
        &bus,
        &["mock-robot", "perception-bridge", "forecaster", "safety"],
        Duration::from_secs(60),
    )
    .await?;

    // Your pose estimator → the bridge → the forecaster → your subscriber.
    h.spawn(
        "publish_keypoints",
        "examples/publish_keypoints",
        &["--seconds", "25"],
    )?;
    h.spawn(
        "subscribe_forecasts",
        "examples/subscribe_forecasts",
        &["--count", "5", "--timeout-s", "20"],
    )?;
    let (ok, log) = finished(&mut h, "subscribe_forecasts", Duration::from_secs(40)).await;
    assert!(ok, "subscribe_forecasts failed:\n{log}");
    let printed = log.lines().filter(|l| l.starts_with("forecast ")).count();
    assert_eq!(printed, 5, "{log}");
    assert!(log.contains("in 1 s at Some(["), "{log}");

    // Record a few of the forecasts this session saw, for read_recording.
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("recording.mcap");
    let mut rec =
        echo_record::Recorder::new(std::io::BufWriter::new(std::fs::File::create(&path)?))?;
    let mut recorded = 0;
    while recorded < 3 {
        let Ok(Some(f)) = tokio::time::timeout(Duration::from_secs(10), forecasts.recv()).await
        else {
            anyhow::bail!("no forecasts reached the test's own session");
        };
        rec.write(
            &keys::forecast(&robot),
            f.msg.header.stamp_ns,
            &encode(&f.msg),
        )?;
        recorded += 1;
    }
    rec.finish()?;

    // The e-stop latches.
    h.spawn(
        "send_estop",
        "examples/send_estop",
        &["--reason", "example"],
    )?;
    let (ok, log) = finished(&mut h, "send_estop", Duration::from_secs(20)).await;
    assert!(ok, "send_estop failed:\n{log}");
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    let mut stopped = false;
    while !stopped && tokio::time::Instant::now() < deadline {
        if let Ok(Some(s)) = tokio::time::timeout(Duration::from_secs(1), status.recv()).await {
            stopped = s.msg.state == SafetyState::EStopped
                && s.msg.reasons.iter().any(|r| r.contains("example"));
        }
    }
    assert!(stopped, "the safety service never reported the e-stop");

    h.spawn_raw(
        "read_recording",
        "examples/read_recording",
        &[path.to_str().unwrap_or_default()],
    )?;
    let (ok, log) = finished(&mut h, "read_recording", Duration::from_secs(20)).await;
    assert!(ok, "read_recording failed:\n{log}");
    assert!(log.contains("3 messages on 1 keys"), "{log}");
    assert!(log.contains("predicted frames at 15 Hz"), "{log}");
    Ok(())
}
