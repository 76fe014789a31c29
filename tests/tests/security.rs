//! Mutual TLS and access control through `echoctl router` with deploy/zenoh/router-secure.json5:
//! a host whose certificate is not from Echo's CA cannot connect, nor can a plain-TCP one; a host
//! with a valid certificate but the wrong identity cannot publish robot commands, and the router
//! logs the attempt; the safety identity can.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use echo_bus::testkit::free_port;
use echo_bus::{keys, Bus, BusArgs, RobotId};
use echo_system_tests::Harness;

const ROBOT: &str = "sys-sec";

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn make_certs(dir: &Path, names: &[&str]) -> anyhow::Result<()> {
    let out = Command::new(repo().join("deploy/tls/make-certs"))
        .arg(dir)
        .args(names)
        .output()?;
    anyhow::ensure!(
        out.status.success(),
        "make-certs: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    Ok(())
}

fn client(port: u16, dir: &Path, name: &str, tls: bool) -> BusArgs {
    BusArgs {
        robot: ROBOT.into(),
        mode: Some("client".into()),
        connect: vec![format!(
            "{}/127.0.0.1:{port}",
            if tls { "tls" } else { "tcp" }
        )],
        no_multicast_scouting: true,
        tls_dir: tls.then(|| dir.to_path_buf()),
        tls_name: Some(name.into()),
        ..Default::default()
    }
}

/// Publish raw bytes on `key`.
async fn put(bus: &Bus, key: &str, payload: impl Into<Vec<u8>>) -> anyhow::Result<()> {
    bus.session()
        .put(key, payload.into())
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))
}

/// Count the samples arriving on `key` at `bus` (the subscriber lives as long as the guard).
async fn counter(
    bus: &Bus,
    key: &str,
) -> anyhow::Result<(Arc<AtomicU64>, zenoh::pubsub::Subscriber<()>)> {
    let n = Arc::new(AtomicU64::new(0));
    let c = n.clone();
    let sub = bus
        .session()
        .declare_subscriber(key.to_string())
        .callback(move |_| {
            c.fetch_add(1, Ordering::Relaxed);
        })
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok((n, sub))
}

/// Open a client, retrying while the router starts.
async fn connect(args: &BusArgs, service: &str) -> anyhow::Result<Bus> {
    let mut last = None;
    for _ in 0..40 {
        match Bus::open(args, service).await {
            Ok(b) => return Ok(b),
            Err(e) => last = Some(e),
        }
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
    Err(last.unwrap())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn only_certified_identities_connect_and_only_safety_commands() -> anyhow::Result<()> {
    if Command::new("openssl").arg("version").output().is_err() {
        eprintln!("skipping: openssl is not installed");
        return Ok(());
    }
    let scratch = tempfile::tempdir()?;
    let tmp = scratch.path().to_path_buf();
    let (good, rogue) = (tmp.join("good"), tmp.join("rogue"));
    make_certs(
        &good,
        &[
            "router",
            "safety",
            "forecaster",
            "robot-interface",
            "intruder",
        ],
    )?;
    // Same common name, different (untrusted) authority.
    make_certs(&rogue, &["safety"])?;

    let mut h = Harness::new(ROBOT, 0)?;
    let port = free_port();
    let cfg = repo().join("deploy/zenoh/router-secure.json5");
    h.spawn_raw(
        "router",
        "echoctl",
        &[
            "router",
            "--zenoh-config",
            cfg.to_str().unwrap(),
            "--listen",
            &format!("tls/127.0.0.1:{port}"),
            "--tls-dir",
            good.to_str().unwrap(),
        ],
    )?;

    let robot_if = connect(&client(port, &good, "robot-interface", true), "mock-robot").await?;
    let robot = RobotId::new(ROBOT)?;
    let (received, _sub) = counter(&robot_if, &keys::command(&robot)).await?;

    // A certificate from another authority, and plain TCP, are refused at connection.
    let e = Bus::open(&client(port, &rogue, "safety", true), "safety").await;
    assert!(e.is_err(), "a rogue certificate connected");
    let e = Bus::open(&client(port, &good, "safety", false), "safety").await;
    assert!(e.is_err(), "a plain TCP client connected to the TLS router");

    // The forecaster identity is authenticated but may not command the robot.
    let forecaster = connect(&client(port, &good, "forecaster", true), "forecaster").await?;
    let intruder = connect(&client(port, &good, "intruder", true), "intruder").await?;
    tokio::time::sleep(Duration::from_millis(500)).await;
    for _ in 0..20 {
        for b in [&forecaster, &intruder] {
            put(b, &keys::command(&robot), "move!").await?;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    // Its own stream still flows (it is not simply disconnected).
    let (forecasts, _fsub) = counter(&robot_if, &keys::forecast(&robot)).await?;
    let safety = connect(&client(port, &good, "safety", true), "safety").await?;
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    while (received.load(Ordering::Relaxed) == 0 || forecasts.load(Ordering::Relaxed) == 0)
        && tokio::time::Instant::now() < deadline
    {
        put(&safety, &keys::command(&robot), "{}").await?;
        put(&forecaster, &keys::forecast(&robot), "{}").await?;
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let before = received.load(Ordering::Relaxed);
    assert!(
        before >= 1,
        "the safety identity could not command the robot"
    );
    assert!(
        forecasts.load(Ordering::Relaxed) >= 1,
        "forecasts did not flow"
    );
    // Every command that arrived came from safety: more forecaster puts add nothing.
    for _ in 0..10 {
        put(&forecaster, &keys::command(&robot), "move!").await?;
    }
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert_eq!(received.load(Ordering::Relaxed), before);

    // The ROS 2 side (zenoh-bridge-ros2dds keys): the controllers take trajectories from the
    // safety identity only.
    let traj = format!("{ROBOT}/arm_left_controller/joint_trajectory");
    let (trajectories, _tsub) = counter(&robot_if, &traj).await?;
    tokio::time::sleep(Duration::from_millis(300)).await;
    for _ in 0..10 {
        put(&forecaster, &traj, vec![0u8; 8]).await?;
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert_eq!(trajectories.load(Ordering::Relaxed), 0);
    let deadline = tokio::time::Instant::now() + Duration::from_secs(5);
    while trajectories.load(Ordering::Relaxed) == 0 && tokio::time::Instant::now() < deadline {
        put(&safety, &traj, vec![0u8; 8]).await?;
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(
        trajectories.load(Ordering::Relaxed) > 0,
        "safety could not send a trajectory"
    );

    let log = std::fs::read_to_string(h.log_dir().join("router.log"))?;
    assert!(
        log.lines().any(|l| l.contains("access denied")
            && l.contains("CertCommonName(forecaster)")
            && l.contains("Put (ingress) on echo/sys-sec/command")),
        "router log:\n{log}"
    );
    assert!(h.is_running("router"));
    Ok(())
}
