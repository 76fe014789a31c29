//! Primary and standby forecasters for one robot, as separate processes over Zenoh: only the
//! primary publishes; when it crashes (SIGKILL) the standby takes over; when a new primary
//! starts, the standby steps back; a second instance on a taken rank refuses to start.

use std::time::Duration;

use echo_bus::topics;
use echo_system_tests::Harness;

/// Every forecast received during `d` (read continuously: the inbox keeps only the newest few).
async fn collect(
    inbox: &echo_bus::Inbox<echo_msgs::Forecast>,
    d: Duration,
) -> Vec<echo_msgs::Forecast> {
    let end = tokio::time::Instant::now() + d;
    let mut out = vec![];
    while let Ok(Some(m)) = tokio::time::timeout_at(end, inbox.recv()).await {
        out.push(m.msg);
    }
    out
}

/// Start a forecaster of `rank` (the zero-velocity backend: failover does not depend on the model).
fn spawn_forecaster(h: &mut Harness, label: &str, rank: &str) -> anyhow::Result<()> {
    let model = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/forecaster");
    let model = model.to_str().unwrap_or_default();
    h.spawn(
        label,
        "forecaster",
        &[
            "--model",
            model,
            "--backend",
            "zero-velocity",
            "--rank",
            rank,
        ],
    )
}

/// Source prefix of the forecasts published by the process `pid`.
fn from_pid(source: &str, pid: u32) -> bool {
    source.starts_with(&format!("forecaster-{pid}-"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn standby_takes_over_when_the_primary_dies() -> anyhow::Result<()> {
    let mut h = Harness::new("sys-failover", 7)?;
    h.spawn_services("single", &["mock-robot", "perception-bridge"])?;
    h.spawn(
        "mock-perception",
        "echoctl",
        &["mock-perception", "--clip", "test:7"],
    )?;
    spawn_forecaster(&mut h, "primary", "0")?;
    let bus = h.bus("system-test").await?;
    let robot = bus.robot().clone();
    let forecasts = bus.subscribe(&topics::forecast(&robot)).await?;
    h.wait_alive(
        &bus,
        &["forecaster-r0", "forecaster"],
        Duration::from_secs(60),
    )
    .await?;
    spawn_forecaster(&mut h, "standby", "1")?;
    h.wait_alive(
        &bus,
        &["forecaster-r1", "mock-perception", "perception-bridge"],
        Duration::from_secs(60),
    )
    .await?;
    let (p0, p1) = (h.pid("primary").unwrap(), h.pid("standby").unwrap());

    // Both run; only the primary publishes.
    tokio::time::timeout(Duration::from_secs(30), forecasts.recv())
        .await?
        .expect("a first forecast");
    tokio::time::sleep(Duration::from_secs(1)).await;
    forecasts.drain();
    let seen = collect(&forecasts, Duration::from_secs(3)).await;
    assert!(seen.len() >= 20, "{} forecasts in 3 s", seen.len());
    assert!(
        seen.iter().all(|f| from_pid(&f.header.source, p0)),
        "a forecast not from the primary: {:?}",
        seen.iter()
            .find(|f| !from_pid(&f.header.source, p0))
            .map(|f| &f.header.source)
    );

    // A duplicate rank refuses to start.
    spawn_forecaster(&mut h, "duplicate", "1")?;

    // The primary crashes: the standby publishes soon after.
    let killed = tokio::time::Instant::now();
    h.kill("primary");
    let took_over = loop {
        if let Ok(Some(f)) =
            tokio::time::timeout(Duration::from_millis(100), forecasts.recv()).await
        {
            if from_pid(&f.msg.header.source, p1) {
                break Some(killed.elapsed());
            }
        }
        if killed.elapsed() > Duration::from_secs(10) {
            break None;
        }
    };
    let took_over = took_over.expect("the standby never published");
    eprintln!(
        "standby took over {:.0} ms after the primary died",
        took_over.as_secs_f64() * 1e3
    );
    assert!(
        took_over < Duration::from_secs(3),
        "takeover took {took_over:?}"
    );

    // A new primary starts: the standby steps back.
    spawn_forecaster(&mut h, "primary-2", "0")?;
    let p2 = h.pid("primary-2").unwrap();
    let deadline = tokio::time::Instant::now() + Duration::from_secs(60);
    loop {
        let f = tokio::time::timeout(Duration::from_secs(1), forecasts.recv()).await;
        if let Ok(Some(f)) = f {
            if from_pid(&f.msg.header.source, p2) {
                break;
            }
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "the new primary never published"
        );
    }
    tokio::time::sleep(Duration::from_secs(1)).await;
    forecasts.drain();
    let seen = collect(&forecasts, Duration::from_secs(2)).await;
    assert!(!seen.is_empty());
    assert!(
        seen.iter().all(|f| from_pid(&f.header.source, p2)),
        "the standby kept publishing next to the new primary"
    );

    let status = h
        .exit_status("duplicate")
        .expect("the duplicate rank is still running");
    assert!(!status.success());
    let log = std::fs::read_to_string(h.log_dir().join("duplicate.log"))?;
    assert!(log.contains("already has a forecaster of rank 1"), "{log}");
    assert!(h.is_running("standby"));
    Ok(())
}
