//! Round trips and rejections of the message contract.

use echo_msgs::*;

fn header() -> Header {
    Header::new("tiago-1", "test-0001", frames::HEAD_CAMERA_OPTICAL)
}

fn points3d_frame(n: usize) -> KeypointFrame {
    KeypointFrame {
        header: header(),
        format: KeypointFormat::Smpl24,
        joint_names: None,
        camera: None,
        depth_image: None,
        people: vec![DetectedPerson {
            detection_id: Some(7),
            keypoints: Keypoints::Points3d {
                xyz: vec![[0.1, 0.2, 2.0]; n],
            },
            confidence: vec![0.9; n],
        }],
    }
}

#[test]
fn keypoint_frame_round_trips() {
    let f = points3d_frame(24);
    let back: KeypointFrame = decode(&encode(&f)).unwrap();
    assert_eq!(back, f);
}

#[test]
fn wrong_size_is_rejected_with_field() {
    let err = decode::<KeypointFrame>(&encode(&points3d_frame(23))).unwrap_err();
    assert_eq!(err.reason(), "wrong_size");
    assert!(err.to_string().contains("people[0]"), "{err}");
}

#[test]
fn malformed_json_is_rejected() {
    for bad in [&b"{"[..], b"null", b"[]", b"{\"header\":1}", &[0xff, 0xfe]] {
        let err = decode::<KeypointFrame>(bad).unwrap_err();
        assert_eq!(err.reason(), "malformed", "{err}");
    }
}

#[test]
fn nan_cannot_hide_in_json() {
    // serde_json writes non-finite floats as null; they must not decode as numbers.
    let mut f = points3d_frame(24);
    if let Keypoints::Points3d { xyz } = &mut f.people[0].keypoints {
        xyz[3][1] = f64::NAN;
    }
    let err = decode::<KeypointFrame>(&encode(&f)).unwrap_err();
    assert_eq!(err.reason(), "malformed");
    // A huge literal that overflows to inf is refused by the JSON parser as well.
    let text = String::from_utf8(encode(&points3d_frame(24))).unwrap();
    let text = text.replacen("2.0", "1e999", 1);
    assert!(decode::<KeypointFrame>(text.as_bytes()).is_err());
}

#[test]
fn non_finite_values_fail_validation() {
    let mut js = JointState {
        header: header(),
        name: vec!["a".into(), "b".into()],
        position: vec![0.0, f64::INFINITY],
        velocity: vec![],
        base: None,
    };
    assert_eq!(js.validate().unwrap_err().reason(), "non_finite");
    js.position[1] = 0.5;
    js.validate().unwrap();
    js.velocity = vec![0.0];
    assert_eq!(js.validate().unwrap_err().reason(), "wrong_size");
}

#[test]
fn schema_version_and_robot_id_are_checked() {
    let mut f = points3d_frame(24);
    f.header.schema = SCHEMA_VERSION + 1;
    assert_eq!(
        decode::<KeypointFrame>(&encode(&f)).unwrap_err().reason(),
        "schema_version"
    );
    let mut f = points3d_frame(24);
    f.header.robot_id = "tiago/../x".into();
    assert_eq!(
        decode::<KeypointFrame>(&encode(&f)).unwrap_err().reason(),
        "bad_identifier"
    );
}

#[test]
fn confidence_out_of_range_is_rejected() {
    let mut f = points3d_frame(24);
    f.people[0].confidence[4] = 1.5;
    assert_eq!(f.validate().unwrap_err().reason(), "out_of_range");
}

#[test]
fn pixel_keypoints_need_intrinsics_and_depth() {
    let mut f = points3d_frame(17);
    f.format = KeypointFormat::Coco17;
    f.people[0].keypoints = Keypoints::PixelsDepth {
        uv: vec![[320.0, 240.0]; 17],
        depth_m: None,
    };
    assert!(f.validate().is_err());
    f.camera = Some(CameraIntrinsics {
        fx: 500.0,
        fy: 500.0,
        cx: 320.0,
        cy: 240.0,
        width: 640,
        height: 480,
    });
    assert!(f.validate().is_err(), "no depth source");
    f.depth_image = Some(DepthImage {
        width: 640,
        height: 480,
        depth_mm: vec![0; 10],
    });
    assert_eq!(f.validate().unwrap_err().reason(), "wrong_size");
    f.depth_image = Some(DepthImage {
        width: 640,
        height: 480,
        depth_mm: vec![2000; 640 * 480],
    });
    f.validate().unwrap();
}

fn pose() -> HumanPose {
    HumanPose {
        joints: vec![[1.0, 0.0, 1.0]; 22],
        root_position: [1.0, 0.0, 0.9],
        root_orientation: [0.0, 0.0, 0.0, 1.0],
        local_positions: vec![[0.0; 3]; 22],
        local_rotations: vec![[0.0, 0.0, 0.0, 1.0]; 22],
        confidence: vec![1.0; 22],
    }
}

#[test]
fn skeletons_check_quaternions_and_partner() {
    let mut s = HumanSkeletons {
        header: Header::new("tiago-1", "bridge", frames::BASE_FOOTPRINT),
        rate_hz: 15.0,
        tracks: vec![HumanTrack {
            track_id: 1,
            pose: pose(),
            root_velocity: [0.0; 3],
            age_frames: 3,
            filled_joints: vec![],
        }],
        partner_id: Some(1),
    };
    s.validate().unwrap();
    s.tracks[0].pose.local_rotations[5] = [0.0, 0.0, 0.5, 0.5];
    assert_eq!(s.validate().unwrap_err().reason(), "not_unit_quaternion");
    s.tracks[0].pose.local_rotations[5] = [0.0, 0.0, 0.0, 1.0];
    s.partner_id = Some(9);
    assert!(s.validate().is_err());
}

#[test]
fn plans_need_increasing_time() {
    let mut p = RobotPlan {
        header: header(),
        mode: ControlMode::Forecast,
        joint_names: vec!["torso_lift_joint".into()],
        points: vec![
            PlanPoint {
                t: 0.1,
                positions: vec![0.1],
                base: None,
            },
            PlanPoint {
                t: 0.1,
                positions: vec![0.1],
                base: None,
            },
        ],
    };
    assert_eq!(p.validate().unwrap_err().reason(), "not_increasing");
    p.points[1].t = 0.2;
    p.validate().unwrap();
    p.points[1].positions.push(0.0);
    assert_eq!(p.validate().unwrap_err().reason(), "wrong_size");
}

#[test]
fn unknown_joints_are_named() {
    let err = validate::check_joint_names("name", &["head_1_joint", "elbow"], &["head_1_joint"])
        .unwrap_err();
    assert_eq!(err.reason(), "unknown_joint");
    assert!(err.to_string().contains("elbow"));
}

#[test]
fn oversized_payload_is_rejected_unparsed() {
    let big = vec![b' '; MAX_PAYLOAD_BYTES + 1];
    assert_eq!(decode::<EStop>(&big).unwrap_err().reason(), "too_large");
}

#[test]
fn explicit_joint_names_must_belong_to_the_format() {
    let mut f = points3d_frame(2);
    f.joint_names = Some(vec!["right_wrist".into(), "left_wrist".into()]);
    f.validate().unwrap();
    f.joint_names = Some(vec!["right_wrist".into(), "left_pinky".into()]);
    let err = f.validate().unwrap_err();
    assert_eq!(err.reason(), "unknown_joint");
    assert!(err.to_string().contains("left_pinky"));
}
