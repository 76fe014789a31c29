//! `pose-estimator`: the head camera's images in, keypoints for the perception bridge out.

use anyhow::Result;
use clap::Parser;
use echo_bus::{shutdown, telemetry};

/// The head camera's images in (ROS 2 over zenoh-bridge-ros2dds, or an image folder), the
/// people's COCO-17 keypoints out on `perception/raw`.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    args: pose_estimator::Args,
}

#[tokio::main]
async fn main() -> Result<()> {
    telemetry::init();
    let cli = Cli::parse();
    pose_estimator::serve(cli.args, shutdown::on_signals()).await
}
