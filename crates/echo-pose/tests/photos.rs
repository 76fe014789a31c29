//! The real model on real photographs (scikit-image's `astronaut.png`, 512 × 512: Eileen
//! Collins facing the camera, cut off at the waist; `camera.png`, 512 × 512 greyscale: a man in
//! profile behind a camera), both unpacked by `scripts/setup` into `.cache/photos/`.
//!
//! Reference points were set by looking at the photographs (drawn with a 25–50 pixel grid) and
//! are boxes, in pixels, around where each joint is:
//!
//! | photo, joint (the person's own side) | seen at | box x | box y |
//! |---|---|---|---|
//! | astronaut nose | tip at (222, 128) | 200–245 | 110–145 |
//! | astronaut right eye (image left) | (205, 103) | 190–222 | 88–120 |
//! | astronaut left eye (image right) | (248, 103) | 232–265 | 88–120 |
//! | astronaut right shoulder (image left) | joint under the suit, ~(110, 245) | 70–160 | 200–290 |
//! | astronaut left shoulder (image right) | ~(310, 255) | 265–350 | 210–300 |
//! | astronaut right elbow | sleeve bend at the left edge, ~(55, 410) | 20–110 | 340–460 |
//! | astronaut right wrist | above the glove's wrist ring, ~(160, 485) | 110–195 | 440–512 |
//! | astronaut hips | below the frame (the photo ends at her waist) | 60–320 | 430–620 |
//! | cameraman nose | tip at (251, 162) | 235–268 | 148–180 |
//! | cameraman right ear (near side) | (187, 138) | 170–210 | 120–160 |
//!
//! A MediaPipe 0.10.21 run of its own pipeline (detector + this landmark model, in Python) on
//! the same photographs agrees with these boxes (e.g. astronaut nose (223, 128), shoulders
//! (113, 240) and (306, 257)).
//!
//! Without the model or ONNX Runtime each test says why and passes, unless
//! `ECHO_REQUIRE_ASSETS` is set (CI runs `scripts/setup` first), where that is a failure.

use echo_msgs::{CameraIntrinsics, DepthImage, Header, Keypoints, Validate};
use echo_pose::{
    BlazePose, EstimatorConfig, Image, PixelFormat, PoseEstimator, PoseLandmarks,
    COCO17_FROM_BLAZEPOSE,
};

/// The estimator, or `None` (after saying why) when the model or ONNX Runtime is missing.
fn estimator() -> Option<PoseEstimator> {
    let missing = match (
        echo_pose::model::locate_model(),
        echo_onnx::runtime::locate_dylib(),
    ) {
        (Ok(model), Some(_)) => {
            let model = BlazePose::load(&model, 2).expect("the converted BlazePose model loads");
            return Some(PoseEstimator::new(model, EstimatorConfig::default()));
        }
        (Err(e), _) => e.to_string(),
        (_, None) => "ONNX Runtime not installed: run scripts/setup or set ECHO_ORT_DYLIB".into(),
    };
    // scripts/test (CI) runs scripts/setup first and sets ECHO_REQUIRE_ASSETS=1.
    assert!(
        std::env::var_os("ECHO_REQUIRE_ASSETS").is_none(),
        "{missing}"
    );
    eprintln!("skipping: {missing}");
    None
}

/// A photograph from `.cache/photos` (RGB or grey), or `None` when missing (see [`estimator`]).
fn photo(name: &str) -> Option<image::DynamicImage> {
    let dirs = echo_assets::cache_dirs("photos");
    if let Some(p) = dirs.iter().map(|d| d.join(name)).find(|p| p.is_file()) {
        return Some(image::open(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display())));
    }
    let msg = format!("test photo {name} not found in {dirs:?}: run scripts/setup");
    assert!(std::env::var_os("ECHO_REQUIRE_ASSETS").is_none(), "{msg}");
    eprintln!("skipping: {msg}");
    None
}

/// Both, or `None`.
fn assets(name: &str) -> Option<(PoseEstimator, image::RgbImage)> {
    let est = estimator()?;
    Some((est, photo(name)?.to_rgb8()))
}

