//! mock perception → perception bridge → skeletons, as separate processes over Zenoh on
//! loopback, with the simulated robot sweeping its head: the published skeletons match the
//! ground-truth motion in base_footprint; bad inputs are rejected, counted, and visible in the
//! bridge's status while it keeps running.

use std::time::Duration;

use echo_bus::testkit::within;
use echo_bus::topics;
use echo_msgs::{encode, frames, now_ns, Header, KeypointFormat, KeypointFrame, ServiceStatus};
use echo_sim::perception::{MockPerception, MockPerceptionConfig};
use echo_system_tests::Harness;
use nalgebra::Vector3;

const SETTLE_S: f64 = 1.5;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn skeletons_match_ground_truth_while_the_head_moves() -> anyhow::Result<()> {
    let mut h = Harness::new("sys-perception", 3)?;
    let t0 = now_ns() + 2_000_000_000;
    h.spawn(
        "mock-robot",
        "echoctl",
        &[
            "mock-robot",
            "--head-sweep",
            "0.35",
            "--head-sweep-period",
            "3",
        ],
    )?;
    h.spawn_services("single", &["perception-bridge"])?;
    h.spawn(
        "mock-perception",
        "echoctl",
        &["mock-perception", "--t0-ns", &t0.to_string(), "--seed", "3"],
    )?;
    let bus = h.bus("system-test").await?;
    let robot = bus.robot().clone();
    let humans = bus.subscribe(&topics::humans(&robot)).await?;
    let states = bus.subscribe(&topics::robot_state(&robot)).await?;
    h.wait_alive(
        &bus,
        &["mock-robot", "perception-bridge", "mock-perception"],
        Duration::from_secs(30),
    )
    .await?;

    // The same script as the mock publisher (ground truth does not depend on its noise).
    let truth = MockPerception::new(MockPerceptionConfig::default());
    let (mut errors, mut frames_n, mut partner_n) = (vec![], 0usize, 0usize);
    let (mut pan_min, mut pan_max) = (f64::INFINITY, f64::NEG_INFINITY);
    let deadline = tokio::time::Instant::now() + Duration::from_secs(9);
    while tokio::time::Instant::now() < deadline {
        for s in states.drain() {
            if let Some(p) = s.msg.position_of("head_1_joint") {
                pan_min = pan_min.min(p);
                pan_max = pan_max.max(p);
            }
        }
        let Ok(Some(rx)) = tokio::time::timeout(Duration::from_millis(200), humans.recv()).await
        else {
            continue;
        };
        let s = rx.msg;
        assert_eq!(s.header.frame_id, frames::BASE_FOOTPRINT);
        frames_n += 1;
        let t = (s.header.stamp_ns as f64 - t0 as f64) / 1e9;
        let Some(pid) = s.partner_id else { continue };
        partner_n += 1;
        if t < SETTLE_S {
            continue;
        }
        let gt = truth.truth(truth.script_time(t));
        let track = s
            .tracks
            .iter()
            .find(|t| t.track_id == pid)
            .expect("partner track");
        let e: f64 = (0..22)
            .map(|k| (Vector3::from(track.pose.joints[k]) - gt[0][k]).norm())
            .sum::<f64>()
            / 22.0;
        errors.push(e);
    }
    assert!(
        pan_max - pan_min > 0.4,
        "the head must move during the test: pan range {}",
        pan_max - pan_min
    );
    assert!(frames_n > 80, "only {frames_n} skeleton frames in 9 s");
    assert!(
        errors.len() > 50,
        "only {} comparable frames ({partner_n} with a partner)",
        errors.len()
    );
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    let p95 = errors[errors.len() * 95 / 100];
    eprintln!(
        "per-frame mean joint error: median {:.1} mm, p95 {:.1} mm over {} frames",
        median * 1e3,
        p95 * 1e3,
        errors.len()
    );
    // Tolerance: 1 cm keypoint noise, One-Euro lag and capture-time jitter on a moving head.
    assert!(median < 0.04, "median per-frame error {median} m");
    assert!(p95 < 0.08, "p95 per-frame error {p95} m");
    assert!(h.is_running("perception-bridge"));
    assert!(
        h.stop("perception-bridge", Duration::from_secs(5)),
        "clean shutdown on SIGTERM"
    );
    Ok(())
}

