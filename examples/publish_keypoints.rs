//! Publish keypoints the way your own pose estimator would: one `KeypointFrame` per camera
//! image on `echo/<robot>/perception/raw`, here two people 2.5 m in front of the head camera,
//! as 3D points (metres) in the camera's optical frame (x right, y down, z forward) in Echo's
//! 22-joint SMPL order. The perception bridge turns them into tracked skeletons in the robot's
//! frame.
//!
//! ```sh
//! cargo run --example publish_keypoints -- --robot tiago --seconds 10
//! ```

use std::time::Duration;

use clap::Parser;
use echo_bus::{topics, Bus, BusArgs};
use echo_motion::skeleton::{forward, Body, Pose};
use echo_msgs::{DetectedPerson, Header, KeypointFormat, KeypointFrame, Keypoints};
use nalgebra::Vector3;

#[derive(Parser)]
struct Args {
    /// Network and robot id (the same flags as every Echo binary).
    #[command(flatten)]
    bus: BusArgs,
    /// Seconds to publish.
    #[arg(long, default_value_t = 10.0)]
    seconds: f64,
    /// Frames per second.
    #[arg(long, default_value_t = 15.0)]
    rate_hz: f64,
}

/// Camera height above the floor the example assumes (TIAGo++'s head camera, torso down).
const CAMERA_HEIGHT_M: f64 = 1.2;

/// A person facing the camera at `ahead` metres, `side` metres to the left, swaying by `sway`.
fn person(ahead: f64, side: f64, sway: f64) -> Vec<[f64; 3]> {
    let body = Body::with_height(1.72);
    let root = Vector3::new(ahead, side + sway, body.pelvis_height());
    // Facing back towards the camera (yaw π), in a frame with x ahead, y left, z up.
    let joints = forward(&body, &Pose::rest(root, std::f64::consts::PI));
    // → the camera's optical frame: x right, y down, z forward.
    joints
        .iter()
        .map(|p| [-p.y, CAMERA_HEIGHT_M - p.z, p.x])
        .collect()
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let bus = Bus::open(&args.bus, "example-keypoints").await?;
    let raw = bus.publisher(&topics::perception_raw(bus.robot())).await?;
    let frames = (args.seconds * args.rate_hz).round() as u64;
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / args.rate_hz));
    for k in 0..frames {
        tick.tick().await;
        let t = k as f64 / args.rate_hz;
        let sway = 0.1 * (0.5 * t).sin();
        let people = [person(2.5, 0.5, sway), person(2.6, -0.6, -sway)]
            .into_iter()
            .enumerate()
            .map(|(i, xyz)| DetectedPerson {
                detection_id: Some(i as u32),
                confidence: vec![0.9; xyz.len()],
                keypoints: Keypoints::Points3d { xyz },
            })
            .collect();
        raw.put(KeypointFrame {
            header: Header::new(bus.robot().as_str(), "", "head_front_camera_optical_frame"),
            format: KeypointFormat::Smpl22,
            joint_names: None,
            camera: None,
            depth_image: None,
            people,
        })
        .await?;
    }
    println!("published {frames} keypoint frames on {}", raw_key(&bus));
    bus.close().await?;
    Ok(())
}

fn raw_key(bus: &Bus) -> String {
    topics::perception_raw(bus.robot()).key.to_string()
}
