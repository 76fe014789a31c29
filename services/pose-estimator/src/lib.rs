//! The pose-estimator service: wiring and lifecycle around [`echo_pose::PoseEstimator`].
//!
//! Inputs, one of two:
//! - **the robot's camera**, ROS 2 through zenoh-bridge-ros2dds (`--ros2-namespace`):
//!   `sensor_msgs/Image` on `<ns>/head_front_camera/rgb/image_raw` (rgb8, bgr8, rgba8, bgra8,
//!   mono8), its `sensor_msgs/CameraInfo`, and depth registered to it (16UC1 or 32FC1). Only
//!   the newest image waits: a camera at 30 Hz and an estimator at 10 Hz drop frames rather
//!   than fall behind;
//! - **an image folder** (`--images DIR`): PNG and JPEG files in name order, played at `--fps`,
//!   stamped when read, with a nominal camera unless `--fx` … give one.
//!
//! Output: `perception/raw` ([`KeypointFrame`], COCO-17, one per image used);
//! `status/pose-estimator` with every rejection counted by reason.
//!
//! Rules ([`CameraFrames`]): a colour image is used only when it decodes and its encoding and
//! size are right (`invalid`), it is newer than the last one used (`reordered`), it is not
//! older than `--max-age-ms` by this host's clock (`stale`) nor ahead of it by more than
//! `--max-clock-skew-ms` (`future`), and a valid `CameraInfo` of the same size has arrived
//! (`no_camera_info`; pixel keypoints without intrinsics cannot be placed). Depth goes with
//! it when its stamp is within `--depth-sync-ms` and its size matches; otherwise the frame
//! goes without depth (the estimator then places people by their metric pose). A
//! `CameraInfo` that cannot be right (non-positive focal length, principal point outside the
//! image) is rejected and the previous one kept.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{anyhow, Context, Result};
use echo_bus::shutdown::Shutdown;
use echo_bus::{topics, Bus, BusArgs, Stats};
use echo_msgs::{now_ns, CameraIntrinsics, DepthImage, Header, KeypointFrame};
use echo_pose::{EstimatorConfig, Image, PixelFormat, PoseError, PoseEstimator};
use echo_ros2::image::{ImageError, RosCameraInfo, RosImage};
use futures::{Stream, StreamExt};

/// Service name (liveliness token, status key, logs).
pub const SERVICE: &str = "pose-estimator";

/// Edge name of the camera input in counters.
pub const INPUT_EDGE: &str = "camera";

/// The frame offline images are said to come from (no driver names one).
pub const DEFAULT_FRAME: &str = "head_front_camera_rgb_optical_frame";

/// Command-line / environment configuration of the service.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Network.
    #[command(flatten)]
    pub bus: BusArgs,
    /// ROS 2 namespace of the camera topics ("/" for none).
    #[arg(long, default_value = "/", env = "ECHO_ROS2_NAMESPACE")]
    pub ros2_namespace: String,
    /// Colour image topic.
    #[arg(long, default_value = echo_ros2::image::HEAD_RGB_TOPIC)]
    pub image_topic: String,
    /// Camera info topic of the colour image.
    #[arg(long, default_value = echo_ros2::image::HEAD_RGB_INFO_TOPIC)]
    pub camera_info_topic: String,
    /// Depth registered to the colour image ("" for none).
    #[arg(long, default_value = echo_ros2::image::HEAD_DEPTH_TOPIC)]
    pub depth_topic: String,
    /// Read images from this folder instead of the camera (PNG, JPEG; name order).
    #[arg(long)]
    pub images: Option<PathBuf>,
    /// With --images: frames per second.
    #[arg(long, default_value_t = 10.0)]
    pub fps: f64,
    /// With --images: start again after the last image.
    #[arg(long = "loop")]
    pub repeat: bool,
    /// With --images: the camera frame named in the output.
    #[arg(long, default_value = DEFAULT_FRAME)]
    pub frame_id: String,
    /// With --images: focal length in pixels (both axes; principal point at the centre).
    /// Absent: a nominal 62° horizontal field of view.
    #[arg(long)]
    pub focal_px: Option<f64>,
    /// Images older than this by this host's clock are not used, ms.
    #[arg(long, default_value_t = 500)]
    pub max_age_ms: u64,
    /// Depth is paired with a colour image stamped within this, ms.
    #[arg(long, default_value_t = 40)]
    pub depth_sync_ms: u64,
    /// ONNX Runtime intra-op threads (0: its choice).
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// Most people reported per image.
    #[arg(long, default_value_t = 8)]
    pub max_people: usize,
}