fn rgb(img: &image::RgbImage) -> Image<'_> {
    Image::new(img.width(), img.height(), PixelFormat::Rgb8, img.as_raw()).unwrap()
}

/// COCO-17 index of a joint name.
fn coco(name: &str) -> usize {
    echo_msgs::KeypointFormat::Coco17
        .joint_names()
        .iter()
        .position(|n| *n == name)
        .unwrap()
}

/// The image point of COCO joint `name`.
fn at(lm: &PoseLandmarks, name: &str) -> (f32, f32) {
    let p = lm.image[COCO17_FROM_BLAZEPOSE[coco(name)]];
    (p.x, p.y)
}

fn assert_in(lm: &PoseLandmarks, name: &str, x: (f32, f32), y: (f32, f32)) {
    let (px, py) = at(lm, name);
    assert!(
        px >= x.0 && px <= x.1 && py >= y.0 && py <= y.1,
        "{name} at ({px:.0}, {py:.0}), expected x {x:?}, y {y:?}"
    );
}

fn describe(lm: &PoseLandmarks) -> String {
    let mut s = format!("presence {:.3}, crop {:?}\n", lm.presence, lm.roi);
    for name in echo_msgs::KeypointFormat::Coco17.joint_names() {
        let p = lm.image[COCO17_FROM_BLAZEPOSE[coco(name)]];
        s += &format!(
            "  {name:15} ({:6.1}, {:6.1}) visibility {:.2}\n",
            p.x, p.y, p.visibility
        );
    }
    s
}

fn mirrored(img: &image::RgbImage) -> image::RgbImage {
    image::imageops::flip_horizontal(img)
}

#[test]
fn one_person_in_the_astronaut_photo_and_her_keypoints_fall_on_her() {
    let Some((mut est, img)) = assets("astronaut.png") else {
        return;
    };
    let people = est.detect(&rgb(&img)).unwrap();
    assert_eq!(
        people.len(),
        1,
        "{:#?}",
        people.iter().map(describe).collect::<Vec<_>>()
    );
    let lm = &people[0];
    eprintln!("astronaut: {}", describe(lm));
    assert!(lm.presence >= 0.5);
    assert_in(lm, "nose", (200.0, 245.0), (110.0, 145.0));
    assert_in(lm, "right_eye", (190.0, 222.0), (88.0, 120.0));
    assert_in(lm, "left_eye", (232.0, 265.0), (88.0, 120.0));
    assert_in(lm, "right_shoulder", (70.0, 160.0), (200.0, 290.0));
    assert_in(lm, "left_shoulder", (265.0, 350.0), (210.0, 300.0));
    assert_in(lm, "right_elbow", (20.0, 110.0), (340.0, 460.0));
    assert_in(lm, "right_wrist", (110.0, 195.0), (440.0, 512.0));
    assert_in(lm, "left_hip", (60.0, 320.0), (430.0, 620.0));
    assert_in(lm, "right_hip", (60.0, 320.0), (430.0, 620.0));
    // Facing the camera, her left is on the image's right.
    for (l, r) in [
        ("left_eye", "right_eye"),
        ("left_shoulder", "right_shoulder"),
        ("left_hip", "right_hip"),
    ] {
        assert!(at(lm, l).0 > at(lm, r).0, "{l} should be right of {r}");
    }
    // Head and shoulders are plainly visible.
    for name in [
        "nose",
        "left_eye",
        "right_eye",
        "left_shoulder",
        "right_shoulder",
    ] {
        let v = lm.image[COCO17_FROM_BLAZEPOSE[coco(name)]].visibility;
        assert!(v > 0.9, "{name} visibility {v}");
    }
}

