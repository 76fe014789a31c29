//! `echoctl scene`: a 20 s recording as a GIF and as a Foxglove MCAP, and the live server.

use std::path::Path;
use std::process::Command;

use echo_msgs::{
    encode, Header, HumanPose, HumanSkeletons, HumanTrack, JointState, SafetyState, SafetyStatus,
};

fn echoctl(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_echoctl"))
        .args(args)
        .output()
        .expect("run echoctl")
}

fn header(t: u64) -> Header {
    let mut h = Header::new("tiago", "test", "base_footprint");
    h.stamp_ns = t;
    h
}

/// A stick person (22 joints) at (x, 0) facing the robot, the right hand raised by `wave`.
fn person(x: f64, wave: f64) -> Vec<[f64; 3]> {
    let mut j = vec![[x, 0.0, 0.95]; 22];
    let set = |j: &mut Vec<[f64; 3]>, i: usize, y: f64, z: f64| j[i] = [x, y, z];
    for (i, y, z) in [
        (1, 0.09, 0.9),
        (2, -0.09, 0.9),
        (3, 0.0, 1.05),
        (4, 0.09, 0.5),
        (5, -0.09, 0.5),
        (6, 0.0, 1.2),
        (7, 0.09, 0.08),
        (8, -0.09, 0.08),
        (9, 0.0, 1.3),
        (10, 0.09, 0.02),
        (11, -0.09, 0.02),
        (12, 0.0, 1.5),
        (13, 0.08, 1.42),
        (14, -0.08, 1.42),
        (15, 0.0, 1.62),
        (16, 0.18, 1.42),
        (17, -0.18, 1.42),
        (18, 0.2, 1.15),
        (19, -0.2, 1.15 + 0.3 * wave),
        (20, 0.2, 0.9),
        (21, -0.2, 0.9 + 0.7 * wave),
    ] {
        set(&mut j, i, y, z);
    }
    j
}

fn humans(t: u64, joints: Vec<[f64; 3]>) -> Vec<u8> {
    let root = joints[0];
    encode(&HumanSkeletons {
        header: header(t),
        rate_hz: 15.0,
        tracks: vec![HumanTrack {
            track_id: 1,
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
            age_frames: 1,
            filled_joints: vec![],
        }],
        partner_id: Some(1),
    })
}

/// 20 s: the partner walks from 3.5 m to 1.2 m and waves, the robot raises its right arm.
fn write_recording(path: &Path, seconds: u64) {
    let t0 = 1_700_000_000_000_000_000u64;
    let mut msgs: Vec<(u64, &str, Vec<u8>)> = vec![];
    for k in 0..=seconds * 15 {
        let t = t0 + k * 1_000_000_000 / 15;
        let s = k as f64 / 15.0 / seconds as f64;
        let wave = (k as f64 * 0.6).sin().max(0.0) * s;
        msgs.push((
            t,
            "echo/tiago/humans",
            humans(t, person(3.5 - 2.3 * s, wave)),
        ));
    }
    for k in 0..seconds * 100 {
        let t = t0 + k * 10_000_000;
        let s = k as f64 / (seconds * 100) as f64;
        let names = [
            "torso_lift_joint",
            "arm_right_1_joint",
            "arm_right_2_joint",
            "arm_right_4_joint",
        ];
        msgs.push((
            t,
            "echo/tiago/robot/state",
            encode(&JointState {
                header: header(t),
                name: names.iter().map(|n| n.to_string()).collect(),
                position: vec![0.15 + 0.1 * s, 0.2, -0.8 * s, 1.8 - 1.2 * s],
                velocity: vec![],
                base: None,
            }),
        ));
    }
    for k in 0..seconds * 50 {
        let t = t0 + k * 20_000_000 + 1;
        let s = k as f64 / (seconds * 50) as f64;
        msgs.push((
            t,
            "echo/tiago/safety/status",
            encode(&SafetyStatus {
                header: header(t),
                state: if s < 0.7 {
                    SafetyState::Following
                } else {
                    SafetyState::Limiting
                },
                reasons: vec![],
                speed_scale: 1.0 - 0.5 * s,
                min_separation_m: Some(2.5 - 2.0 * s),
                counters: Default::default(),
            }),
        ));
    }
    msgs.push((
        t0 + 5,
        "echo/tiago/humans",
        b"{\"not\": \"skeletons\"}".to_vec(),
    ));
    msgs.sort_by_key(|m| m.0);
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut rec = echo_record::Recorder::new(file).unwrap();
    for (t, k, p) in &msgs {
        rec.write(k, *t, p).unwrap();
    }
    rec.finish().unwrap();
}

#[test]
fn scene_gif_and_mcap_convert_a_recording() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("run.mcap");
    write_recording(&rec, 20);
    let gif = dir.path().join("run.gif");
    let out = echoctl(&["scene", "gif", rec.to_str().unwrap(), gif.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!("{text}");
    assert!(text.contains("201 frames of 640×480"), "{text}");
    assert!(text.contains("1 malformed"), "{text}");
    let bytes = std::fs::read(&gif).unwrap();
    assert_eq!(&bytes[..6], b"GIF89a");

    let fox = dir.path().join("run.foxglove.mcap");
    let out = echoctl(&[
        "scene",
        "mcap",
        rec.to_str().unwrap(),
        fox.to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("1 not drawn"), "{text}");
    // Still a recording of the bus: every message back, byte for byte.
    assert_eq!(
        echo_record::read_recording(&fox).unwrap(),
        echo_record::read_recording(&rec).unwrap()
    );

    // Mistakes are named.
    let out = echoctl(&[
        "scene",
        "gif",
        rec.to_str().unwrap(),
        gif.to_str().unwrap(),
        "--fps",
        "0",
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("fps"));
    let missing = dir.path().join("missing.mcap");
    let out = echoctl(&[
        "scene",
        "mcap",
        missing.to_str().unwrap(),
        fox.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing.mcap"));
}

#[test]
fn scene_live_serves_and_stops() {
    let out = echoctl(&[
        "scene",
        "live",
        "--port",
        "0",
        "--seconds",
        "0.5",
        "--robot",
        "tiago",
        "--no-multicast-scouting",
        "--listen",
        "tcp/127.0.0.1:0",
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("Foxglove: open connection ws://127.0.0.1:"),
        "{text}"
    );
    assert!(
        !text.contains("ws://127.0.0.1:0 "),
        "the real port is printed: {text}"
    );
    assert!(text.contains("served 0 messages"), "{text}");
}
