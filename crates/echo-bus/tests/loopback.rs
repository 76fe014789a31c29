//! Two real Zenoh sessions over TCP on loopback: typed delivery, rejection counting, sensor drops
//! counted, and liveliness that disappears when a session closes.

use std::time::Duration;

use echo_bus::testkit::{loopback_mesh, within};
use echo_bus::{topics, Bus};
use echo_msgs::{EStop, EStopAction, Header, JointState};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn typed_delivery_rejections_and_liveliness() {
    let mesh = loopback_mesh("bus-test", 2);
    let a = Bus::open(&mesh[0], "alpha").await.unwrap();
    let b = Bus::open(&mesh[1], "beta").await.unwrap();
    let robot = a.robot().clone();
    let watch = a
        .watch_alive(&echo_bus::keys::alive_all(&robot))
        .await
        .unwrap();
    let inbox = a.subscribe(&topics::estop(&robot)).await.unwrap();
    let token = b.declare_alive().await.unwrap();
    assert!(watch
        .wait_for("bus-test", &["beta"], Duration::from_secs(10))
        .await
        .is_empty());

    let publisher = b.publisher(&topics::estop(&robot)).await.unwrap();
    // Subscriptions need a moment to propagate between peers.
    tokio::time::sleep(Duration::from_millis(300)).await;
    publisher
        .put(EStop {
            header: Header::new("", "", ""),
            action: EStopAction::Engage,
            reason: "test".into(),
        })
        .await
        .unwrap();
    let got = within(5.0, "an e-stop", inbox.recv()).await.unwrap();
    assert_eq!(got.msg.header.robot_id, "bus-test");
    assert_eq!(got.msg.header.source, b.source());

    publisher.put_raw(b"{not json".to_vec()).await.unwrap();
    publisher.put_raw(vec![b'x'; 2 << 20]).await.unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let stats = a.stats();
    assert_eq!(stats.rejected_count("estop", "malformed"), 1);
    assert_eq!(stats.rejected_count("estop", "too_large"), 1);

    // A sensor stream nobody drains keeps the newest messages and counts the rest as dropped.
    let states = a.subscribe(&topics::robot_state(&robot)).await.unwrap();
    let sp = b.publisher(&topics::robot_state(&robot)).await.unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;
    for _ in 0..100 {
        sp.put(JointState {
            header: Header::new("", "", ""),
            name: vec![],
            position: vec![],
            velocity: vec![],
            base: None,
        })
        .await
        .unwrap();
    }
    tokio::time::sleep(Duration::from_millis(500)).await;
    // Zenoh may already drop under congestion at the sender (Drop policy); whatever arrives,
    // the inbox keeps at most its depth (32 for joint states) and counts every message it drops.
    let kept = states.drain().len() as u64;
    let received = stats.received_count("robot_state");
    assert!(received > 0);
    assert!(kept <= 32, "kept {kept}");
    assert_eq!(kept + stats.dropped_count("robot_state"), received);
    if received > 32 {
        assert!(stats.dropped_count("robot_state") > 0);
    }

    drop(token);
    b.close().await.unwrap();
    let deadline = tokio::time::Instant::now() + Duration::from_secs(5);
    while watch.is_alive("bus-test", "beta") && tokio::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(
        !watch.is_alive("bus-test", "beta"),
        "liveliness gone when the peer closes"
    );
}
