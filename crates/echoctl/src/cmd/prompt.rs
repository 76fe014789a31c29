//! `echoctl prompt`: announce the interaction (text, type, control mode) to a robot, once or
//! repeatedly — what a dialogue manager or an operator does.

use std::time::Duration;

use anyhow::{Context, Result};
use echo_bus::shutdown::Shutdown;
use echo_bus::{topics, Bus, BusArgs};
use echo_msgs::{ControlMode, Header, Interaction, InteractionIntent};

use super::mock_perception::clip_of;

/// Options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Network.
    #[command(flatten)]
    pub bus: BusArgs,
    /// Description of the interaction, e.g. "One person waves, and the other waves back."
    #[arg(long, conflicts_with = "clip")]
    pub text: Option<String>,
    /// Interaction type (snake_case, e.g. wave, handshake, handover, imitation, idle).
    #[arg(long, default_value = "idle", conflicts_with = "clip")]
    pub interaction: String,
    /// Take text and type from a generated clip (`<split>:<index>`), as the mock perception plays it.
    #[arg(long)]
    pub clip: Option<String>,
    /// Control mode: forecast or imitation.
    #[arg(long, default_value = "forecast")]
    pub mode: String,
    /// Repeat every this many seconds until stopped (default: publish once).
    #[arg(long)]
    pub every: Option<f64>,
}

fn snake<T: serde::de::DeserializeOwned>(what: &str, s: &str) -> Result<T> {
    serde_json::from_value(serde_json::Value::String(s.into()))
        .with_context(|| format!("unknown {what} '{s}'"))
}

/// Publish the intent.
pub async fn serve(args: Args, mut stop: Shutdown) -> Result<()> {
    let (text, interaction) = match &args.clip {
        Some(spec) => {
            let clip = clip_of(spec)?;
            (
                clip.texts.first().cloned().unwrap_or_default(),
                clip.params.kind,
            )
        }
        None => (
            args.text.clone().unwrap_or_default(),
            snake::<Interaction>("interaction", &args.interaction)?,
        ),
    };
    let mode: ControlMode = snake("mode", &args.mode)?;
    let bus = Bus::open(&args.bus, "operator").await?;
    let robot = bus.robot().clone();
    let out = bus.publisher(&topics::prompt(&robot)).await?;
    // Let the session reach its peers first.
    tokio::time::sleep(Duration::from_millis(300)).await;
    loop {
        out.put(InteractionIntent {
            header: Header::new(robot.as_str(), "", ""),
            text: text.clone(),
            interaction,
            mode,
        })
        .await?;
        let Some(every) = args.every else { break };
        tokio::select! {
            _ = tokio::time::sleep(Duration::from_secs_f64(every.max(0.05))) => {}
            _ = stop.wait() => break,
        }
    }
    bus.close().await
}
