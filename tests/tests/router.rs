//! `echoctl router` routes between two client sessions that only know the router.

use std::time::Duration;

use echo_bus::testkit::{free_port, within};
use echo_bus::{topics, Bus, BusArgs};
use echo_msgs::{EStop, EStopAction, Header};
use echo_system_tests::Harness;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn clients_talk_through_the_router() -> anyhow::Result<()> {
    let mut h = Harness::new("sys-router", 0)?;
    let port = free_port();
    h.spawn_raw(
        "router",
        "echoctl",
        &[
            "router",
            "--listen",
            &format!("tcp/127.0.0.1:{port}"),
            "--no-multicast-scouting",
        ],
    )?;
    let client = |name: &str| {
        let mut a = BusArgs::loopback("sys-router", &[], &[port]);
        a.mode = Some("client".into());
        let name = name.to_string();
        async move { Bus::open(&a, &name).await }
    };
    // Clients retry until the router is up.
    let mut a = None;
    for _ in 0..50 {
        if let Ok(b) = client("alpha").await {
            a = Some(b);
            break;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    let a = a.expect("client alpha connects to the router");
    let b = client("beta").await?;
    let inbox = a.subscribe(&topics::estop(a.robot())).await?;
    let publisher = b.publisher(&topics::estop(b.robot())).await?;
    tokio::time::sleep(Duration::from_millis(500)).await;
    publisher
        .put(EStop {
            header: Header::new("", "", ""),
            action: EStopAction::Engage,
            reason: "via router".into(),
        })
        .await?;
    let got = within(5.0, "an e-stop through the router", inbox.recv())
        .await
        .unwrap();
    assert_eq!(got.msg.reason, "via router");
    assert!(h.is_running("router"));
    Ok(())
}