fn frame_json(robot: &str, source: &str, seq: u64, stamp_ns: u64) -> KeypointFrame {
    let mut header = Header::new(robot, source, frames::HEAD_CAMERA_OPTICAL);
    header.seq = seq;
    header.stamp_ns = stamp_ns;
    KeypointFrame {
        header,
        format: KeypointFormat::Smpl24,
        joint_names: None,
        camera: None,
        depth_image: None,
        people: vec![],
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_inputs_are_rejected_counted_and_visible_in_status() -> anyhow::Result<()> {
    let mut h = Harness::new("sys-badinput", 3)?;
    h.spawn_services("single", &["mock-robot", "perception-bridge"])?;
    h.spawn("mock-perception", "echoctl", &["mock-perception"])?;
    let bus = h.bus("attacker").await?;
    let robot = bus.robot().clone();
    let raw = bus.publisher(&topics::perception_raw(&robot)).await?;
    let status = bus
        .subscribe(&topics::service_status(&robot, "perception-bridge"))
        .await?;
    let humans = bus.subscribe(&topics::humans(&robot)).await?;
    h.wait_alive(
        &bus,
        &["mock-robot", "perception-bridge", "mock-perception"],
        Duration::from_secs(30),
    )
    .await?;
    within(10.0, "first skeletons", humans.recv()).await;

    let r = robot.as_str();
    let good = String::from_utf8(encode(&frame_json(r, "a", 1, now_ns())))?;
    let payloads: Vec<(&str, Vec<u8>)> = vec![
        ("malformed", b"{\"header\": {".to_vec()),
        ("malformed", good.replacen("\"people\":[]", "\"people\":[{\"keypoints\":{\"kind\":\"points_3d\",\"xyz\":[[1e999,0,0]]},\"confidence\":[1]}]", 1).into_bytes()),
        ("wrong_size", good.replacen("\"people\":[]", "\"people\":[{\"keypoints\":{\"kind\":\"points_3d\",\"xyz\":[[1,0,2]]},\"confidence\":[1]}]", 1).replacen("\"source\":\"a\"", "\"source\":\"b\"", 1).into_bytes()),
        ("unknown_joint", good.replacen("\"people\":[]", "\"joint_names\":[\"left_pinky\"],\"people\":[]", 1).replacen("\"source\":\"a\"", "\"source\":\"c\"", 1).into_bytes()),
        ("stale", encode(&frame_json(r, "d", 0, now_ns() - 2_000_000_000))),
        ("accepted", encode(&frame_json(r, "e", 10, now_ns()))),
        ("out_of_order", encode(&frame_json(r, "e", 9, now_ns()))),
    ];
    for (_, p) in &payloads {
        raw.put_raw(p.clone()).await?;
        tokio::time::sleep(Duration::from_millis(30)).await;
    }
    // The next status reports (1 Hz) must show every reason; the bridge keeps publishing.
    let mut last: Option<ServiceStatus> = None;
    let deadline = tokio::time::Instant::now() + Duration::from_secs(5);
    let expected = [
        "malformed",
        "wrong_size",
        "unknown_joint",
        "stale",
        "out_of_order",
    ];
    while tokio::time::Instant::now() < deadline {
        if let Ok(Some(s)) = tokio::time::timeout(Duration::from_millis(300), status.recv()).await {
            let ok = expected
                .iter()
                .all(|r| s.msg.rejected.contains_key(&format!("perception_raw/{r}")));
            last = Some(s.msg);
            if ok {
                break;
            }
        }
    }
    let st = last.expect("a status message");
    for r in expected {
        assert!(
            st.rejected.contains_key(&format!("perception_raw/{r}")),
            "no '{r}' in {:?}",
            st.rejected
        );
    }
    assert_eq!(st.rejected["perception_raw/malformed"], 2);
    assert!(st.last_error.is_some());
    humans.drain();
    within(5.0, "skeletons after the bad inputs", humans.recv()).await;
    assert!(h.is_running("perception-bridge"));
    Ok(())
}
