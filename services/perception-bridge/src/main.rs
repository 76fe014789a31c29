//! `perception-bridge`: pose-estimator keypoints in, tracked skeletons in base_footprint out.

use anyhow::Result;
use clap::Parser;
use echo_bus::{shutdown, telemetry};

/// Pose-estimator keypoints in, tracked 22-joint skeletons in base_footprint out.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    args: perception_bridge::Args,
}

#[tokio::main]
async fn main() -> Result<()> {
    telemetry::init();
    let cli = Cli::parse();
    perception_bridge::serve(cli.args, shutdown::on_signals()).await
}
