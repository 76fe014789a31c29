//! Engage or reset the emergency stop on `echo/<robot>/estop`. The safety service latches an
//! engage (the robot brakes to rest and holds) until a reset arrives.
//!
//! ```sh
//! cargo run --example send_estop -- --robot tiago --reason "hand in the way"
//! cargo run --example send_estop -- --robot tiago --reset
//! ```

use std::time::Duration;

use clap::Parser;
use echo_bus::{topics, Bus, BusArgs};
use echo_msgs::{EStop, EStopAction, Header};

#[derive(Parser)]
struct Args {
    /// Network and robot id.
    #[command(flatten)]
    bus: BusArgs,
    /// Reset instead of engage.
    #[arg(long)]
    reset: bool,
    /// Who and why (kept in the safety status).
    #[arg(long, default_value = "operator")]
    reason: String,
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let bus = Bus::open(&args.bus, "example-estop").await?;
    let estop = bus.publisher(&topics::estop(bus.robot())).await?;
    // Give the subscribers' routes a moment to reach this new session, then send it three
    // times (an e-stop is idempotent; a lost first sample must not matter).
    tokio::time::sleep(Duration::from_millis(500)).await;
    for _ in 0..3 {
        estop
            .put(EStop {
                header: Header::new(bus.robot().as_str(), "", ""),
                action: if args.reset {
                    EStopAction::Reset
                } else {
                    EStopAction::Engage
                },
                reason: args.reason.clone(),
            })
            .await?;
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    println!(
        "e-stop {} sent to robot '{}'",
        if args.reset { "reset" } else { "engage" },
        bus.robot()
    );
    bus.close().await?;
    Ok(())
}
