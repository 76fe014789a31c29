//! Foxglove output: an MCAP file read back with the `mcap` crate and decoded with prost, and
//! the live server seen by a WebSocket client of the Foxglove WebSocket protocol (the SDK's
//! server negotiates `foxglove.sdk.v1`, the protocol's current name; the older
//! `foxglove.websocket.v1` alone is refused).

#![cfg(feature = "foxglove")]

mod common;

use std::collections::BTreeMap;
use std::time::Duration;

use common::*;
use echo_scene::foxglove::{convert_recording, FoxgloveOptions, LiveServer, SCENE_TOPIC, TF_TOPIC};
use echo_scene::SceneBuilder;
use foxglove::messages::{FrameTransforms, SceneUpdate};
use futures::{SinkExt, StreamExt};
use prost::Message as _;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::Message;

#[test]
fn converted_recordings_carry_scene_and_tf_schemas_and_the_raw_json() {
    let dir = tempfile::tempdir().unwrap();
    let (raw, out) = (
        dir.path().join("walk.mcap"),
        dir.path().join("walk.foxglove.mcap"),
    );
    write_walk_recording(&raw);
    let summary = convert_recording(&raw, &out, &FoxgloveOptions::default()).unwrap();
    let original = echo_record::read_recording(&raw).unwrap();
    assert_eq!(summary.raw, original.len() as u64);
    assert_eq!(summary.rejected, 1);

    let bytes = std::fs::read(&out).unwrap();
    let mut scenes = vec![];
    let mut tfs = vec![];
    let mut raw_back: Vec<(String, u64, Vec<u8>)> = vec![];
    let mut channels = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m
            .channel
            .schema
            .as_ref()
            .map(|s| (s.name.clone(), s.encoding.clone(), s.data.to_vec()));
        channels.insert(
            m.channel.topic.clone(),
            (m.channel.message_encoding.clone(), schema),
        );
        match m.channel.topic.as_str() {
            SCENE_TOPIC => scenes.push((m.log_time, SceneUpdate::decode(&m.data[..]).unwrap())),
            TF_TOPIC => tfs.push((m.log_time, FrameTransforms::decode(&m.data[..]).unwrap())),
            key => raw_back.push((key.to_string(), m.log_time, m.data.to_vec())),
        }
    }
    // Schemas: names, encodings, and descriptors that describe the messages.
    for (topic, name, message) in [
        (SCENE_TOPIC, "foxglove.SceneUpdate", "SceneUpdate"),
        (TF_TOPIC, "foxglove.FrameTransforms", "FrameTransforms"),
    ] {
        let (encoding, schema) = &channels[topic];
        assert_eq!(encoding, "protobuf");
        let (schema_name, schema_encoding, data) = schema.clone().expect("a schema");
        assert_eq!(schema_name, name);
        assert_eq!(schema_encoding, "protobuf");
        let set = prost_types::FileDescriptorSet::decode(&data[..]).unwrap();
        assert!(set.file.iter().any(
            |f| f.package() == "foxglove" && f.message_type.iter().any(|d| d.name() == message)
        ));
    }
    // The raw channels: JSON, no schema, every message byte for byte.
    let (encoding, schema) = &channels["echo/r1/humans"];
    assert_eq!((encoding.as_str(), schema.is_none()), ("json", true));
    raw_back.sort_by(|a, b| a.1.cmp(&b.1).then(a.0.cmp(&b.0)));
    let mut want: Vec<(String, u64, Vec<u8>)> = original
        .iter()
        .map(|r| (r.key.clone(), r.log_time_ns, r.payload.clone()))
        .collect();
    want.sort_by(|a, b| a.1.cmp(&b.1).then(a.0.cmp(&b.0)));
    assert_eq!(raw_back, want);
    // So the converted file is still a recording (replay and render read the bus messages).
    assert_eq!(echo_record::read_recording(&out).unwrap(), original);

    // Scenes: at most 30 per second, every entity in base_footprint, the partner walking.
    assert_eq!(scenes.len() as u64, summary.scenes);
    assert!(
        scenes.len() >= 45 && scenes.len() <= 92,
        "{} scenes",
        scenes.len()
    );
    assert!(scenes
        .windows(2)
        .all(|w| w[1].0 >= w[0].0 + 33_333_333 || w[1].0 == original.last().unwrap().log_time_ns));
    let (t_last, last) = scenes.last().unwrap();
    assert_eq!(*t_last, original.last().unwrap().log_time_ns);
    let ids: Vec<&str> = last.entities.iter().map(|e| e.id.as_str()).collect();
    for id in [
        "robot",
        "camera",
        "partner",
        "forecast",
        "safety",
        "separation",
    ] {
        assert!(ids.contains(&id), "{id} in {ids:?}");
    }
    assert!(last.entities.iter().all(|e| e.frame_id == "base_footprint"));
    assert_eq!(last.deletions.len(), 1, "the previous scene is cleared");
    let partner = last.entities.iter().find(|e| e.id == "partner").unwrap();
    let head = partner
        .spheres
        .iter()
        .find(|s| s.size.unwrap().x > 0.15)
        .unwrap();
    let want_head = person(walk_x(3.0), 0.0)[15];
    let p = head.pose.unwrap().position.unwrap();
    assert!((p.x - want_head[0]).abs() < 1e-9 && (p.z - want_head[2]).abs() < 1e-9);
    // A robot capsule is a cylinder whose length joins its end spheres.
    let robot = last.entities.iter().find(|e| e.id == "robot").unwrap();
    assert_eq!(robot.cylinders.len(), 13, "14 capsules, the head a sphere");

    // Link frames: the head camera where forward kinematics puts it.
    let (_, tf) = tfs.last().unwrap();
    let cam = tf
        .transforms
        .iter()
        .find(|t| t.child_frame_id == "head_front_camera_optical_frame")
        .unwrap();
    assert_eq!(cam.parent_frame_id, "base_footprint");
    let model = echo_robot::RobotModel::tiago_dual();
    let q = model
        .values_from(
            echo_robot::home_pose()
                .iter()
                .map(|(n, v)| (n.as_str(), *v)),
        )
        .unwrap();
    let want = model
        .fk(&q, "head_front_camera_optical_frame")
        .unwrap()
        .translation
        .vector;
    let got = cam.translation.unwrap();
    assert!((got.x - want.x).abs() < 1e-9 && (got.z - want.z).abs() < 1e-9);
}

