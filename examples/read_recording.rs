//! Read a recording (`echoctl record`, or the `recording.mcap` every demo run writes): how many
//! messages arrived on each key over how long, and the first message of each kind decoded.
//!
//! ```sh
//! cargo run --example read_recording -- /tmp/echo-demo-1234/recording.mcap
//! ```

use std::collections::BTreeMap;
use std::path::PathBuf;

use clap::Parser;
use echo_msgs::{decode, Forecast, HumanSkeletons, JointState, RobotCommand, SafetyStatus};

#[derive(Parser)]
struct Args {
    /// The MCAP file.
    path: PathBuf,
}

/// A one-line reading of a payload on `key` (`echo/<robot>/<edge>`), through the typed
/// message of its edge (docs/PROTOCOL.md).
fn describe(key: &str, payload: &[u8]) -> String {
    let edge = key.splitn(3, '/').nth(2).unwrap_or("");
    let parsed = match edge {
        "humans" => {
            decode::<HumanSkeletons>(payload).map(|m| format!("{} people tracked", m.tracks.len()))
        }
        "forecast" => decode::<Forecast>(payload)
            .map(|m| format!("{} predicted frames at {} Hz", m.human.len(), m.rate_hz)),
        "robot/state" => {
            decode::<JointState>(payload).map(|m| format!("{} joints measured", m.name.len()))
        }
        "command" => decode::<RobotCommand>(payload)
            .map(|m| format!("{} controller trajectories", m.trajectories.len())),
        "safety/status" => decode::<SafetyStatus>(payload)
            .map(|m| format!("{:?}, speed scale {:.2}", m.state, m.speed_scale)),
        _ => return format!("{} bytes", payload.len()),
    };
    parsed.unwrap_or_else(|e| format!("undecodable: {e}"))
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let messages = echo_record::read_recording(&args.path)?;
    anyhow::ensure!(!messages.is_empty(), "{}: no messages", args.path.display());
    let t0 = messages[0].log_time_ns;
    let t1 = messages[messages.len() - 1].log_time_ns;
    let mut per_key: BTreeMap<&str, (usize, &[u8])> = BTreeMap::new();
    for m in &messages {
        per_key.entry(&m.key).or_insert((0, &m.payload)).0 += 1;
    }
    println!(
        "{}: {} messages on {} keys over {:.1} s",
        args.path.display(),
        messages.len(),
        per_key.len(),
        (t1 - t0) as f64 / 1e9
    );
    for (key, (n, first)) in per_key {
        println!("  {key:<40} {n:>6}   first: {}", describe(key, first));
    }
    Ok(())
}
