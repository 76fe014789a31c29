//! `echoctl up --profile single` as Zenoh clients of a router: every service of the profile comes
//! alive; a service that crashes is restarted by the supervisor; SIGTERM stops them all.

use std::time::Duration;

use echo_bus::testkit::free_port;
use echo_bus::{keys, Bus, BusArgs};
use echo_system_tests::Harness;

const ROBOT: &str = "sys-up";

/// Child processes of `pid` whose command line contains `name`.
fn children_named(pid: u32, name: &str) -> Vec<u32> {
    let mut out = vec![];
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return out;
    };
    for t in tasks.flatten() {
        let kids = std::fs::read_to_string(t.path().join("children")).unwrap_or_default();
        for k in kids
            .split_whitespace()
            .filter_map(|k| k.parse::<u32>().ok())
        {
            let cmd = std::fs::read(format!("/proc/{k}/cmdline")).unwrap_or_default();
            if String::from_utf8_lossy(&cmd).contains(name) {
                out.push(k);
            }
        }
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn up_starts_supervises_and_stops_a_profile() -> anyhow::Result<()> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut h = Harness::new(ROBOT, 0)?;
    let port = free_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    h.spawn_raw(
        "router",
        "echoctl",
        &["router", "--listen", &endpoint, "--no-multicast-scouting"],
    )?;
    tokio::time::sleep(Duration::from_millis(500)).await;
    h.spawn_raw(
        "up",
        "echoctl",
        &[
            "up",
            "--profile",
            "single",
            "--deploy-dir",
            root.join("deploy").to_str().unwrap(),
            "--models",
            root.join("models").to_str().unwrap(),
            "--robot",
            ROBOT,
            "--mode",
            "client",
            "--connect",
            &endpoint,
        ],
    )?;
    let mut me = BusArgs::loopback(ROBOT, &[], &[port]);
    me.mode = Some("client".into());
    let bus = Bus::open(&me, "system-test").await?;
    let services = [
        "mock-robot",
        "perception-bridge",
        "forecaster",
        "retargeter",
        "safety",
        "mock-perception",
    ];
    h.wait_alive(&bus, &services, Duration::from_secs(90))
        .await?;

    // A crash is repaired.
    let up = h.pid("up").unwrap();
    let bridge = children_named(up, "perception-bridge");
    assert_eq!(bridge.len(), 1, "one bridge child: {bridge:?}");
    let watch = bus.watch_alive(&keys::alive_all(bus.robot())).await?;
    // The watch knows the bridge is alive before the kill (else its loss cannot be seen).
    let missing = watch
        .wait_for(ROBOT, &["perception-bridge"], Duration::from_secs(10))
        .await;
    assert!(missing.is_empty(), "the watch never saw the bridge");
    assert!(echo_launch::send_signal(
        bridge[0],
        echo_launch::Sig::SIGKILL
    ));
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    while watch.is_alive(ROBOT, "perception-bridge") && tokio::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(
        !watch.is_alive(ROBOT, "perception-bridge"),
        "the kill was not seen"
    );
    let missing = watch
        .wait_for(ROBOT, &["perception-bridge"], Duration::from_secs(20))
        .await;
    assert!(missing.is_empty(), "the bridge was not restarted");
    let again = children_named(up, "perception-bridge");
    assert_eq!(again.len(), 1);
    assert_ne!(again[0], bridge[0]);

    // SIGTERM stops everything.
    assert!(
        h.stop("up", Duration::from_secs(15)),
        "up did not exit cleanly"
    );
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    while services.iter().any(|s| watch.is_alive(ROBOT, s))
        && tokio::time::Instant::now() < deadline
    {
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let left: Vec<_> = services
        .iter()
        .filter(|s| watch.is_alive(ROBOT, s))
        .collect();
    assert!(left.is_empty(), "still alive after up stopped: {left:?}");
    Ok(())
}
