//! `echoctl train forecaster`: train the dual-agent forecaster on generated interactions.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use echo_models::model::ForecasterConfig;
use echo_models::train::{train, TrainConfig};
use echo_models::{Checkpoint, CheckpointMeta};

use super::data::progress;

/// Options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// What to train (forecaster).
    pub what: String,
    /// Output stem: writes <out>.safetensors, <out>.json and <out>.loss.csv.
    #[arg(long, default_value = "models/forecaster")]
    pub out: PathBuf,
    /// Training clips.
    #[arg(long, default_value_t = 2600)]
    pub train_clips: u64,
    /// Wall-clock budget, minutes.
    #[arg(long, default_value_t = 15.0)]
    pub max_minutes: f64,
    /// Epochs at most.
    #[arg(long, default_value_t = 30)]
    pub epochs: usize,
    /// Model width.
    #[arg(long, default_value_t = 64)]
    pub d_model: usize,
    /// Cross-attention rounds (0: single-agent variant).
    #[arg(long, default_value_t = 2)]
    pub rounds: usize,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Train and save.
pub fn run(args: Args) -> Result<()> {
    anyhow::ensure!(
        args.what == "forecaster",
        "only 'forecaster' can be trained so far, not '{}'",
        args.what
    );
    let model = ForecasterConfig {
        d_model: args.d_model,
        rounds: args.rounds,
        ..Default::default()
    };
    let t = TrainConfig {
        train_clips: args.train_clips,
        max_minutes: args.max_minutes,
        epochs: args.epochs,
        seed: args.seed,
        ..Default::default()
    };
    let dev = candle_core::Device::Cpu;
    let pb = progress(0, "training");
    let csv_path = args.out.with_extension("loss.csv");
    if let Some(d) = csv_path.parent() {
        std::fs::create_dir_all(d)?;
    }
    let mut csv = std::fs::File::create(&csv_path)?;
    writeln!(
        csv,
        "epoch,train_loss,val_jpe_0.2,val_jpe_0.5,val_jpe_1.0,val_jpe_1.5,elapsed_s"
    )?;
    let (varmap, log) = train(
        &model,
        &t,
        &dev,
        |k, n, loss| {
            pb.set_length(n as u64);
            pb.set_position(k as u64);
            pb.set_message(format!("loss {loss:.4}"));
        },
        |e| {
            // Printed, not drawn: the epoch summary must also reach logs (no terminal).
            pb.suspend(|| {
                println!(
                    "epoch {}: train loss {:.4}, validation JPE {} mm ({:.0} s)",
                    e.epoch,
                    e.train_loss,
                    e.val_jpe
                        .iter()
                        .map(|x| format!("{x:.1}"))
                        .collect::<Vec<_>>()
                        .join(" / "),
                    e.elapsed_s
                )
            });
            let _ = writeln!(
                csv,
                "{},{:.6},{},{:.1}",
                e.epoch,
                e.train_loss,
                e.val_jpe
                    .iter()
                    .map(|x| format!("{x:.2}"))
                    .collect::<Vec<_>>()
                    .join(","),
                e.elapsed_s
            );
        },
    )?;
    pb.finish_and_clear();
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    let meta = CheckpointMeta {
        model,
        training: t,
        command,
        text_encoder: "none".into(),
        features: "per agent and frame: 22 joints relative to the pelvis in the heading frame (66), pelvis xyz (3), heading quaternion xyzw (4); window frame at A's last observed pelvis and heading".into(),
    };
    Checkpoint::save(&varmap, &meta, &args.out)?;
    println!(
        "{} epochs; saved {}.safetensors/.json, loss curve {}",
        log.len(),
        args.out.display(),
        csv_path.display()
    );
    Ok(())
}
