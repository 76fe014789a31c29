//! The service loop driven by scripted inputs, no network: every kind of bad input is rejected
//! with a reason, counted, and the loop keeps producing skeletons afterwards.

use std::time::Instant;

use anyhow::Result;
use echo_bus::{Received, Stats};
use echo_msgs::{frames, HumanSkeletons, KeypointFrame};
use echo_perception::{BridgeConfig, PerceptionBridge};
use echo_robot::RobotModel;
use echo_sim::perception::{MockPerception, MockPerceptionConfig};
use echo_sim::robot::{SimRobot, SimRobotConfig};
use perception_bridge::{run, Input, Output, INPUT_EDGE};

const T0: u64 = 1_800_000_000_000_000_000;
const FRAME_NS: u64 = 66_666_667;

#[derive(Default)]
struct Collect(Vec<HumanSkeletons>);

impl Output for Collect {
    async fn skeletons(&mut self, msg: HumanSkeletons) -> Result<()> {
        self.0.push(msg);
        Ok(())
    }
}

fn rx<M>(msg: M) -> Received<M> {
    Received {
        msg,
        at: Instant::now(),
    }
}

/// Joint states every 10 ms and a keypoint frame every 1/15 s for `frames` frames.
fn script(frames_n: usize) -> (Vec<Input>, Vec<KeypointFrame>) {
    let model = RobotModel::tiago_dual();
    let robot = SimRobot::new(SimRobotConfig::default(), model.clone());
    let mut mock = MockPerception::new(MockPerceptionConfig {
        drop_joint_prob: 0.0,
        ..Default::default()
    });
    let cam = robot.frame_pose(frames::HEAD_CAMERA_OPTICAL).unwrap();
    let mut inputs = vec![];
    let mut kf = vec![];
    for i in 0..frames_n as u64 {
        let stamp = T0 + i * FRAME_NS;
        inputs.push(Input::JointState(rx(robot.joint_state("tiago", stamp))));
        let f = mock.frame("tiago", i as f64 / 15.0, stamp, &cam).unwrap();
        kf.push(f.clone());
        inputs.push(Input::Keypoints(rx(f)));
    }
    (inputs, kf)
}

async fn drive(inputs: Vec<Input>, now_offset_ns: u64) -> (Collect, Stats) {
    let stats = Stats::new("perception-bridge");
    let mut out = Collect::default();
    let bridge = PerceptionBridge::new(BridgeConfig::default(), RobotModel::tiago_dual());
    // The receiver's wall clock: 20 ms after the newest capture stamp seen so far.
    let newest = std::sync::atomic::AtomicU64::new(T0);
    let stream = futures::stream::iter(inputs.into_iter().inspect(|i| {
        if let Input::Keypoints(k) = i {
            newest.fetch_max(k.msg.header.stamp_ns, std::sync::atomic::Ordering::Relaxed);
        }
    }));
    run(stream, &mut out, bridge, &stats, || {
        newest.load(std::sync::atomic::Ordering::Relaxed) + now_offset_ns
    })
    .await
    .unwrap();
    (out, stats)
}

#[tokio::test]
async fn good_input_gives_15_hz_skeletons() {
    let (inputs, _) = script(30);
    let (out, stats) = drive(inputs, 20_000_000).await;
    assert!(out.0.len() >= 29, "{}", out.0.len());
    assert!(out.0.iter().skip(5).all(|s| s.partner_id.is_some()));
    assert_eq!(stats.rejected_total(), 0);
}

#[tokio::test]
async fn stale_frames_are_rejected_and_counted() {
    let (inputs, _) = script(10);
    // Every frame arrives 800 ms after capture (limit 500 ms).
    let (out, stats) = drive(inputs, 800_000_000).await;
    assert!(out.0.is_empty());
    assert_eq!(stats.rejected_count(INPUT_EDGE, "stale"), 10);
}

#[tokio::test]
async fn reordered_frames_are_rejected_and_the_loop_continues() {
    let (mut inputs, frames) = script(20);
    // Replay frame 3 after frame 10.
    let pos = inputs
        .iter()
        .position(|i| matches!(i, Input::Keypoints(k) if k.msg.header.stamp_ns == frames[10].header.stamp_ns))
        .unwrap();
    inputs.insert(pos + 1, Input::Keypoints(rx(frames[3].clone())));
    let (out, stats) = drive(inputs, 20_000_000).await;
    assert_eq!(stats.rejected_count(INPUT_EDGE, "out_of_order"), 1);
    assert!(out.0.len() >= 19, "later frames still processed");
}

#[tokio::test]
async fn unknown_camera_frames_and_missing_joint_states_are_rejected() {
    let (inputs, frames) = script(5);
    let mut bad = frames[4].clone();
    bad.header.frame_id = "kinect_rgb_optical".into();
    bad.header.stamp_ns += FRAME_NS;
    let mut all: Vec<Input> = inputs;
    all.push(Input::Keypoints(rx(bad)));
    let (_, stats) = drive(all, 20_000_000).await;
    assert_eq!(stats.rejected_count(INPUT_EDGE, "unknown_frame"), 1);

    // Keypoints before any joint state: the camera cannot be placed.
    let only_frames: Vec<Input> = frames
        .into_iter()
        .map(|f| Input::Keypoints(rx(f)))
        .collect();
    let (out, stats) = drive(only_frames, 20_000_000).await;
    assert!(out.0.is_empty());
    assert_eq!(stats.rejected_count(INPUT_EDGE, "no_joint_state"), 5);
}
