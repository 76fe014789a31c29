//! `echoctl eval`: score predictors on a split the way the paper does.

use std::path::PathBuf;

use anyhow::{anyhow, Result};
use echo_eval::harness::{markdown_per_kind, markdown_table};
use echo_eval::window::{windows, ConstantVelocity, ZeroVelocity};
use echo_eval::{evaluate, Predictor, Report};
use echo_motion::synth::{generate_split, Split, KINDS};

use super::data::progress;

/// Options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Split: test or held-out (or train, val).
    #[arg(long, default_value = "test")]
    pub split: String,
    /// Clips per interaction type.
    #[arg(long, default_value_t = 40)]
    pub clips_per_kind: u64,
    /// Predictor: zero-velocity, constant-velocity or all.
    #[arg(long, default_value = "all")]
    pub baseline: String,
    /// Window stride, frames at 15 Hz.
    #[arg(long, default_value_t = 8)]
    pub stride: usize,
    /// Also score trained forecaster checkpoints (stems of .safetensors/.json; repeatable;
    /// named by the file stem in the tables).
    #[arg(long)]
    pub model: Vec<PathBuf>,
    /// Write the reports as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Evaluate and print the table.
pub fn run(args: Args) -> Result<()> {
    let split = Split::parse(&args.split)
        .ok_or_else(|| anyhow!("--split must be train, val, test or held-out"))?;
    let mut predictors: Vec<Box<dyn Predictor>> = match args.baseline.as_str() {
        "zero-velocity" => vec![Box::new(ZeroVelocity)],
        "constant-velocity" => vec![Box::new(ConstantVelocity)],
        "all" => vec![Box::new(ZeroVelocity), Box::new(ConstantVelocity)],
        other => anyhow::bail!(
            "--baseline must be zero-velocity, constant-velocity or all, not '{other}'"
        ),
    };
    let n = args.clips_per_kind * KINDS.len() as u64;
    let pb = progress(n, "generating");
    let clips = generate_split(split, 0..n, 2, &|| pb.inc(1));
    pb.finish_and_clear();
    let w: Vec<_> = clips.iter().flat_map(|c| windows(c, args.stride)).collect();
    let mut reports: Vec<Report> = predictors
        .iter_mut()
        .map(|p| evaluate(p.as_mut(), &w, 64))
        .collect();
    for stem in &args.model {
        let ck = echo_models::Checkpoint::load(stem, &candle_core::Device::Cpu)?;
        let name = stem
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| stem.display().to_string());
        let mut p = ck.predictor(&name);
        reports.push(evaluate(&mut p, &w, 64));
    }
    println!(
        "split {} — {} clips, {} windows (observe 0.53 s, predict 1.53 s at 15 Hz), errors in mm\n",
        args.split,
        clips.len(),
        w.len()
    );
    println!("{}", markdown_table(&reports));
    println!(
        "{}",
        markdown_per_kind(
            &reports,
            &["wave", "bow", "imitation", "handover", "handshake"]
        )
    );
    for r in &reports {
        println!("{}: {:.0} windows/s", r.predictor, r.windows_per_s);
    }
    if let Some(p) = &args.json {
        std::fs::write(p, serde_json::to_vec_pretty(&reports)?)?;
    }
    Ok(())
}