#[test]
fn a_mirrored_photo_swaps_left_and_right() {
    let Some((mut est, img)) = assets("astronaut.png") else {
        return;
    };
    let w = img.width() as f32;
    let orig = est.detect(&rgb(&img)).unwrap();
    let flipped = mirrored(&img);
    let mirr = est.detect(&rgb(&flipped)).unwrap();
    assert_eq!((orig.len(), mirr.len()), (1, 1));
    let (a, b) = (&orig[0], &mirr[0]);
    eprintln!("mirrored: {}", describe(b));
    for (l, r) in [
        ("left_eye", "right_eye"),
        ("left_shoulder", "right_shoulder"),
        ("left_ear", "right_ear"),
    ] {
        // What is the left joint in the mirrored photo is the right one in the photo, mirrored.
        for (m, o) in [(l, r), (r, l)] {
            let (mx, my) = at(b, m);
            let (ox, oy) = at(a, o);
            let d = (mx - (w - 1.0 - ox)).hypot(my - oy);
            assert!(d < 30.0, "mirrored {m} at ({mx:.0}, {my:.0}), photo's {o} at ({ox:.0}, {oy:.0}): {d:.0} px off");
        }
        // And still on the image's right for a person facing the camera.
        assert!(at(b, l).0 > at(b, r).0);
    }
}

#[test]
fn no_person_in_blank_or_noise_images() {
    let Some(mut est) = estimator() else {
        return;
    };
    let (w, h) = (640u32, 480u32);
    let grey = vec![128u8; (w * h * 3) as usize];
    let black = vec![0u8; (w * h * 3) as usize];
    // A fixed pseudo-random sequence (xorshift), so the test is the same every run.
    let mut s = 0x9E37_79B9_7F4A_7C15u64;
    let noise: Vec<u8> = (0..w * h * 3)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 24) as u8
        })
        .collect();
    for (name, buf) in [("grey", &grey), ("black", &black), ("noise", &noise)] {
        let img = Image::new(w, h, PixelFormat::Rgb8, buf).unwrap();
        let found = est.detect(&img).unwrap();
        assert!(
            found.is_empty(),
            "{name}: {:#?}",
            found.iter().map(describe).collect::<Vec<_>>()
        );
        let header = Header::new("r0", "pose-test", "head_front_camera_optical_frame");
        let f = est.process(header, &img, None, None).unwrap();
        assert!(f.people.is_empty(), "{name}");
    }
}

#[test]
fn the_cameraman_in_greyscale() {
    let (Some(mut est), Some(photo)) = (estimator(), photo("camera.png")) else {
        return;
    };
    let grey = photo.to_luma8();
    let img = Image::new(
        grey.width(),
        grey.height(),
        PixelFormat::Mono8,
        grey.as_raw(),
    )
    .unwrap();
    let people = est.detect(&img).unwrap();
    assert_eq!(
        people.len(),
        1,
        "{:#?}",
        people.iter().map(describe).collect::<Vec<_>>()
    );
    eprintln!("cameraman: {}", describe(&people[0]));
    assert_in(&people[0], "nose", (235.0, 268.0), (148.0, 180.0));
    assert_in(&people[0], "right_ear", (170.0, 210.0), (120.0, 160.0));
}

#[test]
fn two_people_side_by_side_are_two_detections_and_tracks() {
    let Some((mut est, img)) = assets("astronaut.png") else {
        return;
    };
    // The photo and its mirror image side by side: two people, 512 pixels apart.
    let (w, h) = (img.width(), img.height());
    let mut both = image::RgbImage::new(2 * w, h);
    image::imageops::replace(&mut both, &img, 0, 0);
    image::imageops::replace(&mut both, &mirrored(&img), w as i64, 0);
    let frame = rgb(&both);
    let people = est.track(&frame).unwrap();
    assert_eq!(
        people.len(),
        2,
        "{:#?}",
        people
            .iter()
            .map(|p| describe(&p.landmarks))
            .collect::<Vec<_>>()
    );
    let mut noses: Vec<(u32, f32)> = people
        .iter()
        .map(|p| (p.id, at(&p.landmarks, "nose").0))
        .collect();
    noses.sort_by(|a, b| a.1.total_cmp(&b.1));
    assert!(noses[0].1 < w as f32 && noses[1].1 > w as f32, "{noses:?}");
    assert_ne!(noses[0].0, noses[1].0);
    // The next frames follow both with the same ids, each on their own crop.
    for _ in 0..3 {
        let again = est.track(&frame).unwrap();
        let mut ids: Vec<(u32, f32)> = again
            .iter()
            .map(|p| (p.id, at(&p.landmarks, "nose").0))
            .collect();
        ids.sort_by(|a, b| a.1.total_cmp(&b.1));
        assert_eq!(ids.len(), 2);
        assert_eq!((ids[0].0, ids[1].0), (noses[0].0, noses[1].0));
        for (a, b) in ids.iter().zip(&noses) {
            assert!(
                (a.1 - b.1).abs() < 20.0,
                "nose moved from {} to {}",
                b.1,
                a.1
            );
        }
    }
}