async fn next_text(
    ws: &mut (impl StreamExt<Item = Result<Message, tokio_tungstenite::tungstenite::Error>> + Unpin),
) -> serde_json::Value {
    loop {
        let m = tokio::time::timeout(Duration::from_secs(10), ws.next())
            .await
            .expect("a message within 10 s")
            .expect("the connection stays open")
            .unwrap();
        if let Message::Text(t) = m {
            return serde_json::from_str(t.as_str()).unwrap();
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_live_server_advertises_the_scene_and_streams_it() {
    let server = LiveServer::start("127.0.0.1", 0).await.unwrap();
    let port = server.port();
    assert_ne!(port, 0);
    let mut request = format!("ws://127.0.0.1:{port}")
        .into_client_request()
        .unwrap();
    request.headers_mut().insert(
        "sec-websocket-protocol",
        "foxglove.websocket.v1, foxglove.sdk.v1".parse().unwrap(),
    );
    let (mut ws, response) = tokio::time::timeout(
        Duration::from_secs(10),
        tokio_tungstenite::connect_async(request),
    )
    .await
    .expect("connects within 10 s")
    .unwrap();
    assert_eq!(
        response.headers()["sec-websocket-protocol"],
        "foxglove.sdk.v1"
    );

    let info = next_text(&mut ws).await;
    assert_eq!(info["op"], "serverInfo");
    assert_eq!(info["name"], "echo");
    let advertise = next_text(&mut ws).await;
    assert_eq!(advertise["op"], "advertise");
    let channels = advertise["channels"].as_array().unwrap();
    let scene = channels
        .iter()
        .find(|c| c["topic"] == SCENE_TOPIC)
        .expect("the scene channel");
    assert_eq!(scene["schemaName"], "foxglove.SceneUpdate");
    assert_eq!(scene["encoding"], "protobuf");
    assert!(channels
        .iter()
        .any(|c| c["topic"] == TF_TOPIC && c["schemaName"] == "foxglove.FrameTransforms"));

    // Subscribe, then publish until a scene arrives.
    let subscribe = serde_json::json!({
        "op": "subscribe",
        "subscriptions": [{"id": 7, "channelId": scene["id"]}],
    });
    ws.send(Message::text(subscribe.to_string())).await.unwrap();
    let mut builder = SceneBuilder::new();
    builder.on_message(
        &key("humans"),
        &humans(T0, vec![track(7, person(1.5, 0.0))], Some(7)),
    );
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    let data = loop {
        assert!(
            tokio::time::Instant::now() < deadline,
            "no scene within 10 s"
        );
        server.publish(&builder, T0);
        server.publish_raw(&key("humans"), b"{}", T0);
        match tokio::time::timeout(Duration::from_millis(100), ws.next()).await {
            Ok(Some(Ok(Message::Binary(b)))) => break b,
            Ok(Some(Ok(_))) | Err(_) => continue,
            Ok(other) => panic!("connection ended: {other:?}"),
        }
    };
    // Message data: opcode 1, subscription id, log time, payload.
    assert_eq!(data[0], 1);
    assert_eq!(u32::from_le_bytes(data[1..5].try_into().unwrap()), 7);
    assert_eq!(u64::from_le_bytes(data[5..13].try_into().unwrap()), T0);
    let update = SceneUpdate::decode(&data[13..]).unwrap();
    assert!(update.entities.iter().any(|e| e.id == "partner"));
    assert_eq!(server.clients(), 1);
    drop(ws);
    tokio::time::timeout(Duration::from_secs(10), server.stop())
        .await
        .expect("stops within 10 s");
}