/// Turns one image into a keypoint frame: the real estimator, or a stand-in in tests.
pub trait Estimate {
    /// The keypoint frame of `img` (header as given).
    fn estimate(
        &mut self,
        header: Header,
        img: &Image,
        depth: Option<&DepthImage>,
        camera: Option<&CameraIntrinsics>,
    ) -> Result<KeypointFrame, PoseError>;
}

impl Estimate for PoseEstimator {
    fn estimate(
        &mut self,
        header: Header,
        img: &Image,
        depth: Option<&DepthImage>,
        camera: Option<&CameraIntrinsics>,
    ) -> Result<KeypointFrame, PoseError> {
        self.process(header, img, depth, camera)
    }
}

/// One input event.
#[derive(Debug)]
pub enum Input {
    /// A `sensor_msgs/Image` (colour), CDR.
    Image(Vec<u8>),
    /// A `sensor_msgs/CameraInfo`, CDR.
    CameraInfo(Vec<u8>),
    /// A `sensor_msgs/Image` (depth), CDR.
    Depth(Vec<u8>),
    /// An image file (offline).
    File(PathBuf),
}

/// Why an input was not used; [`Rejected::reason`] is the counter's name.
#[derive(Debug, thiserror::Error)]
pub enum Rejected {
    /// Undecodable CDR or image file, wrong encoding or size.
    #[error("{0}")]
    Invalid(String),
    /// Not newer than the last image used.
    #[error("image stamp {stamp_ns} not newer than the last used {last_ns}")]
    Reordered {
        /// This image's stamp.
        stamp_ns: u64,
        /// The last used.
        last_ns: u64,
    },
    /// Too old.
    #[error("image {age_ms} ms old (limit {limit_ms} ms)")]
    Stale {
        /// Age.
        age_ms: u64,
        /// Limit.
        limit_ms: u64,
    },
    /// From the future.
    #[error("image stamped {ahead_ms} ms in the future (limit {limit_ms} ms)")]
    Future {
        /// How far ahead.
        ahead_ms: u64,
        /// Limit.
        limit_ms: u64,
    },
    /// No usable camera calibration yet.
    #[error("no valid camera info for a {0}×{1} image yet")]
    NoCameraInfo(u32, u32),
    /// The estimator refused the input.
    #[error("pose estimation: {0}")]
    Estimator(#[from] PoseError),
}

impl Rejected {
    /// Counter name.
    pub fn reason(&self) -> &'static str {
        match self {
            Rejected::Invalid(_) => "invalid",
            Rejected::Reordered { .. } => "reordered",
            Rejected::Stale { .. } => "stale",
            Rejected::Future { .. } => "future",
            Rejected::NoCameraInfo(..) => "no_camera_info",
            Rejected::Estimator(_) => "estimator",
        }
    }
}

impl From<ImageError> for Rejected {
    fn from(e: ImageError) -> Self {
        Rejected::Invalid(e.to_string())
    }
}

/// Time rules of the camera stream.
#[derive(Debug, Clone, Copy)]
pub struct StreamRules {
    /// Oldest usable image, ns.
    pub max_age_ns: u64,
    /// Furthest ahead of this host's clock, ns.
    pub max_ahead_ns: u64,
    /// Depth pairing tolerance, ns.
    pub depth_sync_ns: u64,
}

/// A colour image ready for the estimator, with what goes with it.
#[derive(Debug, Clone)]
pub struct CameraFrame {
    /// The image (owned bytes; `step` may pad rows).
    pub image: RosImage,
    /// Its pixel format.
    pub format: PixelFormat,
    /// Intrinsics.
    pub camera: Option<CameraIntrinsics>,
    /// Depth registered to it, when one was close enough in time.
    pub depth: Option<DepthImage>,
}

