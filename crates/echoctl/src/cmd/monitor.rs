//! `echoctl monitor <key-expr>`: print live messages, like `ros2 topic echo`.

use std::time::Duration;

use anyhow::Result;
use echo_bus::observer::{self, Observation};
use echo_bus::{Bus, BusArgs};

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

/// Print messages on `key` until interrupted, `count` messages or `duration` seconds. Messages
/// on Echo's topics are decoded and validated as their topic's type (`echo_bus::observer`): an
/// invalid one is printed with the reason it would be refused.
pub async fn run(args: Args) -> Result<()> {
    let bus = Bus::open(&args.bus, "echoctl-monitor").await?;
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel();
    let sub = observer::observe(&bus, &args.key, move |ob| {
        let _ = tx.send(ob);
    })
    .await?;
    let deadline = args
        .duration
        .map(|d| tokio::time::Instant::now() + Duration::from_secs_f64(d));
    let mut seen = 0usize;
    let mut stop = echo_bus::shutdown::on_signals();
    loop {
        let ob = tokio::select! {
            o = rx.recv() => match o { Some(o) => o, None => break },
            _ = stop.wait() => break,
            _ = async { match deadline { Some(d) => tokio::time::sleep_until(d).await, None => std::future::pending().await } } => break,
        };
        println!("--- {}{}", ob.key, describe(&ob, args.compact)?);
        seen += 1;
        if args.count.is_some_and(|c| seen >= c) {
            break;
        }
    }
    drop(sub);
    bus.close().await
}

/// The age, validity and body of one observed message.
fn describe(ob: &Observation, compact: bool) -> Result<String> {
    let verdict = match &ob.message {
        Some(Ok(_)) => ob
            .age_ms()
            .map(|a| format!(" age {a:.1} ms"))
            .unwrap_or_default(),
        Some(Err(e)) => format!(" INVALID: {e}"),
        None => String::new(),
    };
    let body = match serde_json::from_slice::<serde_json::Value>(&ob.payload) {
        Ok(v) if compact => serde_json::to_string(&v)?,
        Ok(v) => serde_json::to_string_pretty(&v)?,
        Err(e) => format!("({} bytes, not JSON: {e})", ob.payload.len()),
    };
    Ok(format!("{verdict}\n{body}"))
}
