//! Mutual TLS and access control through `echoctl router` with deploy/zenoh/router-secure.json5:
//! a host whose certificate is not from Echo's CA cannot connect, nor can a plain-TCP one; a host
//! with a valid certificate but the wrong identity cannot publish robot commands, nor another
//! service's status or liveliness token, and the router logs the attempt under the identity's
//! name; the identities that own those keys can; the head camera's images reach the pose
//! estimator from the robot interface only.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
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

/// Record `(key, payload)` of every sample arriving on `key` at `bus` (the subscriber lives as
/// long as the guard).
type Received = Arc<Mutex<Vec<(String, String)>>>;
async fn recorder(
    bus: &Bus,
    key: &str,
) -> anyhow::Result<(Received, zenoh::pubsub::Subscriber<()>)> {
    let got: Received = Arc::default();
    let g = got.clone();
    let sub = bus
        .session()
        .declare_subscriber(key.to_string())
        .callback(move |s| {
            let payload = String::from_utf8_lossy(&s.payload().to_bytes()).into_owned();
            g.lock()
                .unwrap()
                .push((s.key_expr().as_str().to_string(), payload));
        })
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok((got, sub))
}

fn openssl_missing() -> bool {
    let missing = Command::new("openssl").arg("version").output().is_err();
    if missing {
        eprintln!("skipping: openssl is not installed");
    }
    missing
}

/// Start `echoctl router` with the secure configuration and the certificates in `certs`; returns
/// its TLS port.
fn secure_router(h: &mut Harness, certs: &Path) -> anyhow::Result<u16> {
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
            certs.to_str().unwrap(),
        ],
    )?;
    Ok(port)
}

/// Whether the router's log has an access denial naming `identity` and containing `what`.
fn denial_logged(log: &str, identity: &str, what: &str) -> bool {
    log.lines()
        .any(|l| l.contains(&format!("access denied: {identity} (zid ")) && l.contains(what))
}

