//! `echoctl bench sizes`: the forecaster at the shipped width (d_model 64, 4 heads, 1
//! self-attention layer) and at d_model 256 (16 heads, 4 layers), both with the shipped
//! model's other settings and random weights: inference at batch 1 and 16 on every backend,
//! one training step (forward, backward, AdamW) at batch 64 on candle, and the floating-point
//! operations of each. The JSON is what `scripts/bench-vs-pytorch` compares with PyTorch.

use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use candle_core::{DType, Device, Tensor};
use candle_nn::{VarBuilder, VarMap};
use echo_bus::stats::percentile_sorted;
use echo_models::model::{Forecaster, ForecasterConfig};
use echo_models::{CheckpointMeta, TrainConfig};
use echo_train::optim::AdamW;
use echo_train::train::{batch_loss, train_step, update};

/// The two sizes: name, width, self-attention layers.
const SIZES: [(&str, usize, usize); 2] = [("d64", 64, 1), ("d256", 256, 4)];

/// Run both sizes, print one line per case, write the JSON when asked.
pub fn run(like: &Path, quick: bool, json: Option<&Path>) -> Result<()> {
    let div = if quick { 5 } else { 1 };
    let mut cases = Vec::new();
    for (name, d, layers) in SIZES {
        let stem = super::bench::untrained(like, d, layers)?;
        let cfg = CheckpointMeta::load(&stem)?.model;
        println!(
            "{name}: {:.1} MFLOP per window (inference), {:.1} MFLOP per window per training step",
            flops_per_window(&cfg, false) / 1e6,
            3.0 * flops_per_window(&cfg, true) / 1e6
        );
        let samples = if d > 64 { 200 } else { 500 } / div;
        let measured = super::bench::forecaster(&stem, samples);
        let _ = std::fs::remove_file(stem.with_extension("safetensors"));
        let _ = std::fs::remove_file(stem.with_extension("json"));
        for (backend, batch, median, n) in measured? {
            cases.push(serde_json::json!({
                "model": name, "batch": batch, "kind": "inference", "backend": backend,
                "median_ms": median, "samples": n,
                "gflop": batch as f64 * flops_per_window(&cfg, false) / 1e9,
            }));
        }
        let steps = if d > 64 { 10 } else { 30 } / div.min(3);
        let (median, n) = train_steps(&cfg, 64, steps.max(3))?;
        println!("{name} training step batch 64 (candle-cpu)  median {median:8.3} ms  n={n}");
        cases.push(serde_json::json!({
            "model": name, "batch": 64, "kind": "train-step", "backend": "candle-cpu",
            "median_ms": median, "samples": n,
            "gflop": 64.0 * 3.0 * flops_per_window(&cfg, true) / 1e9,
        }));
    }
    if let Some(path) = json {
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)?;
        }
        let threads = std::env::var("RAYON_NUM_THREADS").unwrap_or_default();
        std::fs::write(
            path,
            serde_json::to_vec_pretty(&serde_json::json!({
                "backend_note": format!("candle 0.11.1, {threads} threads; ONNX Runtime"),
                "cases": cases,
            }))?,
        )?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// Median milliseconds of `n` training steps at batch `b` on random windows (two warm-up
