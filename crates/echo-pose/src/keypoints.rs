//! From the model's landmarks to the bridge's `KeypointFrame` (COCO-17), with depth from the
//! aligned depth image where it agrees with the model, else from the model's metric pose
//! placed in front of the camera (rules in the crate documentation).

use echo_msgs::{
    CameraIntrinsics, DepthImage, DetectedPerson, Header, KeypointFormat, KeypointFrame, Keypoints,
};
use echo_perception::lift::sample_depth;

use crate::estimator::Person;
use crate::model::{Landmark, PoseLandmarks, BODY_LANDMARKS};
use crate::PoseError;

/// BlazePose landmark of each COCO-17 keypoint, in COCO order (nose, eyes, ears, shoulders,
/// elbows, wrists, hips, knees, ankles; left before right).
pub const COCO17_FROM_BLAZEPOSE: [usize; 17] = [
    0, 2, 5, 7, 8, 11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28,
];

/// Horizontal field of view assumed when no intrinsics are given: the TIAGo++ head camera's
/// (~62°, fx = 522 px at 640 px wide).
pub const NOMINAL_FX_PER_WIDTH: f64 = 522.0 / 640.0;

/// A sampled depth is used for a keypoint when it is within this of the model's depth for it
/// (else the window hit the background or an occluder).
pub const DEPTH_AGREEMENT_M: f64 = 0.3;

/// Body points that take part in placing a person: visible with at least this probability.
pub const FIT_VISIBILITY: f32 = 0.5;

/// Distances accepted for a person's hip centre, metres.
pub const DISTANCE_RANGE_M: (f64, f64) = (0.2, 30.0);

/// The pinhole assumed for a `width × height` image without intrinsics: [`NOMINAL_FX_PER_WIDTH`],
/// square pixels, principal point at the centre.
pub fn nominal_camera(width: u32, height: u32) -> CameraIntrinsics {
    let f = NOMINAL_FX_PER_WIDTH * width as f64;
    CameraIntrinsics {
        fx: f,
        fy: f,
        cx: (width as f64 - 1.0) / 2.0,
        cy: (height as f64 - 1.0) / 2.0,
        width,
        height,
    }
}

/// Checks the optional depth image and intrinsics against a `width × height` colour image.
pub fn check_inputs(
    width: u32,
    height: u32,
    depth: Option<&DepthImage>,
    camera: Option<&CameraIntrinsics>,
) -> Result<(), PoseError> {
    if let Some(c) = camera {
        if ![c.fx, c.fy, c.cx, c.cy].iter().all(|v| v.is_finite()) || c.fx <= 0.0 || c.fy <= 0.0 {
            return Err(PoseError::InvalidIntrinsics);
        }
        if (c.width, c.height) != (width, height) {
            return Err(PoseError::IntrinsicsSize {
                camera: (c.width, c.height),
                image: (width, height),
            });
        }
    }
    if let Some(d) = depth {
        if camera.is_none() {
            return Err(PoseError::DepthWithoutIntrinsics);
        }
        if (d.width, d.height) != (width, height)
            || d.depth_mm.len() != d.width as usize * d.height as usize
        {
            return Err(PoseError::DepthSize {
                depth: (d.width, d.height),
                values: d.depth_mm.len(),
                image: (width, height),
            });
        }
    }
    Ok(())
}

/// Whether a landmark lies on the image (pixel-centre coordinates).
fn in_image(p: &Landmark, width: u32, height: u32) -> bool {
    p.x >= -0.5 && p.y >= -0.5 && p.x < width as f32 - 0.5 && p.y < height as f32 - 0.5
}

/// Indices of the body points that place a person: visible ones inside the image; when fewer
/// than 4, every one inside the image.
fn fit_points(lm: &PoseLandmarks, width: u32, height: u32) -> Vec<usize> {
    let inside = |i: &usize| in_image(&lm.image[*i], width, height);
    let visible: Vec<usize> = (0..BODY_LANDMARKS)
        .filter(inside)
        .filter(|&i| lm.image[i].visibility >= FIT_VISIBILITY)
        .collect();
    if visible.len() >= 4 {
        visible
    } else {
        (0..BODY_LANDMARKS).filter(inside).collect()
    }
}

