//! `retargeter`: live imitation of the partner, and batch retargeting on request.

use anyhow::Result;
use clap::Parser;
use echo_bus::{shutdown, telemetry};

/// Human-to-robot retargeting: imitation plans and a batch queryable.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    args: retargeter::Args,
}

#[tokio::main]
async fn main() -> Result<()> {
    telemetry::init();
    let cli = Cli::parse();
    retargeter::serve(cli.args, shutdown::on_signals()).await
}
