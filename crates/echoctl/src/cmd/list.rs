//! `echoctl list`: which services are alive, from liveliness tokens.

use std::time::Duration;

use anyhow::Result;
use echo_bus::{keys, Bus, BusArgs};

/// Options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Network.
    #[command(flatten)]
    pub bus: BusArgs,
    /// List every robot of the fleet, not only `--robot`.
    #[arg(long)]
    pub all: bool,
    /// How long to wait for replies, ms.
    #[arg(long, default_value_t = 1000)]
    pub timeout_ms: u64,
}

/// Print `robot  service` for every live token.
pub async fn run(args: Args) -> Result<()> {
    let bus = Bus::open(&args.bus, "echoctl-list").await?;
    let key = if args.all {
        keys::alive_fleet()
    } else {
        keys::alive_all(bus.robot())
    };
    // Give the session a moment to connect to its peers before asking.
    tokio::time::sleep(Duration::from_millis(300)).await;
    let alive = bus
        .alive_now(&key, Duration::from_millis(args.timeout_ms))
        .await?;
    if alive.is_empty() {
        println!("no services alive on {key}");
    } else {
        println!("{:<16} SERVICE", "ROBOT");
        for (r, s) in alive {
            println!("{r:<16} {s}");
        }
    }
    bus.close().await
}