/// Where the hip centre lies in the camera's optical frame (metres), with no depth: the shift
/// `t` that best makes the model's metric pose, `world + t`, project through `cam` onto the
/// image landmarks. Each fitting point gives two equations linear in `t`,
/// `(u − cx)/fx · (Z + tz) = X + tx` and the same for v, solved by least squares weighted by
/// visibility. The distance thus comes from the person's pixel size against the model's metric
/// size (a person much taller or shorter than the model assumes is placed too near or too
/// far). `None` when fewer than 3 points, degenerate, or outside [`DISTANCE_RANGE_M`].
pub fn fit_translation(
    lm: &PoseLandmarks,
    cam: &CameraIntrinsics,
    width: u32,
    height: u32,
) -> Option<[f64; 3]> {
    let pts = fit_points(lm, width, height);
    if pts.len() < 3 {
        return None;
    }
    // Normal equations of rows (-1, 0, a)·t = X − aZ and (0, -1, b)·t = Y − bZ.
    let (mut sw, mut swa, mut swb, mut swq) = (0.0f64, 0.0, 0.0, 0.0);
    let (mut rx, mut ry, mut rz) = (0.0f64, 0.0, 0.0);
    for &i in &pts {
        let w = (lm.image[i].visibility as f64).max(1e-3);
        let a = (lm.image[i].x as f64 - cam.cx) / cam.fx;
        let b = (lm.image[i].y as f64 - cam.cy) / cam.fy;
        let [x, y, z] = lm.world[i].map(|v| v as f64);
        let (ex, ey) = (x - a * z, y - b * z);
        sw += w;
        swa += w * a;
        swb += w * b;
        swq += w * (a * a + b * b);
        rx -= w * ex;
        ry -= w * ey;
        rz += w * (a * ex + b * ey);
    }
    // [[sw, 0, -swa], [0, sw, -swb], [-swa, -swb, swq]] · t = [rx, ry, rz]
    let det = sw * (sw * swq - swb * swb) - swa * swa * sw;
    if !det.is_finite() || det.abs() <= 1e-8 * sw.powi(3) {
        return None;
    }
    // Eliminate tx and ty: tx = (rx + swa·tz)/sw, ty = (ry + swb·tz)/sw.
    let tz = (rz + (swa * rx + swb * ry) / sw) / (swq - (swa * swa + swb * swb) / sw);
    let tx = (rx + swa * tz) / sw;
    let ty = (ry + swb * tz) / sw;
    let t = [tx, ty, tz];
    (t.iter().all(|v| v.is_finite()) && tz >= DISTANCE_RANGE_M.0 && tz <= DISTANCE_RANGE_M.1)
        .then_some(t)
}

