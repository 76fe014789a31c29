//! `echoctl mock-perception`: a scripted partner (and optional bystander) seen by the head
//! camera, published as pose-estimator keypoints at 15 Hz.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use echo_bus::shutdown::Shutdown;
use echo_bus::{topics, Bus, BusArgs};
use echo_msgs::{frames, now_ns, JointState};
use echo_robot::RobotModel;
use echo_sim::mission::Mission;
use echo_sim::perception::{MockFormat, MockPerception, MockPerceptionConfig};

/// Service name.
pub const SERVICE: &str = "mock-perception";

/// Mock estimator options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Network.
    #[command(flatten)]
    pub bus: BusArgs,
    /// Keypoint format: smpl24-points or coco17-pixels-depth.
    #[arg(long, default_value = "smpl24-points")]
    pub format: String,
    /// Frame rate, Hz.
    #[arg(long, default_value_t = 15.0)]
    pub rate: f64,
    /// Keypoint noise σ, metres.
    #[arg(long, default_value_t = 0.01)]
    pub noise: f64,
    /// Probability that a joint is missing in a frame.
    #[arg(long, default_value_t = 0.02)]
    pub drop_joints: f64,
    /// Probability that a frame is lost.
    #[arg(long, default_value_t = 0.0)]
    pub drop_frames: f64,
    /// Capture-to-publish latency, ms.
    #[arg(long, default_value_t = 30.0)]
    pub latency_ms: f64,
    /// Add a bystander walking across.
    #[arg(long)]
    pub bystander: bool,
    /// Random seed.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Script start (ns since the UNIX epoch); default: now. Script time = (capture − start).
    #[arg(long)]
    pub t0_ns: Option<u64>,
    /// Replay both people of a generated interaction instead of the demo partner:
    /// `<split>:<index>` (e.g. `test:7`, an approach-and-greet of the test split).
    #[arg(long)]
    pub clip: Option<String>,
    /// Distance of the replayed pair's midpoint in front of the robot, m.
    #[arg(long, default_value_t = 2.8)]
    pub clip_distance: f64,
    /// With --clip: show only person A, placed so the robot stands where person B stood (the
    /// robot plays B where B stood when the two were closest: the partner walks up to the robot).
    #[arg(long)]
    pub robot_plays_b: bool,
    /// Play a human–robot mission's partner: a scenario file, or its name under
    /// `deploy/scenarios/` (mission, wave, handshake, handover, high-five, walk-up); the robot
    /// plays the other person.
    #[arg(long, conflicts_with = "clip")]
    pub scenario: Option<String>,
    /// Replay person A of a real two-person capture (two BVH files, one clock) as the partner;
    /// the robot plays person B.
    #[arg(long, num_args = 2, value_names = ["A_BVH", "B_BVH"], conflicts_with_all = ["clip", "scenario"])]
    pub capture: Option<Vec<PathBuf>>,
    /// With --capture: the capture's description (its interaction type is read from it).
    #[arg(
        long,
        default_value = "Two people walk up to each other and shake hands."
    )]
    pub capture_prompt: String,
}

/// The mission the partner performs: a scenario (file or name under the deployment directory's
/// `scenarios/`), or person A of a real capture.
pub fn mission_of(
    scenario: Option<&str>,
    capture: Option<&[PathBuf]>,
    capture_prompt: &str,
) -> Result<Option<Mission>> {
    if let Some(files) = capture {
        let [a, b] = files else {
            anyhow::bail!("--capture takes two BVH files, A then B");
        };
        let texts = vec![capture_prompt.to_string()];
        let kind = echo_motion::intergen::kind_from_text(&texts);
        let (clip, _) = echo_motion::capture::load_bvh_pair(
            a,
            b,
            &echo_motion::capture::PairOptions::default(),
            texts,
            kind,
        )
        .with_context(|| format!("loading the capture {} + {}", a.display(), b.display()))?;
        let name = format!(
            "capture {}",
            a.file_stem().unwrap_or_default().to_string_lossy()
        );
        return Ok(Some(Mission::from_clip(
            &name,
            clip,
            format!("{} + {}", a.display(), b.display()),
        )));
    }
    let deploy = echo_assets::deploy_dir(std::path::Path::new("deploy"));
    Ok(scenario.map(|s| Mission::load(s, &deploy)).transpose()?)
}