/// Forge statuses as the forecaster and the operator: the safety service's through declared
/// publishers (`pubs`, as the services publish theirs), others' and the safety filter's by puts.
async fn forge(
    robot: &RobotId,
    forecaster: &Bus,
    operator: &Bus,
    pubs: &[(zenoh::pubsub::Publisher<'_>, &str)],
) -> anyhow::Result<()> {
    for (p, tag) in pubs {
        p.put(*tag).await.map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    let (f, o) = ("forged by forecaster", "forged by operator");
    put(forecaster, &keys::service_status(robot, "retargeter"), f).await?;
    put(forecaster, &keys::service_status_all(robot), f).await?;
    put(operator, &keys::service_status(robot, "forecaster"), o).await?;
    put(forecaster, &keys::safety_status(robot), f).await?;
    put(operator, &keys::safety_status(robot), o).await?;
    Ok(())
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
    if openssl_missing() {
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
    let port = secure_router(&mut h, &good)?;

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
        denial_logged(&log, "forecaster", "Put (ingress) on echo/sys-sec/command"),
        "router log:\n{log}"
    );
    assert!(h.is_running("router"));
    Ok(())
}

/// Every identity publishes its own service status and holds its own liveliness token; none can
/// forge another service's: not the forecaster (on the edge box) nor an operator's laptop.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn identities_publish_only_their_own_status_and_liveliness() -> anyhow::Result<()> {
    if openssl_missing() {
        return Ok(());
    }
    let scratch = tempfile::tempdir()?;
    let certs = scratch.path().join("certs");
    make_certs(
        &certs,
        &[
            "router",
            "safety",
            "forecaster",
            "operator",
            "robot-interface",
        ],
    )?;
    let mut h = Harness::new(ROBOT, 0)?;
    let port = secure_router(&mut h, &certs)?;
    let robot = RobotId::new(ROBOT)?;

    // The observer (any identity may subscribe and watch liveliness): the robot interface.
    let observer = connect(&client(port, &certs, "robot-interface", true), "mock-robot").await?;
    let (statuses, _ssub) = recorder(&observer, &keys::service_status_all(&robot)).await?;
    let (filter_status, _fsub) = recorder(&observer, &keys::safety_status(&robot)).await?;
    let alive = observer.watch_alive(&keys::alive_all(&robot)).await?;

    let forecaster = connect(&client(port, &certs, "forecaster", true), "forecaster").await?;
    let operator = connect(&client(port, &certs, "operator", true), "operator").await?;

    // Forged liveliness tokens first: a monitor would take them for the safety service (or
    // another one) running.
    let forged_alive: [(&Bus, &[&str]); 2] = [
        (&forecaster, &["safety", "retargeter"]),
        (&operator, &["safety", "perception-bridge", "operator"]),
    ];
    let mut forged_tokens = vec![];
    for (bus, services) in forged_alive {
        for s in services {
            forged_tokens.push(
                bus.session()
                    .liveliness()
                    .declare_token(keys::alive(&robot, s))
                    .await
                    .map_err(|e| anyhow::anyhow!("{e}"))?,
            );
        }
    }
    // The forecaster's own tokens (service and failover instance) do appear.
    let mut own_tokens = vec![];
    for s in ["forecaster", "forecaster-r0"] {
        own_tokens.push(
            forecaster
                .session()
                .liveliness()
                .declare_token(keys::alive(&robot, s))
                .await
                .map_err(|e| anyhow::anyhow!("{e}"))?,
        );
    }
    let missing = alive
        .wait_for(
            ROBOT,
            &["forecaster", "forecaster-r0"],
            Duration::from_secs(10),
        )
        .await;
    assert!(missing.is_empty(), "own tokens not seen: {missing:?}");
    tokio::time::sleep(Duration::from_millis(300)).await;
    let live_now = observer
        .alive_now(&keys::alive_all(&robot), Duration::from_secs(2))
        .await?;
    for forged in ["safety", "retargeter", "perception-bridge", "operator"] {
        assert!(
            !alive.is_alive(ROBOT, forged),
            "forged token alive/{forged} seen: {:?}",
            alive.snapshot()
        );
        assert!(
            !live_now.iter().any(|(_, s)| s == forged),
            "forged token alive/{forged} answered a liveliness query: {live_now:?}"
        );
    }

    // Forged statuses, through declared publishers as the services publish (and plain puts).
    let status_of = |s: &str| keys::service_status(&robot, s);
    let mut pubs = vec![];
    for (bus, tag) in [
        (&forecaster, "forged by forecaster"),
        (&operator, "forged by operator"),
    ] {
        let p = bus
            .session()
            .declare_publisher(status_of("safety"))
            .await
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        pubs.push((p, tag));
    }
    forge(&robot, &forecaster, &operator, &pubs).await?;

    // The owners' own statuses and tokens are delivered.
    let safety = connect(&client(port, &certs, "safety", true), "safety").await?;
    let _safety_token = safety.declare_alive().await?;
    let own = |got: &Received, key: &str, payload: &str| {
        got.lock()
            .unwrap()
            .iter()
            .any(|(k, p)| k == key && p == payload)
    };
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    while !(own(&statuses, &status_of("safety"), "from safety")
        && own(&statuses, &status_of("forecaster"), "from forecaster")
        && own(&filter_status, &keys::safety_status(&robot), "from safety"))
        && tokio::time::Instant::now() < deadline
    {
        put(&safety, &status_of("safety"), "from safety").await?;
        put(&safety, &keys::safety_status(&robot), "from safety").await?;
        put(&forecaster, &status_of("forecaster"), "from forecaster").await?;
        forge(&robot, &forecaster, &operator, &pubs).await?;
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(
        own(&statuses, &status_of("safety"), "from safety"),
        "the safety service's status did not arrive: {:?}",
        statuses.lock().unwrap()
    );
    assert!(
        own(&statuses, &status_of("forecaster"), "from forecaster"),
        "the forecaster's status did not arrive: {:?}",
        statuses.lock().unwrap()
    );
    assert!(
        own(&filter_status, &keys::safety_status(&robot), "from safety"),
        "the safety filter's status did not arrive"
    );
    let missing = alive
        .wait_for(ROBOT, &["safety"], Duration::from_secs(10))
        .await;
    assert!(missing.is_empty(), "the safety service's token not seen");
    tokio::time::sleep(Duration::from_millis(300)).await;
    for got in [&statuses, &filter_status] {
        let got = got.lock().unwrap();
        let forged: Vec<_> = got
            .iter()
            .filter(|(_, p)| p.starts_with("forged"))
            .collect();
        assert!(forged.is_empty(), "forged statuses delivered: {forged:?}");
    }

    let log = std::fs::read_to_string(h.log_dir().join("router.log"))?;
    for (identity, what) in [
        ("forecaster", "Put (ingress) on echo/sys-sec/status/safety"),
        ("operator", "Put (ingress) on echo/sys-sec/status/safety"),
        (
            "forecaster",
            "Put (ingress) on echo/sys-sec/status/retargeter",
        ),
        ("operator", "Put (ingress) on echo/sys-sec/safety/status"),
        (
            "forecaster",
            "Liveliness Token (ingress) on echo/sys-sec/alive/safety",
        ),
        (
            "operator",
            "Liveliness Token (ingress) on echo/sys-sec/alive/safety",
        ),
    ] {
        assert!(
            denial_logged(&log, identity, what),
            "no denial of {identity}: {what} in the router log:\n{log}"
        );
    }
    drop((forged_tokens, own_tokens));
    assert!(h.is_running("router"));
    Ok(())
}

/// The head camera through the router: zenoh-bridge-ros2dds (identity `robot-interface`)
/// publishes it, the pose estimator (identity `perception`) receives it and publishes its own
/// status; another identity can neither publish camera images nor the pose estimator's status.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_camera_reaches_the_pose_estimator_only_from_the_robot_interface() -> anyhow::Result<()>
{
    if openssl_missing() {
        return Ok(());
    }
    let scratch = tempfile::tempdir()?;
    let certs = scratch.path().join("certs");
    make_certs(
        &certs,
        &["router", "perception", "robot-interface", "forecaster"],
    )?;
    let mut h = Harness::new(ROBOT, 0)?;
    let port = secure_router(&mut h, &certs)?;
    let robot = RobotId::new(ROBOT)?;
    let image = format!("{ROBOT}{}", echo_ros2::image::HEAD_RGB_TOPIC);

    let estimator = connect(&client(port, &certs, "perception", true), "pose-estimator").await?;
    let (images, _isub) = recorder(&estimator, &image).await?;
    let ros_bridge = connect(&client(port, &certs, "robot-interface", true), "mock-robot").await?;
    let (statuses, _ssub) = recorder(&ros_bridge, &keys::service_status_all(&robot)).await?;
    let forecaster = connect(&client(port, &certs, "forecaster", true), "forecaster").await?;
    let status = keys::service_status(&robot, "pose-estimator");
    let arrived =
        |got: &Received, payload: &str| got.lock().unwrap().iter().any(|(_, p)| p == payload);
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    while !(arrived(&images, "from the camera") && arrived(&statuses, "from the pose estimator"))
        && tokio::time::Instant::now() < deadline
    {
        put(&ros_bridge, &image, "from the camera").await?;
        put(&estimator, &status, "from the pose estimator").await?;
        put(&forecaster, &image, "forged by forecaster").await?;
        put(&forecaster, &status, "forged by forecaster").await?;
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(
        arrived(&images, "from the camera"),
        "the camera did not reach the pose estimator"
    );
    assert!(
        arrived(&statuses, "from the pose estimator"),
        "the pose estimator's status did not arrive"
    );
    for got in [&images, &statuses] {
        assert!(
            !arrived(got, "forged by forecaster"),
            "forged samples delivered: {:?}",
            got.lock().unwrap()
        );
    }
    let log = std::fs::read_to_string(h.log_dir().join("router.log"))?;
    assert!(
        denial_logged(&log, "forecaster", &format!("Put (ingress) on {image}")),
        "router log:\n{log}"
    );
    assert!(h.is_running("router"));
    Ok(())
}
