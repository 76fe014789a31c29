//! Time per frame of the pose estimator at the TIAGo++ head camera's 640 × 480, on the
//! astronaut photograph (`.cache/photos/astronaut.png`, scaled to 480 × 480 and centred on a
//! grey 640 × 480 frame): the landmark model alone on a tracked person's crop, one tracked
//! frame end to end (crop, model, keypoint frame), and the first-frame search. Medians.
//!
//! `cargo run --release -p echo-pose --example pose_timing [-- RUNS THREADS]` (defaults: 20
//! runs, 2 intra-op threads).

use std::time::Instant;

use echo_msgs::{CameraIntrinsics, Header};
use echo_pose::{BlazePose, EstimatorConfig, Image, PixelFormat, PoseEstimator};

fn median_ms(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let mut args = std::env::args().skip(1);
    let runs: usize = args.next().map_or(20, |a| a.parse().expect("RUNS"));
    let threads: usize = args.next().map_or(2, |a| a.parse().expect("THREADS"));
    let path = echo_assets::cache_dirs("photos")
        .into_iter()
        .map(|d| d.join("astronaut.png"))
        .find(|p| p.is_file())
        .expect("astronaut.png: run scripts/setup");
    let photo = image::open(&path).expect("the photo").to_rgb8();
    let small = image::imageops::resize(&photo, 480, 480, image::imageops::FilterType::Triangle);
    let mut frame = image::RgbImage::from_pixel(640, 480, image::Rgb([128, 128, 128]));
    image::imageops::replace(&mut frame, &small, 80, 0);
    let img = Image::new(640, 480, PixelFormat::Rgb8, frame.as_raw()).expect("640 × 480 RGB");
    let cam = CameraIntrinsics {
        fx: 522.0,
        fy: 522.0,
        cx: 320.0,
        cy: 240.0,
        width: 640,
        height: 480,
    };

    let t = Instant::now();
    let model = BlazePose::load_default(threads).expect("the model (run scripts/setup)");
    println!("model loaded in {:.0} ms", t.elapsed().as_secs_f64() * 1e3);
    let mut est = PoseEstimator::new(model, EstimatorConfig::default());

    let mut search = vec![];
    let mut roi = None;
    for _ in 0..3 {
        let t = Instant::now();
        let found = est.detect(&img).expect("detect");
        search.push(t.elapsed().as_secs_f64() * 1e3);
        roi = found.first().map(|p| p.next_roi());
    }
    let roi = roi.expect("a person in the frame");

    let mut model_ms = vec![];
    for i in 0..runs + 2 {
        let t = Instant::now();
        est.model_mut().run(&img, &roi).expect("run");
        if i >= 2 {
            model_ms.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }

    let mut frame_ms = vec![];
    let header = Header::new("r0", "pose-timing", "head_front_camera_optical_frame");
    est.process(header.clone(), &img, None, Some(&cam))
        .expect("process");
    for _ in 0..runs {
        let t = Instant::now();
        let f = est
            .process(header.clone(), &img, None, Some(&cam))
            .expect("process");
        frame_ms.push(t.elapsed().as_secs_f64() * 1e3);
        assert_eq!(f.people.len(), 1);
    }

    println!(
        "640x480, {threads} intra-op threads, {runs} runs: landmark model {:.1} ms median \
         (min {:.1}, max {:.1}); tracked frame end to end {:.1} ms median; first-frame search \
         {:.0} ms median of 3",
        median_ms(model_ms.clone()),
        model_ms.iter().cloned().fold(f64::INFINITY, f64::min),
        model_ms.iter().cloned().fold(0.0, f64::max),
        median_ms(frame_ms),
        median_ms(search),
    );
}