/// The generated clip named by `<split>:<index>`.
pub fn clip_of(spec: &str) -> Result<echo_motion::synth::Clip> {
    let (split, index) = spec
        .split_once(':')
        .ok_or_else(|| anyhow::anyhow!("--clip must be <split>:<index>, not '{spec}'"))?;
    let split = echo_motion::synth::Split::parse(split)
        .ok_or_else(|| anyhow::anyhow!("--clip: unknown split '{split}'"))?;
    let index: u64 = index
        .parse()
        .map_err(|_| anyhow::anyhow!("--clip: '{index}' is not a clip index"))?;
    Ok(echo_motion::synth::generate(&split.clip(index)))
}

impl Args {
    /// The mock estimator configuration these options describe.
    pub fn config(&self) -> Result<MockPerceptionConfig> {
        let format = match self.format.as_str() {
            "smpl24-points" => MockFormat::Smpl24Points,
            "coco17-pixels-depth" => MockFormat::Coco17PixelsDepth,
            other => anyhow::bail!(
                "--format must be smpl24-points or coco17-pixels-depth, not '{other}'"
            ),
        };
        Ok(MockPerceptionConfig {
            format,
            rate_hz: self.rate,
            noise_m: self.noise,
            drop_joint_prob: self.drop_joints,
            drop_frame_prob: self.drop_frames,
            latency_ms: self.latency_ms,
            bystander: self.bystander,
            seed: self.seed,
            ..Default::default()
        })
    }
}

/// Publish keypoint frames until `stop`. The camera pose comes from the latest robot joint
/// state (the image shows what the camera really pointed at).
pub async fn serve(args: Args, mut stop: Shutdown) -> Result<()> {
    let cfg = args.config()?;
    let bus = Bus::open(&args.bus, SERVICE).await?;
    let robot_id = bus.robot().clone();
    let states = bus.subscribe(&topics::robot_state(&robot_id)).await?;
    let out = bus.publisher(&topics::perception_raw(&robot_id)).await?;
    let _alive = bus.declare_alive().await?;
    let reporter = bus.spawn_status_reporter(Duration::from_secs(1), stop.clone());
    let model = RobotModel::tiago_dual();
    let mission = mission_of(
        args.scenario.as_deref(),
        args.capture.as_deref(),
        &args.capture_prompt,
    )?;
    let mut mock = match &args.clip {
        _ if mission.is_some() => MockPerception::with_people(
            cfg.clone(),
            mission.as_ref().map(Mission::actors).unwrap_or_default(),
        ),
        Some(spec) if args.robot_plays_b => MockPerception::with_people(
            cfg.clone(),
            echo_sim::perception::clip_partner_for_robot(&clip_of(spec)?),
        ),
        Some(spec) => MockPerception::with_people(
            cfg.clone(),
            echo_sim::perception::clip_actors(&clip_of(spec)?, args.clip_distance),
        ),
        None => MockPerception::new(cfg.clone()),
    };
    let t0 = args.t0_ns.unwrap_or_else(now_ns);
    let mut latest: Option<JointState> = None;
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / cfg.rate_hz.max(0.1)));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let latency = Duration::from_secs_f64(cfg.latency_ms.max(0.0) / 1e3);
    tracing::info!(robot = %robot_id, format = %args.format, "mock perception running");
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            _ = stop.wait() => break,
        }
        if let Some(js) = states.drain().pop() {
            latest = Some(js.msg);
        }
        // Without a joint state the camera cannot be placed: the robot is not up yet.
        let Some(js) = &latest else { continue };
        let q = model.known_values(
            js.name
                .iter()
                .map(String::as_str)
                .zip(js.position.iter().copied()),
        );
        let camera = model.fk(&q, frames::HEAD_CAMERA_OPTICAL)?;
        let stamp = now_ns();
        let t = mock.script_time(stamp.saturating_sub(t0) as f64 / 1e9);
        if let Some(frame) = mock.frame(robot_id.as_str(), t, stamp, &camera) {
            tokio::time::sleep(latency).await;
            out.put(frame).await?;
        }
    }
    let _ = tokio::time::timeout(Duration::from_secs(2), reporter).await;
    bus.close().await
}
