//! The perception-bridge service: wiring and lifecycle around [`echo_perception::PerceptionBridge`].
//!
//! Inputs: `perception/raw` (KeypointFrame), `robot/state` (JointState).
//! Output: `humans` (HumanSkeletons) at the model rate; `status/perception-bridge`.

use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use echo_bus::shutdown::Shutdown;
use echo_bus::{topics, Bus, BusArgs, Received, Stats};
use echo_msgs::{now_ns, HumanSkeletons, JointState, KeypointFrame};
use echo_perception::{BridgeConfig, PerceptionBridge};
use echo_robot::RobotModel;
use futures::{Stream, StreamExt};

/// Command-line / environment configuration of the service.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Network.
    #[command(flatten)]
    pub bus: BusArgs,
    /// Bridge configuration (JSON); defaults when absent.
    #[arg(long, env = "ECHO_BRIDGE_CONFIG")]
    pub config: Option<std::path::PathBuf>,
    /// Robot description (URDF); the embedded TIAGo++ when absent.
    #[arg(long, env = "ECHO_URDF")]
    pub urdf: Option<std::path::PathBuf>,
}

struct BusOutput(echo_bus::Publisher<HumanSkeletons>);

impl Output for BusOutput {
    async fn skeletons(&mut self, msg: HumanSkeletons) -> Result<()> {
        self.0.put(msg).await
    }
}

/// Open the bus, wire inputs and outputs, and run until `stop` triggers.
pub async fn serve(args: Args, stop: Shutdown) -> Result<()> {
    let cfg = match &args.config {
        Some(p) => BridgeConfig::from_file(p).map_err(anyhow::Error::msg)?,
        None => BridgeConfig::default(),
    };
    cfg.check().map_err(anyhow::Error::msg)?;
    let model = match &args.urdf {
        Some(p) => {
            RobotModel::from_urdf_file(p).with_context(|| format!("loading {}", p.display()))?
        }
        None => RobotModel::tiago_dual(),
    };
    let bus = Bus::open(&args.bus, SERVICE).await?;
    let robot = bus.robot().clone();
    let keypoints = bus.subscribe(&topics::perception_raw(&robot)).await?;
    let states = bus.subscribe(&topics::robot_state(&robot)).await?;
    let mut output = BusOutput(bus.publisher(&topics::humans(&robot)).await?);
    let alive = bus.declare_alive().await?;
    let reporter = bus.spawn_status_reporter(Duration::from_secs(1), stop.clone());

    let kp = futures::stream::unfold(keypoints, |ib| async move {
        ib.recv().await.map(|r| (Input::Keypoints(r), ib))
    });
    let js = futures::stream::unfold(states, |ib| async move {
        ib.recv().await.map(|r| (Input::JointState(r), ib))
    });
    let mut stop_inputs = stop.clone();
    let inputs = futures::stream::select(kp, js)
        .take_until(Box::pin(async move { stop_inputs.wait().await }));
    tracing::info!(robot = %robot, rate_hz = cfg.rate_hz, "perception bridge running");
    let stats = bus.stats();
    run(
        Box::pin(inputs),
        &mut output,
        PerceptionBridge::new(cfg, model),
        &stats,
        now_ns,
    )
    .await?;
    let _ = tokio::time::timeout(Duration::from_secs(2), reporter).await;
    drop(alive);
    bus.close().await?;
    tracing::info!("perception bridge stopped");
    Ok(())
}

/// Service name (liveliness token, status key, logs).
pub const SERVICE: &str = "perception-bridge";

/// Edge name of the keypoint input in counters.
pub const INPUT_EDGE: &str = "perception_raw";

/// One input event.
#[derive(Debug)]
pub enum Input {
    /// A keypoint frame from the pose estimator.
    Keypoints(Received<KeypointFrame>),
    /// A robot joint state.
    JointState(Received<JointState>),
}

/// Where the service's output goes.
pub trait Output {
    /// Publish one skeletons message.
    fn skeletons(
        &mut self,
        msg: HumanSkeletons,
    ) -> impl std::future::Future<Output = Result<()>> + Send;
}

/// Run the bridge over `inputs` until they end. `wall_now_ns` reads the receiver's wall clock
/// (compared with capture stamps for staleness). Rejections are counted in `stats` and logged.
pub async fn run<S, O>(
    mut inputs: S,
    output: &mut O,
    mut bridge: PerceptionBridge,
    stats: &Stats,
    wall_now_ns: impl Fn() -> u64,
) -> Result<()>
where
    S: Stream<Item = Input> + Unpin,
    O: Output,
{
    while let Some(input) = inputs.next().await {
        match input {
            Input::JointState(js) => bridge.on_joint_state(&js.msg),
            Input::Keypoints(frame) => {
                let started = Instant::now();
                match bridge.on_keypoints(&frame.msg, wall_now_ns()) {
                    Ok(out) => {
                        for e in &out.rejected_people {
                            stats.rejected(INPUT_EDGE, e.reason(), &e.to_string());
                        }
                        for s in out.skeletons {
                            output.skeletons(s).await?;
                        }
                        stats.latency_ms(started.elapsed().as_secs_f64() * 1e3);
                    }
                    Err(e) => stats.rejected(INPUT_EDGE, e.reason(), &e.to_string()),
                }
            }
        }
    }
    Ok(())
}
