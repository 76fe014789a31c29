//! `echoctl monitor <key-expr>`: print live messages, like `ros2 topic echo`.

use std::time::Duration;

use anyhow::{anyhow, Result};
use echo_bus::{Bus, BusArgs};
use echo_msgs::now_ns;

/// Options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Key expression, e.g. 'echo/tiago/humans' or 'echo/tiago/**'.
    pub key: String,
    /// Network.
    #[command(flatten)]
    pub bus: BusArgs,
    /// Stop after this many messages.
    #[arg(long)]
    pub count: Option<usize>,
    /// One compact line per message instead of pretty JSON.
    #[arg(long)]
    pub compact: bool,
    /// Stop after this many seconds.
    #[arg(long)]
    pub duration: Option<f64>,
}

/// Print messages on `key` until interrupted, `count` messages or `duration` seconds.
pub async fn run(args: Args) -> Result<()> {
    let bus = Bus::open(&args.bus, "echoctl-monitor").await?;
    let sub = bus
        .session()
        .declare_subscriber(args.key.as_str())
        .await
        .map_err(|e| anyhow!("subscribing to {}: {e}", args.key))?;
    let deadline = args
        .duration
        .map(|d| tokio::time::Instant::now() + Duration::from_secs_f64(d));
    let mut seen = 0usize;
    let mut stop = echo_bus::shutdown::on_signals();
    loop {
        let sample = tokio::select! {
            s = sub.recv_async() => match s { Ok(s) => s, Err(_) => break },
            _ = stop.wait() => break,
            _ = async { match deadline { Some(d) => tokio::time::sleep_until(d).await, None => std::future::pending().await } } => break,
        };
        let bytes = sample.payload().to_bytes();
        let key = sample.key_expr().as_str().to_string();
        let body = match serde_json::from_slice::<serde_json::Value>(&bytes) {
            Ok(v) => {
                let age = v
                    .pointer("/header/stamp_ns")
                    .and_then(|s| s.as_u64())
                    .map(|s| format!(" age {:.1} ms", (now_ns() as f64 - s as f64) / 1e6))
                    .unwrap_or_default();
                let text = if args.compact {
                    serde_json::to_string(&v)?
                } else {
                    serde_json::to_string_pretty(&v)?
                };
                format!("{age}\n{text}")
            }
            Err(e) => format!(" ({} bytes, not JSON: {e})", bytes.len()),
        };
        println!("--- {key}{body}");
        seen += 1;
        if args.count.is_some_and(|c| seen >= c) {
            break;
        }
    }
    drop(sub);
    bus.close().await
}
