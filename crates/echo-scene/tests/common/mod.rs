//! Valid bus messages for the tests, and a small recording of a person walking up to the robot.

#![allow(dead_code)]

use std::path::Path;

use echo_motion::skeleton::{forward, Body, Pose};
use echo_msgs::{
    encode, Forecast, Header, HumanPose, HumanSkeletons, HumanTrack, JointState, SafetyState,
    SafetyStatus,
};
use nalgebra::Vector3;

pub const ROBOT: &str = "r1";
pub const T0: u64 = 1_700_000_000_000_000_000;

pub fn header(stamp_ns: u64, frame: &str) -> Header {
    let mut h = Header::new(ROBOT, "test", frame);
    h.stamp_ns = stamp_ns;
    h
}

/// A 1.75 m person standing at (x, y) facing the robot (−x).
pub fn person(x: f64, y: f64) -> Vec<[f64; 3]> {
    let body = Body::with_height(1.75);
    let root = Vector3::new(x, y, body.pelvis_height());
    forward(&body, &Pose::rest(root, std::f64::consts::PI))
        .iter()
        .map(|p| [p.x, p.y, p.z])
        .collect()
}

pub fn track(id: u32, joints: Vec<[f64; 3]>) -> HumanTrack {
    let root = joints[0];
    HumanTrack {
        track_id: id,
        pose: HumanPose {
            local_positions: joints
                .iter()
                .map(|p| [p[0] - root[0], p[1] - root[1], p[2] - root[2]])
                .collect(),
            local_rotations: vec![[0.0, 0.0, 0.0, 1.0]; 22],
            confidence: vec![1.0; 22],
            root_position: root,
            root_orientation: [0.0, 0.0, 1.0, 0.0],
            joints,
        },
        root_velocity: [0.0; 3],
        age_frames: 10,
        filled_joints: vec![],
    }
}

pub fn humans(stamp_ns: u64, tracks: Vec<HumanTrack>, partner: Option<u32>) -> Vec<u8> {
    encode(&HumanSkeletons {
        header: header(stamp_ns, "base_footprint"),
        rate_hz: 15.0,
        tracks,
        partner_id: partner,
    })
}

pub fn joint_state(stamp_ns: u64, pairs: &[(&str, f64)]) -> Vec<u8> {
    encode(&JointState {
        header: header(stamp_ns, "base_footprint"),
        name: pairs.iter().map(|(n, _)| n.to_string()).collect(),
        position: pairs.iter().map(|(_, v)| *v).collect(),
        velocity: vec![],
        base: None,
    })
}

pub fn home_state(stamp_ns: u64) -> Vec<u8> {
    let home = echo_robot::home_pose();
    let pairs: Vec<(&str, f64)> = home.iter().map(|(n, v)| (n.as_str(), *v)).collect();
    joint_state(stamp_ns, &pairs)
}

/// The partner stepping from `x` towards the robot by 2 cm per frame, 23 frames.
pub fn forecast(stamp_ns: u64, partner: u32, x: f64) -> Vec<u8> {
    encode(&Forecast {
        header: header(stamp_ns, "base_footprint"),
        model: "test".into(),
        rate_hz: 15.0,
        partner_id: partner,
        human: (0..23)
            .map(|k| person(x - 0.02 * (k + 1) as f64, 0.0))
            .collect(),
        robot: None,
        inference_ms: 3.0,
    })
}

pub fn safety(stamp_ns: u64, state: SafetyState, sep: Option<f64>) -> Vec<u8> {
    encode(&SafetyStatus {
        header: header(stamp_ns, ""),
        state,
        reasons: vec![],
        speed_scale: 0.5,
        min_separation_m: sep,
        counters: Default::default(),
    })
}

pub fn key(suffix: &str) -> String {
    format!("echo/{ROBOT}/{suffix}")
}

/// Where the partner stands at `t_s` of the walk: from x = 3.0 m at 0 s to 1.5 m at 3 s.
pub fn walk_x(t_s: f64) -> f64 {
    3.0 - 0.5 * t_s
}

/// A 3 s recording (echo-record's format): the partner walks up (15 Hz), the robot holds its
/// home pose (50 Hz), the safety filter limits (10 Hz), a forecast (5 Hz), one malformed
/// message. The last message is at exactly 3 s.
pub fn write_walk_recording(path: &Path) {
    let file = std::fs::File::create(path).unwrap();
    let mut rec = echo_record::Recorder::new(std::io::BufWriter::new(file)).unwrap();
    let mut msgs: Vec<(u64, String, Vec<u8>)> = vec![];
    let at = |k: u64, hz: u64| T0 + k * 1_000_000_000 / hz;
    for k in 0..=45 {
        let t = at(k, 15);
        let x = walk_x((t - T0) as f64 / 1e9);
        msgs.push((
            t,
            key("humans"),
            humans(t, vec![track(7, person(x, 0.0))], Some(7)),
        ));
    }
    for k in 0..150 {
        let t = at(k, 50);
        msgs.push((t, key("robot/state"), home_state(t)));
    }
    for k in 0..30 {
        let t = at(k, 10) + 1_000_000;
        msgs.push((
            t,
            key("safety/status"),
            safety(t, SafetyState::Limiting, Some(0.8)),
        ));
    }
    for k in 0..15 {
        let t = at(k, 5) + 2_000_000;
        let x = walk_x((t - T0) as f64 / 1e9);
        msgs.push((t, key("forecast"), forecast(t, 7, x)));
    }
    msgs.push((at(1, 2), key("humans"), b"{\"header\": 5}".to_vec()));
    msgs.push((at(1, 3), key("status/safety"), b"{}".to_vec()));
    msgs.sort_by_key(|m| m.0);
    for (t, k, p) in &msgs {
        rec.write(k, *t, p).unwrap();
    }
    rec.finish().unwrap();
}
