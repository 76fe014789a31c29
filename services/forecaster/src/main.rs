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

fn main() -> Result<()> {
    // Before the runtime's threads start: candle's thread count, read once.
    echo_models::threads::fix_candle_thread_count();
    tokio::runtime::Runtime::new()?.block_on(async {
        telemetry::init();
        let cli = Cli::parse();
        forecaster::serve(cli.args, shutdown::on_signals()).await
    })
}
