//! The service's loop on scripted camera samples, with a stand-in estimator: which images reach
//! the estimator, with which calibration and depth, and how every bad one is counted.

use echo_bus::Stats;
use echo_msgs::{CameraIntrinsics, DepthImage, Header, KeypointFormat, KeypointFrame};
use echo_pose::{Image, PoseError};
use echo_ros2::image::{RegionOfInterest, RosCameraInfo, RosImage};
use echo_ros2::{encode, RosHeader, Time};
use pose_estimator::{run, Estimate, Input, Output, RunConfig, StreamRules};

const MS: u64 = 1_000_000;
const NOW: u64 = 1_700_000_000_000 * MS;

/// Records what it was given and answers with an empty frame.
#[derive(Default)]
struct Seen(Vec<(u64, u32, bool, Option<f64>)>);

impl Estimate for Seen {
    fn estimate(
        &mut self,
        header: Header,
        img: &Image,
        depth: Option<&DepthImage>,
        camera: Option<&CameraIntrinsics>,
    ) -> Result<KeypointFrame, PoseError> {
        self.0.push((
            header.stamp_ns,
            img.width(),
            depth.is_some(),
            camera.map(|c| c.fx),
        ));
        Ok(KeypointFrame {
            header,
            format: KeypointFormat::Coco17,
            joint_names: None,
            camera: camera.copied(),
            depth_image: None,
            people: vec![],
        })
    }
}

#[derive(Default)]
struct Out(Vec<KeypointFrame>);

impl Output for Out {
    async fn keypoints(&mut self, msg: KeypointFrame) -> anyhow::Result<()> {
        self.0.push(msg);
        Ok(())
    }
}

fn header(stamp_ns: u64) -> RosHeader {
    RosHeader {
        stamp: Time::from_ns(stamp_ns),
        frame_id: "head_front_camera_rgb_optical_frame".into(),
    }
}

fn colour(stamp_ns: u64, w: u32, h: u32) -> Input {
    Input::Image(
        encode(&RosImage {
            header: header(stamp_ns),
            height: h,
            width: w,
            encoding: "bgr8".into(),
            is_bigendian: 0,
            step: w * 3,
            data: vec![90; (w * h * 3) as usize],
        })
        .unwrap(),
    )
}

fn depth(stamp_ns: u64, w: u32, h: u32) -> Input {
    Input::Depth(
        encode(&RosImage {
            header: header(stamp_ns),
            height: h,
            width: w,
            encoding: "16UC1".into(),
            is_bigendian: 0,
            step: w * 2,
            data: vec![0x10; (w * h * 2) as usize],
        })
        .unwrap(),
    )
}

fn info(w: u32, h: u32, fx: f64) -> Input {
    Input::CameraInfo(
        encode(&RosCameraInfo {
            header: header(NOW),
            height: h,
            width: w,
            distortion_model: "plumb_bob".into(),
            d: vec![0.0; 5],
            k: [
                fx,
                0.0,
                w as f64 / 2.0,
                0.0,
                fx,
                h as f64 / 2.0,
                0.0,
                0.0,
                1.0,
            ],
            r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: [0.0; 12],
            binning_x: 0,
            binning_y: 0,
            roi: RegionOfInterest::default(),
        })
        .unwrap(),
    )
}

fn config() -> RunConfig {
    RunConfig {
        robot: "tiago".into(),
        rules: StreamRules {
            max_age_ns: 500 * MS,
            max_ahead_ns: 500 * MS,
            depth_sync_ns: 40 * MS,
        },
        focal_px: None,
        frame_id: "head_front_camera_rgb_optical_frame".into(),
    }
}

async fn play(inputs: Vec<Input>) -> (Seen, Out, Stats) {
    let mut seen = Seen::default();
    let mut out = Out::default();
    let stats = Stats::new(pose_estimator::SERVICE);
    run(
        futures::stream::iter(inputs),
        &mut out,
        &mut seen,
        &config(),
        &stats,
        || NOW,
    )
    .await
    .unwrap();
    (seen, out, stats)
}

fn rejected(stats: &Stats, reason: &str) -> u64 {
    stats.rejected_count(pose_estimator::INPUT_EDGE, reason)
}

