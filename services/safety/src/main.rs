//! `safety`: plans in, limited commands out — the only path to the robot.

use anyhow::Result;
use clap::Parser;
use echo_bus::{shutdown, telemetry};

/// The safety filter: plans in, limited per-controller trajectories and a base twist out.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    args: safety::Args,
}

#[tokio::main]
async fn main() -> Result<()> {
    telemetry::init();
    let cli = Cli::parse();
    safety::serve(cli.args, shutdown::on_signals()).await
}