/// The camera stream's state: the latest calibration and depth, the last image used.
#[derive(Debug)]
pub struct CameraFrames {
    rules: StreamRules,
    info: Option<CameraIntrinsics>,
    depth: Option<(u64, DepthImage)>,
    last_ns: Option<u64>,
}

impl CameraFrames {
    /// A stream with `rules`.
    pub fn new(rules: StreamRules) -> CameraFrames {
        CameraFrames {
            rules,
            info: None,
            depth: None,
            last_ns: None,
        }
    }

    /// A `CameraInfo` sample.
    pub fn on_camera_info(&mut self, cdr: &[u8]) -> Result<(), Rejected> {
        let info: RosCameraInfo =
            echo_ros2::decode(cdr).map_err(|e| Rejected::Invalid(e.to_string()))?;
        self.info = Some(info.intrinsics()?);
        Ok(())
    }

    /// A depth sample.
    pub fn on_depth(&mut self, cdr: &[u8]) -> Result<(), Rejected> {
        let img: RosImage = echo_ros2::decode(cdr).map_err(|e| Rejected::Invalid(e.to_string()))?;
        let d = img.to_depth_mm()?;
        self.depth = Some((
            img.stamp_ns(),
            DepthImage {
                width: d.width,
                height: d.height,
                depth_mm: d.data,
            },
        ));
        Ok(())
    }

    /// A colour sample at this host's time `now_ns`: the frame to estimate, or why not.
    pub fn on_image(&mut self, cdr: &[u8], now_ns: u64) -> Result<CameraFrame, Rejected> {
        let image: RosImage =
            echo_ros2::decode(cdr).map_err(|e| Rejected::Invalid(e.to_string()))?;
        let format = PixelFormat::from_encoding(&image.encoding)
            .map_err(|e| Rejected::Invalid(e.to_string()))?;
        // Size, step and length, before anything else looks at the pixels.
        Image::with_step(
            image.width,
            image.height,
            format,
            image.step as usize,
            &image.data,
        )
        .map_err(|e| Rejected::Invalid(e.to_string()))?;
        let stamp = image.stamp_ns();
        self.check_time(stamp, now_ns)?;
        let camera = match self.info {
            Some(c) if c.width == image.width && c.height == image.height => c,
            _ => return Err(Rejected::NoCameraInfo(image.width, image.height)),
        };
        let depth = match &self.depth {
            Some((t, d))
                if t.abs_diff(stamp) <= self.rules.depth_sync_ns
                    && d.width == image.width
                    && d.height == image.height =>
            {
                Some(d.clone())
            }
            _ => None,
        };
        self.last_ns = Some(stamp);
        Ok(CameraFrame {
            image,
            format,
            camera: Some(camera),
            depth,
        })
    }

    fn check_time(&self, stamp: u64, now: u64) -> Result<(), Rejected> {
        if stamp > now.saturating_add(self.rules.max_ahead_ns) {
            return Err(Rejected::Future {
                ahead_ms: (stamp - now) / 1_000_000,
                limit_ms: self.rules.max_ahead_ns / 1_000_000,
            });
        }
        if now > stamp.saturating_add(self.rules.max_age_ns) {
            return Err(Rejected::Stale {
                age_ms: (now - stamp) / 1_000_000,
                limit_ms: self.rules.max_age_ns / 1_000_000,
            });
        }
        if let Some(last) = self.last_ns {
            if stamp <= last {
                return Err(Rejected::Reordered {
                    stamp_ns: stamp,
                    last_ns: last,
                });
            }
        }
        Ok(())
    }
}

