//! The camera path as processes over Zenoh on loopback: the pose estimator (BlazePose on ONNX
//! Runtime) turns photographs into keypoint frames, and the perception bridge turns those into
//! tracked skeletons in `base_footprint`, with the simulated robot's joint states placing the
//! head camera.
//!
//! - Images in, skeletons out (`--images`): `camera.png` (scikit-image's cameraman, 512 × 512:
//!   a man from head to shins, hips in view) looped at 5 frames/s. `astronaut.png` is not used
//!   here: the photo ends at her waist, her right hip on its bottom edge. On the frames where
//!   the model puts that hip just outside the image (confidence 0), COCO-17 → SMPL-22 has no
//!   pelvis (nor spine or neck, blends of both hips) and the bridge rejects the frame
//!   (`perception_raw/no_pelvis`, or `too_few_joints` below its 10 joints, in its status), so
//!   she is tracked on only about half of the skeleton frames.
//! - ROS 2 (`--ros2-namespace`): the test plays zenoh-bridge-ros2dds, publishing CDR
//!   `sensor_msgs/Image` (`astronaut.png` as rgb8) and `sensor_msgs/CameraInfo`, then a
//!   truncated sample, a wrong encoding and a stale stamp, which the service must count in its
//!   status while it keeps estimating.
//!
//! Without the model, ONNX Runtime or the photos each test says why and passes, unless
//! `ECHO_REQUIRE_ASSETS` is set (CI runs `scripts/setup` first), where that is a failure.

use std::path::PathBuf;
use std::time::Duration;

use echo_bus::topics;
use echo_motion::skeleton::j;
use echo_msgs::{
    frames, now_ns, CameraIntrinsics, HumanSkeletons, KeypointFormat, KeypointFrame, Keypoints,
    ServiceStatus, Validate,
};
use echo_perception::lift::back_project;
use echo_robot::RobotModel;
use echo_ros2::image::{RegionOfInterest, RosCameraInfo, RosImage};
use echo_ros2::{encode, ros_key, RosHeader, Time};
use echo_system_tests::Harness;
use nalgebra::{Point3, Vector3};

/// The photo `name` from `.cache/photos`, or `None` (after saying why) when it, the BlazePose
/// model or ONNX Runtime is missing.
fn assets(name: &str) -> Option<PathBuf> {
    let dirs = echo_assets::cache_dirs("photos");
    let missing = match (
        echo_pose::model::locate_model(),
        echo_onnx::runtime::locate_dylib(),
        dirs.iter().map(|d| d.join(name)).find(|p| p.is_file()),
    ) {
        (Ok(_), Some(_), Some(photo)) => return Some(photo),
        (Err(e), _, _) => e.to_string(),
        (_, None, _) => {
            "ONNX Runtime not installed: run scripts/setup or set ECHO_ORT_DYLIB".into()
        }
        (_, _, None) => format!("test photo {name} not found in {dirs:?}: run scripts/setup"),
    };
    // scripts/test (CI) runs scripts/setup first and sets ECHO_REQUIRE_ASSETS=1.
    assert!(
        std::env::var_os("ECHO_REQUIRE_ASSETS").is_none(),
        "{missing}"
    );
    eprintln!("skipping: {missing}");
    None
}

/// COCO-17 index of a joint name.
fn coco(name: &str) -> usize {
    KeypointFormat::Coco17
        .joint_names()
        .iter()
        .position(|n| *n == name)
        .unwrap_or_else(|| panic!("{name} is not a COCO-17 joint"))
}

/// The structural checks every frame from the estimator must pass: COCO-17, pixel keypoints
/// with a finite depth in the estimator's accepted range, confidences in [0, 1], the
/// calibration it was given, exactly one person. Returns that person's (uv, depth, confidence).
fn one_person(f: &KeypointFrame) -> (Vec<[f64; 2]>, Vec<f64>, Vec<f64>) {
    f.validate().expect("a valid keypoint frame");
    assert_eq!(f.format, KeypointFormat::Coco17);
    assert!(f.joint_names.is_none(), "all 17 joints in COCO order");
    assert_eq!(f.people.len(), 1, "one person in the photo");
    let p = &f.people[0];
    assert_eq!(p.confidence.len(), 17);
    assert!(
        p.confidence.iter().all(|c| (0.0..=1.0).contains(c)),
        "{:?}",
        p.confidence
    );
    let Keypoints::PixelsDepth {
        uv,
        depth_m: Some(depth),
    } = &p.keypoints
    else {
        panic!("pixel keypoints with depth expected: {:?}", p.keypoints)
    };
    assert_eq!((uv.len(), depth.len()), (17, 17));
    assert!(uv.as_flattened().iter().all(|v| v.is_finite()), "{uv:?}");
    let (near, far) = echo_pose::keypoints::DISTANCE_RANGE_M;
    assert!(
        depth
            .iter()
            .all(|d| d.is_finite() && *d > near - 1.0 && *d < far + 1.0),
        "{depth:?}"
    );
    (uv.clone(), depth.clone(), p.confidence.clone())
}

