//! `echoctl bench camera`: the camera path stage by stage at the TIAGo++ head camera's
//! 640 × 480 — a photograph of a person scaled to 480 × 480 and centred on a grey frame, sent as
//! a ROS 2 `sensor_msgs/Image` (rgb8, 921 600 bytes of pixels) with its `CameraInfo`:
//!
//! * the service's intake: CDR decode alone, then decode plus the checks and time rules
//!   (`pose_estimator::CameraFrames::on_image`);
//! * per ONNX Runtime thread count (1, 2): ONNX Runtime alone on a prepared 1 × 3 × 256 × 256
//!   input; the landmark model on the tracked person's crop (crop sampling with the colour
//!   order, inference, landmarks back to image pixels); a tracked frame end to end
//!   (`PoseEstimator::process`: crop, model, keypoint frame); the same from the CDR sample; the
//!   first-frame search (no one tracked yet);
//! * the perception bridge's step from that keypoint frame to a tracked skeleton.
//!
//! Each line: median, p99 and max in milliseconds.

use std::path::Path;
use std::time::Instant;

use anyhow::{anyhow, Context, Result};
use echo_msgs::{now_ns, CameraIntrinsics, Header, KeypointFrame};
use echo_perception::{BridgeConfig, PerceptionBridge};
use echo_pose::{BlazePose, EstimatorConfig, Image, PixelFormat, PoseEstimator};
use echo_robot::RobotModel;
use echo_ros2::image::{RegionOfInterest, RosCameraInfo, RosImage};
use pose_estimator::{CameraFrames, StreamRules};

use super::bench::report;

/// The head camera's image size.
const WIDTH: u32 = 640;
const HEIGHT: u32 = 480;

/// Milliseconds `f` takes, `n` times.
fn times<T>(n: usize, mut f: impl FnMut() -> Result<T>) -> Result<Vec<f64>> {
    let mut v = Vec::with_capacity(n);
    for _ in 0..n {
        let t = Instant::now();
        std::hint::black_box(f()?);
        v.push(t.elapsed().as_secs_f64() * 1e3);
    }
    Ok(v)
}

/// The photograph scaled to 480 × 480 in the middle of a grey 640 × 480 frame.
fn frame(photo: Option<&Path>) -> Result<image::RgbImage> {
    let path = match photo {
        Some(p) => p.to_path_buf(),
        None => echo_assets::cache_dirs("photos")
            .into_iter()
            .map(|d| d.join("camera.png"))
            .find(|p| p.is_file())
            .ok_or_else(|| anyhow!("camera.png not found: run scripts/setup or pass --photo"))?,
    };
    let photo = image::open(&path)
        .with_context(|| path.display().to_string())?
        .to_rgb8();
    let side = HEIGHT;
    let small = image::imageops::resize(&photo, side, side, image::imageops::FilterType::Triangle);
    let mut frame = image::RgbImage::from_pixel(WIDTH, HEIGHT, image::Rgb([128, 128, 128]));
    image::imageops::replace(&mut frame, &small, ((WIDTH - side) / 2) as i64, 0);
    Ok(frame)
}

/// The TIAGo++ head camera's nominal intrinsics at 640 × 480.
fn intrinsics() -> CameraIntrinsics {
    echo_pose::keypoints::nominal_camera(WIDTH, HEIGHT)
}

fn ros_header(stamp_ns: u64) -> echo_ros2::RosHeader {
    echo_ros2::RosHeader {
        stamp: echo_ros2::Time::from_ns(stamp_ns),
        frame_id: pose_estimator::DEFAULT_FRAME.into(),
    }
}

fn camera_info() -> RosCameraInfo {
    let c = intrinsics();
    RosCameraInfo {
        header: ros_header(now_ns()),
        height: HEIGHT,
        width: WIDTH,
        distortion_model: "plumb_bob".into(),
        d: vec![0.0; 5],
        k: [c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0],
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: [
            c.fx, 0.0, c.cx, 0.0, 0.0, c.fy, c.cy, 0.0, 0.0, 0.0, 1.0, 0.0,
        ],
        binning_x: 0,
        binning_y: 0,
        roi: RegionOfInterest::default(),
    }
}

/// A fresh stream that has the calibration.
fn calibrated_stream(info: &[u8]) -> Result<CameraFrames> {
    let mut frames = CameraFrames::new(StreamRules {
        max_age_ns: 500_000_000,
        max_ahead_ns: 500_000_000,
        depth_sync_ns: 40_000_000,
    });
    frames.on_camera_info(info).map_err(|e| anyhow!("{e}"))?;
    Ok(frames)
}

/// ONNX Runtime alone: the converted model on a prepared input with `threads` threads.
fn runtime_alone(threads: usize, samples: usize) -> Result<Vec<f64>> {
    use ort::session::Session;
    use ort::value::Tensor;
    let path = echo_pose::model::locate_model()?;
    let env = echo_onnx::runtime::environment()?;
    let ort_err = |e: &dyn std::fmt::Display| anyhow!("ONNX Runtime: {e}");
    let mut session = Session::builder(env)
        .map_err(|e| ort_err(&e))?
        .with_intra_threads(threads)
        .map_err(|e| ort_err(&e))?
        .commit_from_file(&path)
        .map_err(|e| ort_err(&e))?;
    let input = session
        .inputs()
        .first()
        .map(|i| i.name().to_string())
        .ok_or_else(|| anyhow!("{}: no input", path.display()))?;
    let crop = echo_pose::image::CROP;
    let data = vec![0.5f32; 3 * crop * crop];
    let mut run = || -> Result<usize> {
        let x =
            Tensor::from_array(([1usize, 3, crop, crop], data.clone())).map_err(|e| ort_err(&e))?;
        let out = session
            .run(ort::inputs![input.as_str() => x])
            .map_err(|e| ort_err(&e))?;
        Ok(out.len())
    };
    for _ in 0..5 {
        run()?;
    }
    times(samples, run)
}

