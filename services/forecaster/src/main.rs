//! `forecaster`: partner skeletons (and the robot's state and prompt) in, forecasts out.

use anyhow::Result;
use clap::Parser;
use echo_bus::{shutdown, telemetry};

/// The dual-agent social forecaster, batched across the robots it serves.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    args: forecaster::Args,
}

#[tokio::main]
async fn main() -> Result<()> {
    telemetry::init();
    let cli = Cli::parse();
    forecaster::serve(cli.args, shutdown::on_signals()).await
}