/// Whether a pixel lies on the camera's image (pixel-centre convention).
fn on_image(p: [f64; 2], cam: &CameraIntrinsics) -> bool {
    p[0] >= -0.5 && p[1] >= -0.5 && p[0] < cam.width as f64 - 0.5 && p[1] < cam.height as f64 - 0.5
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn photos_in_tracked_skeletons_out() -> anyhow::Result<()> {
    let Some(photo) = assets("camera.png") else {
        return Ok(());
    };
    let dir = tempfile::tempdir()?;
    for k in 0..3 {
        std::fs::copy(&photo, dir.path().join(format!("frame_{k:03}.png")))?;
    }
    let mut h = Harness::new("sys-camera", 3)?;
    h.spawn_services("single", &["mock-robot", "perception-bridge"])?;
    let images = dir.path().to_str().unwrap_or_default();
    h.spawn(
        "pose-estimator",
        "pose-estimator",
        &["--images", images, "--fps", "5", "--loop"],
    )?;
    let bus = h.bus("system-test").await?;
    let robot = bus.robot().clone();
    let raw = bus.subscribe(&topics::perception_raw(&robot)).await?;
    let humans = bus.subscribe(&topics::humans(&robot)).await?;
    let states = bus.subscribe(&topics::robot_state(&robot)).await?;
    let bridge_status = bus
        .subscribe(&topics::service_status(&robot, "perception-bridge"))
        .await?;
    h.wait_alive(
        &bus,
        &["mock-robot", "perception-bridge", "pose-estimator"],
        Duration::from_secs(60),
    )
    .await?;

    // Collect until enough of both have arrived (the deadline only bounds the wait).
    let (mut frames, mut skeletons): (Vec<KeypointFrame>, Vec<HumanSkeletons>) = (vec![], vec![]);
    let mut last_state = None;
    let deadline = tokio::time::Instant::now() + Duration::from_secs(60);
    while (frames.len() < 10 || skeletons.len() < 30) && tokio::time::Instant::now() < deadline {
        frames.extend(raw.drain().into_iter().map(|r| r.msg));
        if let Some(s) = states.drain().pop() {
            last_state = Some(s.msg);
        }
        if let Ok(Some(s)) = tokio::time::timeout(Duration::from_millis(200), humans.recv()).await {
            assert_eq!(s.msg.header.frame_id, frames::BASE_FOOTPRINT);
            if !s.msg.tracks.is_empty() {
                skeletons.push(s.msg);
            }
        }
    }
    let status: Option<ServiceStatus> = bridge_status.drain().pop().map(|s| s.msg);
    assert!(
        frames.len() >= 10 && skeletons.len() >= 30,
        "{} keypoint frames, {} skeleton frames with a track; bridge status {status:?}\n\
         --- pose-estimator log:\n{}",
        frames.len(),
        skeletons.len(),
        h.log_tail("pose-estimator")
    );

    // Keypoints: the photo's man, seen from the head down to the shins. His nose, eyes and
    // shoulders are in the photo (the model is sure of them); his ankles lie at or below its
    // bottom edge, and a keypoint off the image is reported as not seen.
    let (mut camera, mut off_image) = (None, 0);
    for f in &frames {
        assert!(f.header.source.starts_with(pose_estimator::SERVICE));
        assert_eq!(f.header.frame_id, pose_estimator::DEFAULT_FRAME);
        let cam = f.camera.expect("the nominal camera of an image folder");
        let (uv, _, conf) = one_person(f);
        for name in [
            "nose",
            "left_eye",
            "right_eye",
            "left_shoulder",
            "right_shoulder",
        ] {
            let k = coco(name);
            assert!(
                on_image(uv[k], &cam) && conf[k] > 0.5,
                "{name}: {:?} {}",
                uv[k],
                conf[k]
            );
        }
        for k in 0..17 {
            if !on_image(uv[k], &cam) {
                assert_eq!(conf[k], 0.0, "keypoint {k} at {:?}", uv[k]);
                off_image += 1;
            }
        }
        camera = Some(cam);
    }
    assert!(off_image > 0, "the ankles are below the photo");
    let cam = camera.expect("a calibration");

    // Where the man should be, by the test's own geometry: the last keypoint frame's pixels
    // and depths back-projected through its intrinsics (X = (u − cx)·z/fx, …), placed by the
    // URDF's forward kinematics of the camera frame at the robot's measured joints (still: the
    // mock robot holds its home pose). The bridge's pelvis is 16 % of the way from the hip
    // midpoint to the shoulder midpoint, its head the midpoint of the ears (echo-perception's
    // COCO-17 map).
    let state = last_state.expect("joint states from the mock robot");
    let model = RobotModel::tiago_dual();
    let q = model.known_values(
        state
            .name
            .iter()
            .map(String::as_str)
            .zip(state.position.iter().copied()),
    );
    let cam_pose = model.fk(&q, pose_estimator::DEFAULT_FRAME)?;
    let last = frames.last().expect("a frame");
    let (uv, depth, _) = one_person(last);
    let at = |name: &str| {
        let k = coco(name);
        let p = back_project(&cam, uv[k][0], uv[k][1], depth[k]);
        (cam_pose * Point3::from(p)).coords
    };
    let mid = |a: &str, b: &str| (at(a) + at(b)) / 2.0;
    let hips = mid("left_hip", "right_hip");
    let shoulders_mid = mid("left_shoulder", "right_shoulder");
    let want_pelvis = hips + (shoulders_mid - hips) * 0.16;
    let want_head = mid("left_ear", "right_ear");
    eprintln!(
        "camera at {:.2?} in base_footprint; expected pelvis {:.2?}, head {:.2?}",
        cam_pose.translation.vector.as_slice(),
        want_pelvis.as_slice(),
        want_head.as_slice()
    );

    // Skeletons: one track, in front of the robot, standing upright.
    let mut ids = std::collections::BTreeSet::new();
    for s in &skeletons {
        s.validate().expect("valid skeletons");
        assert_eq!(s.tracks.len(), 1, "one person, one track");
        let t = &s.tracks[0];
        ids.insert(t.track_id);
        let joint = |k: usize| Vector3::from(t.pose.joints[k]);
        let (pelvis, head) = (joint(j::PELVIS), joint(j::HEAD));
        let shoulders = (joint(j::L_SHOULDER) + joint(j::R_SHOULDER)) / 2.0;
        // In front (x > 0) and within 45° of straight ahead (|y| < x; the nominal camera sees
        // ±31° and the robot's head looks straight ahead), at about the distance the estimator
        // placed him (0.7–1.5 m from the camera; the camera is 0.2 m ahead of the base's
        // centre, 1.2 m up).
        assert!(
            pelvis.x > 0.3 && pelvis.x < 3.0 && pelvis.y.abs() < pelvis.x,
            "pelvis at {pelvis:?}"
        );
        // The man stands on the image's left: the robot's left (+y).
        assert!(pelvis.y > 0.0, "pelvis at {pelvis:?}");
        // Upright: the head above the shoulders' centre and the shoulders above the pelvis.
        assert!(
            head.z > shoulders.z,
            "head {head:?}, shoulders {shoulders:?}"
        );
        assert!(
            shoulders.z > pelvis.z + 0.2,
            "shoulders {shoulders:?}, pelvis {pelvis:?}"
        );
        // The test's own lifting agrees with the bridge's to within the estimator's frame-to-
        // frame jitter on a still photo and the bridge's smoothing (a few centimetres).
        assert!(
            (pelvis - want_pelvis).norm() < 0.1,
            "pelvis {pelvis:?}, expected {want_pelvis:?}"
        );
        assert!(
            (head - want_head).norm() < 0.1,
            "head {head:?}, expected {want_head:?}"
        );
    }
    assert_eq!(ids.len(), 1, "the track keeps its id: {ids:?}");
    let t = &skeletons.last().expect("a skeleton").tracks[0];
    eprintln!(
        "{} keypoint frames, {} skeleton frames; pelvis {:.2?}, shoulders {:.2?} {:.2?}, head \
         {:.2?}",
        frames.len(),
        skeletons.len(),
        t.pose.joints[j::PELVIS],
        t.pose.joints[j::L_SHOULDER],
        t.pose.joints[j::R_SHOULDER],
        t.pose.joints[j::HEAD]
    );
    for label in ["mock-robot", "perception-bridge", "pose-estimator"] {
        assert!(h.is_running(label), "{label} stopped");
    }
    assert!(
        h.stop("pose-estimator", Duration::from_secs(5)),
        "clean shutdown on SIGTERM"
    );
    Ok(())
}

/// The ROS 2 namespace the test's stand-in bridge publishes under.
const NS: &str = "/tiago";

fn ros_header(stamp_ns: u64) -> RosHeader {
    RosHeader {
        stamp: Time::from_ns(stamp_ns),
        frame_id: pose_estimator::DEFAULT_FRAME.into(),
    }
}

/// `sensor_msgs/CameraInfo` of a pinhole `w × h` camera with focal length `f`.
fn camera_info(w: u32, h: u32, f: f64) -> RosCameraInfo {
    let (cx, cy) = ((w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0);
    RosCameraInfo {
        header: ros_header(now_ns()),
        height: h,
        width: w,
        distortion_model: "plumb_bob".into(),
        d: vec![0.0; 5],
        k: [f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0],
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: [f, 0.0, cx, 0.0, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
        binning_x: 0,
        binning_y: 0,
        roi: RegionOfInterest::default(),
    }
}

/// `sensor_msgs/Image` (rgb8) of `photo`, stamped `stamp_ns`.
fn rgb_image(photo: &image::RgbImage, stamp_ns: u64) -> RosImage {
    RosImage {
        header: ros_header(stamp_ns),
        height: photo.height(),
        width: photo.width(),
        encoding: "rgb8".into(),
        is_bigendian: 0,
        step: photo.width() * 3,
        data: photo.as_raw().clone(),
    }
}

/// Publish one sample.
async fn put(p: &zenoh::pubsub::Publisher<'_>, bytes: Vec<u8>) -> anyhow::Result<()> {
    p.put(bytes).await.map_err(|e| anyhow::anyhow!("{e}"))
}

/// Rejections of the camera input by reason in a status.
fn camera_rejections(s: &ServiceStatus, reason: &str) -> u64 {
    let key = format!("{}/{reason}", pose_estimator::INPUT_EDGE);
    s.rejected.get(&key).copied().unwrap_or(0)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ros2_camera_in_keypoints_out_and_bad_images_counted() -> anyhow::Result<()> {
    let Some(path) = assets("astronaut.png") else {
        return Ok(());
    };
    let photo = image::open(&path)?.to_rgb8();
    let (w, hgt) = photo.dimensions();
    let mut h = Harness::new("sys-camera-ros2", 1)?;
    h.spawn(
        "pose-estimator",
        "pose-estimator",
        &["--ros2-namespace", NS],
    )?;
    let bus = h.bus("ros2-bridge").await?;
    let robot = bus.robot().clone();
    let raw = bus.subscribe(&topics::perception_raw(&robot)).await?;
    let status = bus
        .subscribe(&topics::service_status(&robot, pose_estimator::SERVICE))
        .await?;
    let s = bus.session();
    let image_key = ros_key(NS, echo_ros2::image::HEAD_RGB_TOPIC);
    let images = s
        .declare_publisher(image_key)
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let infos = s
        .declare_publisher(ros_key(NS, echo_ros2::image::HEAD_RGB_INFO_TOPIC))
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    h.wait_alive(&bus, &[pose_estimator::SERVICE], Duration::from_secs(60))
        .await?;

    let focal = 420.0;
    let info = encode(&camera_info(w, hgt, focal))?;

    // Good frames at 5 Hz, each with a fresh stamp, until ten keypoint frames came back.
    let mut sent = std::collections::BTreeSet::new();
    let mut got: Vec<KeypointFrame> = vec![];
    let deadline = tokio::time::Instant::now() + Duration::from_secs(60);
    while got.len() < 10 && tokio::time::Instant::now() < deadline {
        put(&infos, info.clone()).await?;
        let stamp = now_ns();
        sent.insert(stamp);
        put(&images, encode(&rgb_image(&photo, stamp))?).await?;
        tokio::time::sleep(Duration::from_millis(200)).await;
        got.extend(raw.drain().into_iter().map(|r| r.msg));
    }
    assert!(
        got.len() >= 10,
        "{} keypoint frames from the ROS 2 camera\n--- pose-estimator log:\n{}",
        got.len(),
        h.log_tail(pose_estimator::SERVICE)
    );
    for f in &got {
        // The frame is the image's: its capture stamp, its optical frame, its calibration.
        assert!(
            sent.contains(&f.header.stamp_ns),
            "stamp {}",
            f.header.stamp_ns
        );
        assert_eq!(f.header.frame_id, pose_estimator::DEFAULT_FRAME);
        let cam = f.camera.expect("the camera info's intrinsics");
        assert_eq!(
            (cam.fx, cam.fy, cam.width, cam.height),
            (focal, focal, w, hgt)
        );
        let (uv, _, conf) = one_person(f);
        // The pixels arrived in order (rows, stride, channels): her face is where it is in the
        // photograph (boxes from crates/echo-pose/tests/photos.rs, set by eye).
        for (name, x, y) in [
            ("nose", (200.0, 245.0), (110.0, 145.0)),
            ("right_eye", (190.0, 222.0), (88.0, 120.0)),
            ("left_eye", (232.0, 265.0), (88.0, 120.0)),
        ] {
            let [u, v] = uv[coco(name)];
            assert!(
                (x.0..=x.1).contains(&u) && (y.0..=y.1).contains(&v),
                "{name} at ({u:.0}, {v:.0})"
            );
            assert!(conf[coco(name)] > 0.5, "{name}: {}", conf[coco(name)]);
        }
    }

    // Bad samples, one at a time so that each is taken before the next replaces it (the
    // service keeps only the newest image), until the status shows every reason.
    let mut truncated = encode(&rgb_image(&photo, now_ns()))?;
    truncated.truncate(truncated.len() / 2);
    let mut short_data = rgb_image(&photo, now_ns());
    short_data
        .data
        .truncate(short_data.data.len() - 3 * w as usize);
    let mut wrong_encoding = rgb_image(&photo, now_ns());
    wrong_encoding.encoding = "yuv422".into();
    let mut last: Option<ServiceStatus> = None;
    let reasons = |s: &ServiceStatus| {
        (
            camera_rejections(s, "invalid"),
            camera_rejections(s, "stale"),
        )
    };
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    while tokio::time::Instant::now() < deadline {
        let stale = rgb_image(&photo, now_ns() - 2_000_000_000);
        for bad in [
            truncated.clone(),
            encode(&short_data)?,
            encode(&wrong_encoding)?,
            encode(&stale)?,
        ] {
            put(&images, bad).await?;
            tokio::time::sleep(Duration::from_millis(300)).await;
        }
        if let Some(s) = status.drain().pop() {
            last = Some(s.msg);
        }
        if last
            .as_ref()
            .is_some_and(|s| reasons(s).0 >= 3 && reasons(s).1 >= 1)
        {
            break;
        }
    }
    let st = last.expect("a status from the pose estimator");
    let (invalid, stale) = reasons(&st);
    assert!(
        invalid >= 3 && stale >= 1,
        "rejections {:?}, last error {:?}",
        st.rejected,
        st.last_error
    );
    assert!(st.last_error.is_some());
    assert!(
        h.is_running(pose_estimator::SERVICE),
        "the service survived the bad samples"
    );

    // And it goes on estimating.
    raw.drain();
    let mut after = 0;
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    while after < 3 && tokio::time::Instant::now() < deadline {
        put(&infos, info.clone()).await?;
        let stamp = now_ns();
        put(&images, encode(&rgb_image(&photo, stamp))?).await?;
        tokio::time::sleep(Duration::from_millis(200)).await;
        for f in raw.drain() {
            one_person(&f.msg);
            after += 1;
        }
    }
    assert!(
        after >= 3,
        "only {after} keypoint frames after the bad samples"
    );
    assert!(
        h.stop(pose_estimator::SERVICE, Duration::from_secs(5)),
        "clean shutdown on SIGTERM"
    );
    Ok(())
}