/// Run every stage and print one line each.
pub fn run(samples: usize, photo: Option<&Path>) -> Result<()> {
    let samples = samples.max(5);
    let frame = frame(photo)?;
    let cam = intrinsics();
    let info = echo_ros2::encode(&camera_info())?;
    let image_at = |stamp_ns: u64| RosImage {
        header: ros_header(stamp_ns),
        height: HEIGHT,
        width: WIDTH,
        encoding: "rgb8".into(),
        is_bigendian: 0,
        step: WIDTH * 3,
        data: frame.as_raw().clone(),
    };
    let cdr = echo_ros2::encode(&image_at(now_ns()))?;
    println!(
        "camera path at {WIDTH} x {HEIGHT} (rgb8 CDR sample of {} bytes), {samples} samples per line",
        cdr.len()
    );

    report(
        "ROS Image CDR decode",
        times(samples, || Ok(echo_ros2::decode::<RosImage>(&cdr)?))?,
    );
    // A fresh sample per call (the stream takes only newer stamps), encoded outside the timing.
    let mut intake = Vec::with_capacity(samples);
    for _ in 0..samples {
        let cdr = echo_ros2::encode(&image_at(now_ns()))?;
        let mut frames = calibrated_stream(&info)?;
        let t = Instant::now();
        let f = frames
            .on_image(&cdr, now_ns())
            .map_err(|e| anyhow!("{e}"))?;
        intake.push(t.elapsed().as_secs_f64() * 1e3);
        std::hint::black_box(f);
    }
    report("intake: decode + checks (on_image)", intake);

    let img = Image::new(WIDTH, HEIGHT, PixelFormat::Rgb8, frame.as_raw())?;
    let header = Header::new(
        "bench",
        pose_estimator::SERVICE,
        pose_estimator::DEFAULT_FRAME,
    );
    let mut last_frame: Option<KeypointFrame> = None;
    for threads in [1usize, 2] {
        report(
            &format!("ONNX Runtime alone, {threads} thread(s)"),
            runtime_alone(threads, samples)?,
        );
        let model = BlazePose::load_default(threads)?;
        let mut est = PoseEstimator::new(model, EstimatorConfig::default());
        let found = est.detect(&img)?;
        let roi = found
            .first()
            .map(|p| p.next_roi())
            .ok_or_else(|| anyhow!("no person found in the frame"))?;
        report(
            &format!("landmark model on the crop, {threads} thread(s)"),
            times(samples, || Ok(est.model_mut().run(&img, &roi)?))?,
        );
        est.process(header.clone(), &img, None, Some(&cam))?;
        report(
            &format!("tracked frame end to end, {threads} thread(s)"),
            times(samples, || {
                let f = est.process(header.clone(), &img, None, Some(&cam))?;
                anyhow::ensure!(f.people.len() == 1, "{} people", f.people.len());
                Ok(f)
            })?,
        );
        let mut from_cdr = Vec::with_capacity(samples);
        let mut frames = calibrated_stream(&info)?;
        for _ in 0..samples {
            let cdr = echo_ros2::encode(&image_at(now_ns()))?;
            let t = Instant::now();
            let f = frames
                .on_image(&cdr, now_ns())
                .map_err(|e| anyhow!("{e}"))?;
            let img = Image::with_step(
                f.image.width,
                f.image.height,
                f.format,
                f.image.step as usize,
                &f.image.data,
            )?;
            let kf = est.process(header.clone(), &img, None, f.camera.as_ref())?;
            from_cdr.push(t.elapsed().as_secs_f64() * 1e3);
            last_frame = Some(kf);
        }
        report(
            &format!("CDR sample to keypoint frame, {threads} thread(s)"),
            from_cdr,
        );
        let searches = (samples / 10).max(5);
        report(
            &format!("first-frame search, {threads} thread(s)"),
            times(searches, || {
                est.reset();
                Ok(est.process(header.clone(), &img, None, Some(&cam))?)
            })?,
        );
    }

    // The bridge: the robot at its home pose, the frame repeated at 15 Hz (a still person).
    let kf = last_frame.ok_or_else(|| anyhow!("no keypoint frame"))?;
    let model = RobotModel::tiago_dual();
    let robot = echo_sim::robot::SimRobot::new(Default::default(), model.clone());
    let mut bridge = PerceptionBridge::new(BridgeConfig::default(), model);
    let start = now_ns();
    let (mut bridge_ms, mut tracked) = (Vec::with_capacity(samples), 0usize);
    for i in 0..samples + 10 {
        let stamp = start + i as u64 * 66_666_667;
        bridge.on_joint_state(&robot.joint_state("bench", stamp));
        let mut f = kf.clone();
        f.header.stamp_ns = stamp;
        f.header.seq = i as u64;
        let t = Instant::now();
        let out = bridge.on_keypoints(&f, stamp + 30_000_000)?;
        let dt = t.elapsed().as_secs_f64() * 1e3;
        if out.skeletons.iter().any(|s| !s.tracks.is_empty()) {
            tracked += 1;
        }
        std::hint::black_box(out);
        if i >= 10 {
            bridge_ms.push(dt);
        }
    }
    anyhow::ensure!(
        tracked > samples / 2,
        "the bridge tracked the person in only {tracked} of {} frames",
        samples + 10
    );
    report("bridge: keypoint frame to skeleton", bridge_ms);
    Ok(())
}