/// The depth of the hip centre from the depth image: the median, over the fitting points
/// with a reading, of `reading − world z` (each reading minus the point's depth relative to
/// the hips). `None` with fewer than 3 readings.
pub fn hip_depth_from_image(
    lm: &PoseLandmarks,
    depth: &DepthImage,
    width: u32,
    height: u32,
) -> Option<f64> {
    let mut v: Vec<f64> = fit_points(lm, width, height)
        .into_iter()
        .filter_map(|i| {
            let p = &lm.image[i];
            sample_depth(depth, p.x as f64, p.y as f64).map(|d| d - lm.world[i][2] as f64)
        })
        .collect();
    if v.len() < 3 {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let hip = v[v.len() / 2];
    (hip >= DISTANCE_RANGE_M.0 && hip <= DISTANCE_RANGE_M.1).then_some(hip)
}

/// A keypoint's confidence: the model's probabilities that it is in the crop (presence) and
/// not occluded (visibility), multiplied; 0 when it lies outside the image (the model guessed
/// it: the bridge takes 0 as not seen).
pub fn keypoint_confidence(p: &Landmark, width: u32, height: u32) -> f64 {
    match in_image(p, width, height) {
        true => (p.visibility as f64 * p.presence as f64).clamp(0.0, 1.0),
        false => 0.0,
    }
}

/// One person as the bridge takes them, or `None` when they cannot be placed in 3D.
///
/// - With intrinsics: pixel keypoints plus a depth per keypoint. With a depth image, a
///   keypoint's depth is the bridge's own sample (median of the 5 × 5 window) when it agrees
///   with the model's depth for it ([`DEPTH_AGREEMENT_M`]), else the model's: the hip depth
///   from [`hip_depth_from_image`] plus the keypoint's world z. Without a depth image (or
///   with too few readings on the person), the model's depth placed by [`fit_translation`].
/// - Without intrinsics: 3D points, `world + t` with `t` fitted through [`nominal_camera`].
///
/// Confidence: [`keypoint_confidence`].
pub fn detected_person(
    person: &Person,
    width: u32,
    height: u32,
    depth: Option<&DepthImage>,
    camera: Option<&CameraIntrinsics>,
) -> Option<DetectedPerson> {
    let lm = &person.landmarks;
    let confidence: Vec<f64> = COCO17_FROM_BLAZEPOSE
        .iter()
        .map(|&i| keypoint_confidence(&lm.image[i], width, height))
        .collect();
    let keypoints = match camera {
        Some(cam) => {
            let from_image = depth.and_then(|d| hip_depth_from_image(lm, d, width, height));
            let hip = match from_image {
                Some(h) => h,
                None => fit_translation(lm, cam, width, height)?[2],
            };
            let mut uv = Vec::with_capacity(17);
            let mut depth_m = Vec::with_capacity(17);
            for &i in &COCO17_FROM_BLAZEPOSE {
                let p = &lm.image[i];
                let model = hip + lm.world[i][2] as f64;
                let sampled = match (from_image, depth) {
                    (Some(_), Some(d)) => sample_depth(d, p.x as f64, p.y as f64),
                    _ => None,
                };
                depth_m.push(match sampled {
                    Some(s) if (s - model).abs() <= DEPTH_AGREEMENT_M => s,
                    _ => model,
                });
                uv.push([p.x as f64, p.y as f64]);
            }
            Keypoints::PixelsDepth {
                uv,
                depth_m: Some(depth_m),
            }
        }
        None => {
            let t = fit_translation(lm, &nominal_camera(width, height), width, height)?;
            Keypoints::Points3d {
                xyz: COCO17_FROM_BLAZEPOSE
                    .iter()
                    .map(|&i| {
                        let w = lm.world[i];
                        [w[0] as f64 + t[0], w[1] as f64 + t[1], w[2] as f64 + t[2]]
                    })
                    .collect(),
            }
        }
    };
    let finite = match &keypoints {
        Keypoints::PixelsDepth { uv, depth_m } => {
            uv.as_flattened().iter().all(|v| v.is_finite())
                && depth_m.iter().flatten().all(|v| v.is_finite())
        }
        Keypoints::Points3d { xyz } => xyz.as_flattened().iter().all(|v| v.is_finite()),
    };
    finite.then_some(DetectedPerson {
        detection_id: Some(person.id),
        keypoints,
        confidence,
    })
}

/// The bridge's message for `people` found in a `width × height` image: COCO-17, the
/// intrinsics when given, no depth image (each keypoint carries its depth); people who cannot
/// be placed are left out.
pub fn keypoint_frame(
    header: Header,
    people: &[Person],
    width: u32,
    height: u32,
    depth: Option<&DepthImage>,
    camera: Option<&CameraIntrinsics>,
) -> Result<KeypointFrame, PoseError> {
    check_inputs(width, height, depth, camera)?;
    Ok(KeypointFrame {
        header,
        format: KeypointFormat::Coco17,
        joint_names: None,
        camera: camera.copied(),
        depth_image: None,
        people: people
            .iter()
            .take(echo_msgs::MAX_PEOPLE)
            .filter_map(|p| detected_person(p, width, height, depth, camera))
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::NUM_LANDMARKS;
    use crate::roi::Roi;
    use echo_msgs::Validate;

    const CAM: CameraIntrinsics = CameraIntrinsics {
        fx: 522.0,
        fy: 522.0,
        cx: 320.0,
        cy: 240.0,
        width: 640,
        height: 480,
    };

    /// A standing person's metric pose (hip-centred, camera axes), crudely: a column of points
    /// from the head (y = -0.7) to the feet (y = 0.9), spread sideways, with some depth.
    fn world_pose() -> Vec<[f32; 3]> {
        (0..NUM_LANDMARKS)
            .map(|i| {
                let f = i as f32 / (NUM_LANDMARKS - 1) as f32;
                let side = if i % 2 == 0 { 0.18 } else { -0.18 };
                [
                    side * (1.0 + f),
                    -0.7 + 1.6 * f,
                    0.05 * ((i % 5) as f32 - 2.0),
                ]
            })
            .collect()
    }

    /// The landmarks of `world` seen at `t` through `cam`, every point visible.
    fn seen(world: &[[f32; 3]], t: [f64; 3], cam: &CameraIntrinsics) -> PoseLandmarks {
        let image = world
            .iter()
            .map(|w| {
                let (x, y, z) = (w[0] as f64 + t[0], w[1] as f64 + t[1], w[2] as f64 + t[2]);
                Landmark {
                    x: (cam.fx * x / z + cam.cx) as f32,
                    y: (cam.fy * y / z + cam.cy) as f32,
                    z: 0.0,
                    visibility: 0.9,
                    presence: 0.9,
                }
            })
            .collect();
        PoseLandmarks {
            roi: Roi {
                cx: 320.0,
                cy: 240.0,
                size: 480.0,
                rotation: 0.0,
            },
            presence: 0.9,
            image,
            world: world.to_vec(),
        }
    }

    fn person(lm: PoseLandmarks) -> Person {
        Person {
            id: 3,
            landmarks: lm,
        }
    }

    #[test]
    fn the_fit_recovers_where_the_person_stands() {
        for t in [[0.0, 0.1, 2.5], [-0.4, 0.2, 4.0], [0.3, 0.0, 1.6]] {
            let lm = seen(&world_pose(), t, &CAM);
            let got = fit_translation(&lm, &CAM, 640, 480).expect("a fit");
            for k in 0..3 {
                assert!((got[k] - t[k]).abs() < 1e-3, "{t:?} → {got:?}");
            }
        }
        // Twice as far is half the pixel size: the distance follows.
        let near = seen(&world_pose(), [0.0, 0.0, 2.0], &CAM);
        let mut far = near.clone();
        for p in &mut far.image {
            p.x = (p.x - 320.0) / 2.0 + 320.0;
            p.y = (p.y - 240.0) / 2.0 + 240.0;
        }
        let tz = fit_translation(&far, &CAM, 640, 480).unwrap()[2];
        assert!((tz - 4.0).abs() < 0.05, "{tz}");
    }

    #[test]
    fn no_fit_from_nothing() {
        let mut lm = seen(&world_pose(), [0.0, 0.0, 2.0], &CAM);
        // Every point on one pixel: no size, no distance.
        for p in &mut lm.image {
            p.x = 100.0;
            p.y = 100.0;
        }
        assert_eq!(fit_translation(&lm, &CAM, 640, 480), None);
        // Every point outside the image.
        for p in &mut lm.image {
            p.x = -50.0;
        }
        assert_eq!(fit_translation(&lm, &CAM, 640, 480), None);
    }

    #[test]
    fn depth_readings_place_keypoints_where_they_agree() {
        let t = [0.1, 0.1, 2.0];
        let lm = seen(&world_pose(), t, &CAM);
        // The person's surface 0.1 m in front of the joint centres; background at 6 m, but a
        // hole (no reading) around the left wrist and the background behind the right wrist.
        let mut depth = DepthImage {
            width: 640,
            height: 480,
            depth_mm: vec![6000; 640 * 480],
        };
        let surface = |i: usize| ((t[2] + lm.world[i][2] as f64 - 0.1) * 1000.0) as u16;
        for (i, p) in lm.image.iter().enumerate().take(BODY_LANDMARKS) {
            let (u, v) = (p.x.round() as i64, p.y.round() as i64);
            for y in v - 2..=v + 2 {
                for x in u - 2..=u + 2 {
                    if (0..640).contains(&x) && (0..480).contains(&y) {
                        depth.depth_mm[(y * 640 + x) as usize] = match i {
                            15 => 0,
                            16 => 6000,
                            _ => surface(i),
                        };
                    }
                }
            }
        }
        let hip = hip_depth_from_image(&lm, &depth, 640, 480).unwrap();
        assert!((hip - 1.9).abs() < 0.01, "{hip}");
        let p = detected_person(&person(lm.clone()), 640, 480, Some(&depth), Some(&CAM)).unwrap();
        let Keypoints::PixelsDepth { uv, depth_m } = &p.keypoints else {
            panic!("pixel keypoints expected")
        };
        let d = depth_m.as_ref().unwrap();
        for (k, &i) in COCO17_FROM_BLAZEPOSE.iter().enumerate() {
            let want = t[2] + lm.world[i][2] as f64 - 0.1;
            assert!(
                (d[k] - want).abs() < 0.01,
                "keypoint {k}: {} vs {want}",
                d[k]
            );
            assert_eq!(uv[k], [lm.image[i].x as f64, lm.image[i].y as f64]);
        }
        assert_eq!(p.detection_id, Some(3));
        assert!(p.confidence.iter().all(|&c| (c - 0.81).abs() < 1e-6));
        // A keypoint outside the image was not seen.
        let mut out = lm.clone();
        out.image[0].y = -3.0;
        let p = detected_person(&person(out), 640, 480, None, Some(&CAM)).unwrap();
        assert_eq!(p.confidence[0], 0.0);
        assert!((p.confidence[1] - 0.81).abs() < 1e-6);
    }

    #[test]
    fn frames_validate_with_and_without_intrinsics() {
        let lm = seen(&world_pose(), [0.0, 0.2, 3.0], &CAM);
        let people = [person(lm.clone())];
        let header = Header::new("r0", "pose-test", "head_front_camera_optical_frame");
        let f = keypoint_frame(header.clone(), &people, 640, 480, None, Some(&CAM)).unwrap();
        f.validate().unwrap();
        assert_eq!(f.format, KeypointFormat::Coco17);
        assert_eq!(f.camera, Some(CAM));
        let Keypoints::PixelsDepth { depth_m, .. } = &f.people[0].keypoints else {
            panic!("pixel keypoints expected")
        };
        // Hip-centred world + 3 m.
        let d = depth_m.as_ref().unwrap();
        assert!((d[11] - (3.0 + lm.world[23][2] as f64)).abs() < 1e-3);
        // No intrinsics: 3D points through the nominal camera (the same one here).
        let f = keypoint_frame(header.clone(), &people, 640, 480, None, None).unwrap();
        f.validate().unwrap();
        assert_eq!(f.camera, None);
        let Keypoints::Points3d { xyz } = &f.people[0].keypoints else {
            panic!("3D keypoints expected")
        };
        assert!(xyz.iter().all(|p| p[2] > 2.0 && p[2] < 4.0), "{xyz:?}");
        // Inputs that do not fit are errors.
        let bad_depth = DepthImage {
            width: 320,
            height: 240,
            depth_mm: vec![0; 320 * 240],
        };
        assert!(matches!(
            keypoint_frame(
                header.clone(),
                &people,
                640,
                480,
                Some(&bad_depth),
                Some(&CAM)
            ),
            Err(PoseError::DepthSize { .. })
        ));
        let short = DepthImage {
            width: 640,
            height: 480,
            depth_mm: vec![0; 10],
        };
        assert!(matches!(
            check_inputs(640, 480, Some(&short), Some(&CAM)),
            Err(PoseError::DepthSize { .. })
        ));
        assert!(matches!(
            check_inputs(640, 480, Some(&bad_depth), None),
            Err(PoseError::DepthWithoutIntrinsics)
        ));
        assert!(matches!(
            check_inputs(320, 240, None, Some(&CAM)),
            Err(PoseError::IntrinsicsSize { .. })
        ));
        let nan = CameraIntrinsics {
            fx: f64::NAN,
            ..CAM
        };
        assert!(matches!(
            check_inputs(640, 480, None, Some(&nan)),
            Err(PoseError::InvalidIntrinsics)
        ));
        let zero = CameraIntrinsics { fy: 0.0, ..CAM };
        assert!(matches!(
            check_inputs(640, 480, None, Some(&zero)),
            Err(PoseError::InvalidIntrinsics)
        ));
    }

    #[test]
    fn coco_mapping_names_the_same_joints() {
        // MediaPipe Pose's names for the landmarks the mapping takes, in COCO-17 order.
        const BLAZEPOSE: [&str; 29] = [
            "nose",
            "left_eye_inner",
            "left_eye",
            "left_eye_outer",
            "right_eye_inner",
            "right_eye",
            "right_eye_outer",
            "left_ear",
            "right_ear",
            "mouth_left",
            "mouth_right",
            "left_shoulder",
            "right_shoulder",
            "left_elbow",
            "right_elbow",
            "left_wrist",
            "right_wrist",
            "left_pinky",
            "right_pinky",
            "left_index",
            "right_index",
            "left_thumb",
            "right_thumb",
            "left_hip",
            "right_hip",
            "left_knee",
            "right_knee",
            "left_ankle",
            "right_ankle",
        ];
        let names = KeypointFormat::Coco17.joint_names();
        for (k, &i) in COCO17_FROM_BLAZEPOSE.iter().enumerate() {
            assert_eq!(BLAZEPOSE[i], names[k]);
        }
    }
}