#[test]
fn the_bridge_gets_a_valid_frame_with_3d() {
    let Some((mut est, img)) = assets("astronaut.png") else {
        return;
    };
    let (w, h) = (img.width(), img.height());
    let cam = CameraIntrinsics {
        fx: 500.0,
        fy: 500.0,
        cx: 255.5,
        cy: 255.5,
        width: w,
        height: h,
    };
    let header = Header::new("r0", "pose-test", "head_front_camera_optical_frame");
    let frame = rgb(&img);

    // Intrinsics, no depth: pixels plus the model's depth at the fitted distance.
    let f = est
        .process(header.clone(), &frame, None, Some(&cam))
        .unwrap();
    f.validate().unwrap();
    assert_eq!(f.people.len(), 1);
    assert_eq!(f.camera, Some(cam));
    let Keypoints::PixelsDepth { uv, depth_m } = &f.people[0].keypoints else {
        panic!("pixel keypoints expected");
    };
    let d = depth_m.as_ref().unwrap();
    // A head-and-torso portrait filling a 500-pixel-focal frame: about 1 m away.
    let (ls, rs) = (coco("left_shoulder"), coco("right_shoulder"));
    eprintln!("shoulder depths {:.2} {:.2}", d[ls], d[rs]);
    for k in [coco("nose"), ls, rs] {
        assert!(d[k] > 0.5 && d[k] < 2.0, "keypoint {k} at {:.2} m", d[k]);
    }
    // Shoulder width from the lifted points: an adult's, 0.25–0.5 m.
    let lift = |k: usize| {
        [
            (uv[k][0] - cam.cx) * d[k] / cam.fx,
            (uv[k][1] - cam.cy) * d[k] / cam.fy,
            d[k],
        ]
    };
    let (a, b) = (lift(ls), lift(rs));
    let width = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    assert!(width > 0.25 && width < 0.5, "shoulder width {width:.2} m");
    for (k, c) in f.people[0].confidence.iter().enumerate() {
        assert!((0.0..=1.0).contains(c), "confidence {k}: {c}");
    }

    // An aligned depth image (a flat 1.5 m): keypoints on her take the readings.
    let depth = DepthImage {
        width: w,
        height: h,
        depth_mm: vec![1500; (w * h) as usize],
    };
    est.reset();
    let f = est
        .process(header.clone(), &frame, Some(&depth), Some(&cam))
        .unwrap();
    f.validate().unwrap();
    let Keypoints::PixelsDepth { depth_m, .. } = &f.people[0].keypoints else {
        panic!("pixel keypoints expected");
    };
    let d = depth_m.as_ref().unwrap();
    for k in [coco("nose"), ls, rs] {
        assert!((d[k] - 1.5).abs() <= 0.3, "keypoint {k} at {:.2} m", d[k]);
    }

    // No intrinsics: 3D points in front of a nominal camera.
    let f = est.process(header.clone(), &frame, None, None).unwrap();
    f.validate().unwrap();
    let Keypoints::Points3d { xyz } = &f.people[0].keypoints else {
        panic!("3D keypoints expected");
    };
    assert!(xyz[0][2] > 0.3 && xyz[0][2] < 3.0, "nose at {:?}", xyz[0]);
    // The nose is above (y down) and between the shoulders.
    assert!(xyz[0][1] < xyz[ls][1] && xyz[0][1] < xyz[rs][1]);
    assert!(xyz[rs][0] < xyz[0][0] && xyz[0][0] < xyz[ls][0]);

    // Inputs that do not fit are errors, not panics.
    let small = DepthImage {
        width: 10,
        height: 10,
        depth_mm: vec![0; 100],
    };
    assert!(est
        .process(header.clone(), &frame, Some(&small), Some(&cam))
        .is_err());
    assert!(est.process(header, &frame, Some(&depth), None).is_err());
}
