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

fn main() -> Result<()> {
    // Before the runtime's threads start: candle's thread count, read once.
    echo_models::threads::fix_candle_thread_count();
    tokio::runtime::Runtime::new()?.block_on(async {
        telemetry::init();
        let cli = Cli::parse();
        retargeter::serve(cli.args, shutdown::on_signals()).await
    })
}
