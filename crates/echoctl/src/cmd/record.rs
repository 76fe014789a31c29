//! `echoctl record` and `echoctl replay`: bus traffic to and from MCAP files.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use echo_bus::{keys, shutdown, Bus, BusArgs};
use echo_record::live::{self, ReplayOptions};

/// Options of `echoctl record`.
#[derive(Debug, Clone, clap::Args)]
pub struct RecordArgs {
    /// Network.
    #[command(flatten)]
    pub bus: BusArgs,
    /// Key expressions to record (repeatable); default: everything of `--robot` (`echo/<robot>/**`).
    #[arg(long = "key")]
    pub keys: Vec<String>,
    /// Output MCAP file.
    #[arg(long, short, default_value = "echo.mcap")]
    pub out: PathBuf,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Add 3D scenes and the robot's link frames for Foxglove (/scene, /tf); the file stays a
    /// complete recording of the bus.
    #[arg(long)]
    pub foxglove: bool,
}

/// Options of `echoctl replay`.
#[derive(Debug, Clone, clap::Args)]
pub struct ReplayArgs {
    /// Network.
    #[command(flatten)]
    pub bus: BusArgs,
    /// The MCAP recording.
    pub file: PathBuf,
    /// Playback speed: 1 = original rate, 2 = twice as fast, 0 = as fast as possible.
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Keep the recorded `header.stamp_ns` (default: restamp to the replay time).
    #[arg(long)]
    pub keep_stamps: bool,
    /// Only replay keys containing this text (repeatable), e.g. `perception/raw`.
    #[arg(long)]
    pub only: Vec<String>,
}

/// Record until Ctrl-C or `--seconds`.
pub async fn record(args: RecordArgs) -> Result<()> {
    let bus = Bus::open(&args.bus, "echoctl-record").await?;
    let keys = if args.keys.is_empty() {
        vec![keys::robot_all(bus.robot())]
    } else {
        args.keys.clone()
    };
    let duration = args.seconds.map(Duration::from_secs_f64);
    // With --foxglove the bus is recorded as usual, then converted into the output file.
    let raw = if args.foxglove {
        args.out.with_extension("bus.mcap")
    } else {
        args.out.clone()
    };
    let summary =
        live::record(bus.session(), &keys, &raw, duration, shutdown::on_signals()).await?;
    let scenes = if args.foxglove {
        let opts = echo_scene::foxglove::FoxgloveOptions::default();
        let s = echo_scene::foxglove::convert_recording(&raw, &args.out, &opts)?;
        std::fs::remove_file(&raw).with_context(|| format!("removing {}", raw.display()))?;
        Some(s.scenes)
    } else {
        None
    };
    println!(
        "wrote {} messages to {} ({} dropped)",
        summary.total(),
        args.out.display(),
        summary.dropped
    );
    for (k, n) in &summary.per_key {
        println!("  {n:>8}  {k}");
    }
    if let Some(n) = scenes {
        println!("  {n:>8}  scenes and frame updates for Foxglove (/scene, /tf)");
    }
    bus.close().await
}

/// Replay a recording.
pub async fn replay(args: ReplayArgs) -> Result<()> {
    let records = echo_record::read_recording(&args.file)?;
    let bus = Bus::open(&args.bus, "echoctl-replay").await?;
    // Let the session reach its peers before the first message.
    tokio::time::sleep(Duration::from_millis(300)).await;
    let opts = ReplayOptions {
        speed: args.speed,
        restamp: !args.keep_stamps,
        only: args.only.clone(),
    };
    let sent = live::replay(bus.session(), &records, &opts, shutdown::on_signals()).await?;
    println!(
        "replayed {sent} of {} messages from {}",
        records.len(),
        args.file.display()
    );
    bus.close().await
}
