//! Subscribe to the forecaster's output on `echo/<robot>/forecast`: for each forecast, where
//! the tracked partner's pelvis is predicted to be one second ahead, and whether it carries a
//! robot plan (HRI models do).
//!
//! ```sh
//! cargo run --example subscribe_forecasts -- --robot tiago --count 20
//! ```

use std::time::Duration;

use clap::Parser;
use echo_bus::{topics, Bus, BusArgs};

#[derive(Parser)]
struct Args {
    /// Network and robot id.
    #[command(flatten)]
    bus: BusArgs,
    /// Stop after this many forecasts.
    #[arg(long, default_value_t = 10)]
    count: usize,
    /// Give up after this many seconds without one.
    #[arg(long, default_value_t = 30.0)]
    timeout_s: f64,
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let bus = Bus::open(&args.bus, "example-forecasts").await?;
    let inbox = bus.subscribe(&topics::forecast(bus.robot())).await?;
    let mut seen = 0;
    while seen < args.count {
        let wait = Duration::from_secs_f64(args.timeout_s);
        let Ok(Some(rx)) = tokio::time::timeout(wait, inbox.recv()).await else {
            anyhow::bail!("no forecast within {} s", args.timeout_s);
        };
        let f = rx.msg;
        // Frame k is k / rate_hz seconds after the newest observation.
        let k = ((f.rate_hz.max(1.0)).round() as usize).min(f.human.len().saturating_sub(1));
        let pelvis = f.human.get(k).and_then(|joints| joints.first());
        println!(
            "forecast {}: partner {} in 1 s at {:?} m ({} frames, model {}, {:.1} ms){}",
            f.header.seq,
            f.partner_id,
            pelvis.map(|p| [p[0], p[1], p[2]].map(|x| (x * 100.0).round() / 100.0)),
            f.human.len(),
            f.model,
            f.inference_ms,
            if f.robot.is_some() {
                ", with a robot plan"
            } else {
                ""
            }
        );
        seen += 1;
    }
    bus.close().await?;
    Ok(())
}