/// An image file as a camera frame stamped `now_ns` (RGB, the given or a nominal camera).
pub fn file_frame(
    path: &Path,
    focal_px: Option<f64>,
    now_ns: u64,
    frame_id: &str,
) -> Result<CameraFrame, Rejected> {
    let rgb = image::open(path)
        .map_err(|e| Rejected::Invalid(format!("{}: {e}", path.display())))?
        .to_rgb8();
    let (width, height) = rgb.dimensions();
    let camera = match focal_px {
        Some(f) if f.is_finite() && f > 0.0 => Some(CameraIntrinsics {
            fx: f,
            fy: f,
            cx: width as f64 / 2.0,
            cy: height as f64 / 2.0,
            width,
            height,
        }),
        Some(f) => return Err(Rejected::Invalid(format!("focal length {f} px"))),
        None => Some(echo_pose::keypoints::nominal_camera(width, height)),
    };
    Ok(CameraFrame {
        image: RosImage {
            header: echo_ros2::RosHeader {
                stamp: echo_ros2::Time::from_ns(now_ns),
                frame_id: frame_id.to_string(),
            },
            height,
            width,
            encoding: "rgb8".into(),
            is_bigendian: 0,
            step: width * 3,
            data: rgb.into_raw(),
        },
        format: PixelFormat::Rgb8,
        camera,
        depth: None,
    })
}

/// Where the service's output goes.
pub trait Output {
    /// Publish one keypoint frame.
    fn keypoints(
        &mut self,
        msg: KeypointFrame,
    ) -> impl std::future::Future<Output = Result<()>> + Send;
}

struct BusOutput(echo_bus::Publisher<KeypointFrame>);

impl Output for BusOutput {
    async fn keypoints(&mut self, msg: KeypointFrame) -> Result<()> {
        self.0.put(msg).await
    }
}

/// What [`run`] needs besides its inputs.
pub struct RunConfig {
    /// Robot id for headers.
    pub robot: String,
    /// Stream rules.
    pub rules: StreamRules,
    /// Offline images: focal length and frame.
    pub focal_px: Option<f64>,
    /// Offline images: frame id.
    pub frame_id: String,
}

/// Run over `inputs` until they end: every usable image through `estimator` to `output`;
/// rejections counted in `stats` (edge [`INPUT_EDGE`]) and logged.
pub async fn run<S, O, E>(
    mut inputs: S,
    output: &mut O,
    estimator: &mut E,
    cfg: &RunConfig,
    stats: &Stats,
    wall_now_ns: impl Fn() -> u64,
) -> Result<()>
where
    S: Stream<Item = Input> + Unpin,
    O: Output,
    E: Estimate,
{
    let mut frames = CameraFrames::new(cfg.rules);
    while let Some(input) = inputs.next().await {
        let frame = match input {
            Input::CameraInfo(b) => frames.on_camera_info(&b).map(|_| None),
            Input::Depth(b) => frames.on_depth(&b).map(|_| None),
            Input::Image(b) => frames.on_image(&b, wall_now_ns()).map(Some),
            Input::File(p) => file_frame(&p, cfg.focal_px, wall_now_ns(), &cfg.frame_id).map(Some),
        };
        let frame = match frame {
            Ok(Some(f)) => f,
            Ok(None) => continue,
            Err(e) => {
                stats.rejected(INPUT_EDGE, e.reason(), &e.to_string());
                continue;
            }
        };
        let started = std::time::Instant::now();
        let mut header = Header::new(&cfg.robot, SERVICE, &frame.image.header.frame_id);
        header.stamp_ns = frame.image.stamp_ns();
        let img = Image::with_step(
            frame.image.width,
            frame.image.height,
            frame.format,
            frame.image.step as usize,
            &frame.image.data,
        );
        let result = img.and_then(|img| {
            estimator.estimate(header, &img, frame.depth.as_ref(), frame.camera.as_ref())
        });
        match result {
            Ok(kf) => {
                stats.latency_ms(started.elapsed().as_secs_f64() * 1e3);
                output.keypoints(kf).await?;
            }
            Err(e) => {
                let e = Rejected::from(e);
                stats.rejected(INPUT_EDGE, e.reason(), &e.to_string());
            }
        }
    }
    Ok(())
}

/// The image files of `dir` in name order (PNG, JPEG).
pub fn image_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("reading {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(anyhow!("no PNG or JPEG images in {}", dir.display()));
    }
    Ok(files)
}

type Samples =
    zenoh::pubsub::Subscriber<zenoh::handlers::RingChannelHandler<zenoh::sample::Sample>>;