/// steps first), and `n`.
fn train_steps(cfg: &ForecasterConfig, b: usize, n: usize) -> Result<(f64, usize)> {
    let dev = Device::Cpu;
    let vm = VarMap::new();
    let model = Forecaster::new(cfg.clone(), VarBuilder::from_varmap(&vm, DType::F32, &dev))?;
    let t = TrainConfig::default();
    let mut opt = AdamW::from_varmap(&vm, t.lr, 1e-4)?;
    let f = cfg.agent_features[0];
    let obs = Tensor::randn(0f32, 0.5, (b, 2, cfg.obs, f), &dev)?;
    let fut = Tensor::randn(0f32, 0.5, (b, 2, cfg.pred, f), &dev)?;
    let text = (cfg.text_dim > 0)
        .then(|| Tensor::randn(0f32, 0.05, (b, cfg.text_dim), &dev))
        .transpose()?;
    for _ in 0..2 {
        train_step(&model, &mut opt, &t, &obs, &fut, text.as_ref())?;
    }
    let mut v = Vec::with_capacity(n);
    let mut parts = [Vec::new(), Vec::new(), Vec::new()];
    for i in 0..2 * n {
        let s = Instant::now();
        if i % 2 == 0 {
            train_step(&model, &mut opt, &t, &obs, &fut, text.as_ref())?;
            v.push(s.elapsed().as_secs_f64() * 1e3);
            continue;
        }
        // The same step in its three parts, each timed.
        let loss = batch_loss(&model, &t, &obs, &fut, text.as_ref())?;
        loss.to_scalar::<f32>()?;
        let forward = s.elapsed().as_secs_f64() * 1e3;
        let grads = loss.backward()?;
        let backward = s.elapsed().as_secs_f64() * 1e3;
        update(&mut opt, &t, &grads)?;
        let done = s.elapsed().as_secs_f64() * 1e3;
        for (p, x) in parts
            .iter_mut()
            .zip([forward, backward - forward, done - backward])
        {
            p.push(x);
        }
    }
    let med = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        percentile_sorted(&v, 50.0)
    };
    let [f, b, u] = parts.map(med);
    println!("  training step parts (medians): forward + loss {f:.2} ms, backward {b:.2} ms, clip + AdamW {u:.2} ms");
    Ok((med(v), n))
}

/// Floating-point operations of one window's forward pass (a multiply-add counts two; matrix
/// products only — layer norms, softmax and GELU add a few per cent): `individual` also decodes
/// the self-intent forecast, as training does. A training step costs about three forward
/// passes (the backward pass computes two products per forward product).
pub fn flops_per_window(cfg: &ForecasterConfig, individual: bool) -> f64 {
    let d = cfg.d_model as f64;
    let t = (cfg.frames() + usize::from(cfg.text_dim > 0)) as f64; // tokens
    let frames = cfg.frames() as f64;
    let pred = cfg.pred as f64;
    let mm = |m: f64, k: f64, n: f64| 2.0 * m * k * n;
    // A block: q, k, v, o projections, scores and weighted sum, feed-forward d → 2d → d.
    let block = 4.0 * mm(t, d, d) + 2.0 * mm(t, t, d) + mm(t, d, 2.0 * d) + mm(t, 2.0 * d, d);
    let mut total = 0.0;
    for &f in &cfg.agent_features {
        let f = f as f64;
        total += mm(frames, f, d) + mm(frames, d, d); // embedding
        total += cfg.self_layers as f64 * block;
        total += cfg.temp_mlp as f64 * mm(t, t, d); // time mixing
        total += cfg.rounds as f64 * block; // one cross-attention block per agent per round
        let decode = mm(pred, d, d) + mm(pred, d, f);
        total += if individual { 2.0 * decode } else { decode };
    }
    if cfg.text_dim > 0 {
        total += 2.0 * mm(1.0, cfg.text_dim as f64, d); // the text token, once per agent
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_count_grows_with_width_and_layers_as_the_products_do() {
        let small = ForecasterConfig {
            text_dim: 384,
            ..ForecasterConfig::default()
        };
        let wide = ForecasterConfig {
            d_model: 128,
            ..small.clone()
        };
        let deep = ForecasterConfig {
            self_layers: 2,
            ..small.clone()
        };
        let (s, w, dp) = (
            flops_per_window(&small, false),
            flops_per_window(&wide, false),
            flops_per_window(&deep, false),
        );
        // Mostly d² terms: doubling the width costs between 2× and 4×.
        assert!(w > 2.0 * s && w < 4.0 * s, "{s} → {w}");
        // One more self-attention layer per agent: 2 blocks of 32 tokens.
        let t = 32.0;
        let block = 16.0 * t * 64.0 * 64.0 + 4.0 * t * t * 64.0;
        assert!((dp - s - 2.0 * block).abs() < 1.0, "{}", dp - s);
        assert!(flops_per_window(&small, true) > s);
    }
}