#[tokio::test]
async fn good_images_reach_the_estimator_with_calibration_and_paired_depth() {
    let (seen, out, stats) = play(vec![
        colour(NOW - 100 * MS, 8, 6), // before any calibration
        info(8, 6, 500.0),
        depth(NOW - 50 * MS, 8, 6),
        colour(NOW - 40 * MS, 8, 6), // depth 10 ms away: paired
        colour(NOW - 10 * MS, 8, 6), // depth 40 ms away: paired (at the limit)
        depth(NOW - 200 * MS, 8, 6), // an older depth replaces it …
        colour(NOW - 5 * MS, 8, 6),  // … and is 195 ms away: no depth
    ])
    .await;
    assert_eq!(rejected(&stats, "no_camera_info"), 1);
    assert_eq!(
        seen.0,
        vec![
            (NOW - 40 * MS, 8, true, Some(500.0)),
            (NOW - 10 * MS, 8, true, Some(500.0)),
            (NOW - 5 * MS, 8, false, Some(500.0)),
        ]
    );
    assert_eq!(out.0.len(), 3);
    assert_eq!(out.0[0].header.source, pose_estimator::SERVICE);
    assert_eq!(out.0[0].header.robot_id, "tiago");
    assert_eq!(
        out.0[0].header.frame_id,
        "head_front_camera_rgb_optical_frame"
    );
}

#[tokio::test]
async fn bad_images_are_counted_by_reason_and_never_reach_the_estimator() {
    let mut truncated = match colour(NOW - 30 * MS, 8, 6) {
        Input::Image(b) => b,
        _ => unreachable!(),
    };
    truncated.truncate(truncated.len() - 7);
    let wrong_encoding = Input::Image(
        encode(&RosImage {
            header: header(NOW - 20 * MS),
            height: 2,
            width: 2,
            encoding: "yuv422".into(),
            is_bigendian: 0,
            step: 4,
            data: vec![0; 8],
        })
        .unwrap(),
    );
    let short_step = Input::Image(
        encode(&RosImage {
            header: header(NOW - 20 * MS),
            height: 2,
            width: 2,
            encoding: "rgb8".into(),
            is_bigendian: 0,
            step: 5,
            data: vec![0; 10],
        })
        .unwrap(),
    );
    let (seen, _, stats) = play(vec![
        info(8, 6, 500.0),
        info(8, 6, -1.0), // impossible calibration: rejected, the first one stays
        Input::Image(truncated),
        Input::Image(vec![0xff; 40]),
        wrong_encoding,
        short_step,
        colour(NOW - 900 * MS, 8, 6),   // stale
        colour(NOW + 5_000 * MS, 8, 6), // from the future
        colour(NOW - 20 * MS, 8, 6),    // used
        colour(NOW - 30 * MS, 8, 6),    // older than the last used
        colour(NOW - 20 * MS, 8, 6),    // the same stamp again
        colour(NOW - 10 * MS, 4, 3),    // no calibration of that size
        depth(NOW, 8, 6),
        Input::Depth(vec![1, 2, 3]),
        Input::File("/nonexistent/frame.png".into()),
    ])
    .await;
    assert_eq!(seen.0, vec![(NOW - 20 * MS, 8, false, Some(500.0))]);
    assert_eq!(rejected(&stats, "invalid"), 7, "{}", stats.rejected_total());
    assert_eq!(rejected(&stats, "stale"), 1);
    assert_eq!(rejected(&stats, "future"), 1);
    assert_eq!(rejected(&stats, "reordered"), 2);
    assert_eq!(rejected(&stats, "no_camera_info"), 1);
}

#[tokio::test]
async fn image_files_are_read_with_a_nominal_camera_and_the_configured_frame() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("frame_000.png");
    image::RgbImage::from_pixel(64, 48, image::Rgb([10, 200, 30]))
        .save(&p)
        .unwrap();
    std::fs::write(dir.path().join("notes.txt"), "not an image").unwrap();
    let files = pose_estimator::image_files(dir.path()).unwrap();
    assert_eq!(files, vec![p.clone()]);
    let (seen, out, _) = play(vec![Input::File(p)]).await;
    assert_eq!(seen.0.len(), 1);
    let (stamp, width, has_depth, fx) = seen.0[0];
    assert_eq!((stamp, width, has_depth), (NOW, 64, false));
    assert!(fx.unwrap() > 0.0, "a nominal camera");
    assert_eq!(
        out.0[0].header.frame_id,
        "head_front_camera_rgb_optical_frame"
    );
    assert!(pose_estimator::image_files(&dir.path().join("missing")).is_err());
}
