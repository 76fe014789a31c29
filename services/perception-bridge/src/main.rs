//! `perception-bridge`: pose-estimator keypoints in, tracked skeletons in base_footprint out.

use std::time::Duration;

use anyhow::{Context, Result};
use clap::Parser;
use echo_bus::{shutdown, telemetry, topics, Bus, BusArgs};
use echo_msgs::{now_ns, HumanSkeletons};
use echo_perception::{BridgeConfig, PerceptionBridge};
use echo_robot::RobotModel;
use futures::StreamExt;
use perception_bridge::{run, Input, Output, SERVICE};

/// Pose-estimator keypoints in, tracked 22-joint skeletons in base_footprint out.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    #[command(flatten)]
    bus: BusArgs,
    /// Bridge configuration (JSON); defaults when absent.
    #[arg(long, env = "ECHO_BRIDGE_CONFIG")]
    config: Option<std::path::PathBuf>,
    /// Robot description (URDF); the embedded TIAGo++ when absent.
    #[arg(long, env = "ECHO_URDF")]
    urdf: Option<std::path::PathBuf>,
}

struct BusOutput(echo_bus::Publisher<HumanSkeletons>);

impl Output for BusOutput {
    async fn skeletons(&mut self, msg: HumanSkeletons) -> Result<()> {
        self.0.put(msg).await
    }
}

#[tokio::main]
async fn main() -> Result<()> {
    telemetry::init();
    let args = Args::parse();
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
    let _alive = bus.declare_alive().await?;
    let mut stop = shutdown::on_signals();
    let reporter = bus.spawn_status_reporter(Duration::from_secs(1), stop.clone());

    let kp = futures::stream::unfold(keypoints, |ib| async move {
        ib.recv().await.map(|r| (Input::Keypoints(r), ib))
    });
    let js = futures::stream::unfold(states, |ib| async move {
        ib.recv().await.map(|r| (Input::JointState(r), ib))
    });
    let inputs =
        futures::stream::select(kp, js).take_until(Box::pin(async move { stop.wait().await }));
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
    bus.close().await?;
    tracing::info!("perception bridge stopped");
    Ok(())
}