async fn ros_subscriber(bus: &Bus, ns: &str, topic: &str, keep: usize) -> Result<Samples> {
    let key = echo_ros2::ros_key(ns, topic);
    bus.session()
        .declare_subscriber(key.clone())
        .with(zenoh::handlers::RingChannel::new(keep))
        .await
        .map_err(|e| anyhow!("ROS 2 subscriber {key}: {e}"))
}

fn samples(sub: Samples, wrap: fn(Vec<u8>) -> Input) -> impl Stream<Item = Input> {
    futures::stream::unfold(sub, move |s| async move {
        let sample = s.recv_async().await.ok()?;
        Some((wrap(sample.payload().to_bytes().to_vec()), s))
    })
}

/// Open the bus, load the model, wire inputs and outputs, and run until `stop` triggers (or
/// the image folder ends, without `--loop`).
pub async fn serve(args: Args, stop: Shutdown) -> Result<()> {
    let model = echo_pose::BlazePose::load_default(args.threads)?;
    let mut estimator = PoseEstimator::new(
        model,
        EstimatorConfig {
            max_people: args.max_people,
            ..Default::default()
        },
    );
    let bus = Bus::open(&args.bus, SERVICE).await?;
    let robot = bus.robot().clone();
    let mut output = BusOutput(bus.publisher(&topics::perception_raw(&robot)).await?);
    let alive = bus.declare_alive().await?;
    let reporter = bus.spawn_status_reporter(Duration::from_secs(1), stop.clone());
    let mut stop_inputs = stop.clone();
    let until_stop = Box::pin(async move { stop_inputs.wait().await });
    let inputs: std::pin::Pin<Box<dyn Stream<Item = Input> + Send>> = match &args.images {
        Some(dir) => {
            let files = image_files(dir)?;
            tracing::info!(images = files.len(), dir = %dir.display(), fps = args.fps, "pose estimator reading images");
            let period = Duration::from_secs_f64(1.0 / args.fps.clamp(0.1, 100.0));
            let mut tick = tokio::time::interval(period);
            tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
            let all: Box<dyn Iterator<Item = PathBuf> + Send> = if args.repeat {
                Box::new(files.into_iter().cycle())
            } else {
                Box::new(files.into_iter())
            };
            Box::pin(
                futures::stream::unfold((all, tick), |(mut it, mut tick)| async move {
                    tick.tick().await;
                    it.next().map(|p| (Input::File(p), (it, tick)))
                })
                .take_until(until_stop),
            )
        }
        None => {
            let ns = args.ros2_namespace.as_str();
            let images = ros_subscriber(&bus, ns, &args.image_topic, 1).await?;
            let info = ros_subscriber(&bus, ns, &args.camera_info_topic, 1).await?;
            let mut streams: Vec<std::pin::Pin<Box<dyn Stream<Item = Input> + Send>>> = vec![
                Box::pin(samples(images, Input::Image)),
                Box::pin(samples(info, Input::CameraInfo)),
            ];
            if !args.depth_topic.is_empty() {
                let depth = ros_subscriber(&bus, ns, &args.depth_topic, 1).await?;
                streams.push(Box::pin(samples(depth, Input::Depth)));
            }
            tracing::info!(namespace = ns, image = %args.image_topic, "pose estimator reading the camera");
            Box::pin(futures::stream::select_all(streams).take_until(until_stop))
        }
    };
    let cfg = RunConfig {
        robot: robot.as_str().to_string(),
        rules: StreamRules {
            max_age_ns: args.max_age_ms * 1_000_000,
            max_ahead_ns: args
                .bus
                .max_clock_skew_ms
                .unwrap_or(echo_bus::ingress::DEFAULT_MAX_CLOCK_SKEW_MS)
                * 1_000_000,
            depth_sync_ns: args.depth_sync_ms * 1_000_000,
        },
        focal_px: args.focal_px,
        frame_id: args.frame_id.clone(),
    };
    let stats = bus.stats();
    tokio::task::block_in_place(|| {
        tokio::runtime::Handle::current().block_on(run(
            inputs,
            &mut output,
            &mut estimator,
            &cfg,
            &stats,
            now_ns,
        ))
    })?;
    let _ = tokio::time::timeout(Duration::from_secs(2), reporter).await;
    drop(alive);
    bus.close().await?;
    tracing::info!("pose estimator stopped");
    Ok(())
}
