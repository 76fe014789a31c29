//! The exported ONNX graph, run by ONNX Runtime, computes what the candle model computes
//! (within 1e-4) for every architecture variant, and for the shipped checkpoint.

mod common;

use candle_core::{Device, Tensor};
use echo_models::features::FEATURES;
use echo_models::model::ForecasterConfig;
use echo_models::{Backend, CandleBackend, Checkpoint};
use echo_onnx::export::build;
use echo_onnx::OrtBackend;
use prost::Message;

fn runtime_available() -> bool {
    if echo_onnx::runtime::locate_dylib().is_some() {
        return true;
    }
    // scripts/test (CI) runs scripts/setup first and sets ECHO_REQUIRE_ASSETS=1.
    assert!(
        std::env::var("ECHO_REQUIRE_ASSETS").is_err(),
        "ONNX Runtime not installed: run scripts/setup"
    );
    eprintln!("ONNX Runtime not installed: run scripts/setup");
    false
}

fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn every_variant_matches_candle() {
    if !runtime_available() {
        return;
    }
    let dev = Device::Cpu;
    let variants = common::variants();
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path().to_path_buf();
    for (i, cfg) in variants.iter().enumerate() {
        let (model, weights) = common::random_model(cfg);
        let path = dir.join(format!("v{i}.onnx"));
        std::fs::write(&path, build(weights, cfg).unwrap().encode_to_vec()).unwrap();
        let mut ort = OrtBackend::load(&path, cfg.clone(), 1).unwrap();
        for b in [1usize, 3] {
            let obs = Tensor::randn(0f32, 1.0, (b, 2, cfg.obs, FEATURES), &dev).unwrap();
            let text = Tensor::randn(0f32, 1.0, (b, cfg.text_dim.max(1)), &dev).unwrap();
            let text = (cfg.text_dim > 0).then_some(text);
            let want = model
                .forward(&obs, text.as_ref())
                .unwrap()
                .flatten_all()
                .unwrap()
                .to_vec1::<f32>()
                .unwrap();
            let got = ort
                .predict(
                    b,
                    &obs.flatten_all().unwrap().to_vec1::<f32>().unwrap(),
                    &text
                        .map(|t| t.flatten_all().unwrap().to_vec1::<f32>().unwrap())
                        .unwrap_or_default(),
                )
                .unwrap();
            let d = max_diff(&want, &got);
            let scale = want.iter().fold(0f32, |m, x| m.max(x.abs()));
            eprintln!(
                "variant {i}, batch {b}: max |candle − ort| {d:.2e} (outputs up to {scale:.2})"
            );
            assert!(
                d < 1e-4,
                "variant {i} ({cfg:?}), batch {b}: max difference {d}"
            );
        }
    }
}

#[test]
fn shipped_checkpoint_exports_and_matches() {
    if !runtime_available() {
        return;
    }
    let stem = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/forecaster");
    let scratch = tempfile::tempdir().unwrap();
    let out = scratch.path().join("shipped.onnx");
    echo_onnx::export_checkpoint(&stem, &out).unwrap();
    let ck = Checkpoint::load(&stem, &Device::Cpu).unwrap();
    let cfg = ck.meta.model.clone();
    let mut ort = OrtBackend::load(&out, cfg.clone(), 0).unwrap();
    let mut candle = CandleBackend::new(ck, Device::Cpu);
    let b = 16;
    let obs = Tensor::randn(0f32, 0.5, b * 2 * cfg.obs * FEATURES, &Device::Cpu)
        .unwrap()
        .to_vec1::<f32>()
        .unwrap();
    let text = Tensor::randn(0f32, 0.05, b * cfg.text_dim, &Device::Cpu)
        .unwrap()
        .to_vec1::<f32>()
        .unwrap();
    let d = max_diff(
        &candle.predict(b, &obs, &text).unwrap(),
        &ort.predict(b, &obs, &text).unwrap(),
    );
    eprintln!("shipped model, batch {b}: max |candle − ort| {d:.2e}");
    assert!(d <= 1e-4, "shipped model: max difference {d}");
}

/// A model whose agents differ (the HRI model: a person and the robot's joints) exports with
/// one input and one output per agent; ONNX Runtime computes what candle computes, for random
/// weights with and without the velocity prior and for the shipped HRI checkpoint.
#[test]
fn robot_agent_models_match_candle() {
    if !runtime_available() {
        return;
    }
    let dev = Device::Cpu;
    let base = ForecasterConfig {
        agent_features: [FEATURES, echo_models::robot_agent::ROBOT_FEATURES],
        text_dim: 16,
        ..Default::default()
    };
    let scratch = tempfile::tempdir().unwrap();
    for (i, cfg) in [
        base.clone(),
        ForecasterConfig {
            velocity_prior_s: 0.4,
            ..base
        },
    ]
    .iter()
    .enumerate()
    {
        let (model, weights) = common::random_model(cfg);
        let path = scratch.path().join(format!("robot{i}.onnx"));
        std::fs::write(&path, build(weights, cfg).unwrap().encode_to_vec()).unwrap();
        let mut ort = OrtBackend::load(&path, cfg.clone(), 1).unwrap();
        let [fa, fb] = cfg.agent_features;
        for b in [1usize, 3] {
            let xa = Tensor::randn(0f32, 1.0, (b, cfg.obs, fa), &dev).unwrap();
            let xb = Tensor::randn(0f32, 1.0, (b, cfg.obs, fb), &dev).unwrap();
            let text = Tensor::randn(0f32, 1.0, (b, cfg.text_dim), &dev).unwrap();
            let ([ya, yb], _) = model.forward_pair(&xa, &xb, Some(&text)).unwrap();
            let flat = |t: &Tensor| t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
            // The backend layout: per window A's frames, then B's.
            let (xa, xb, ya, yb) = (flat(&xa), flat(&xb), flat(&ya), flat(&yb));
            let mut obs = vec![];
            let mut want = vec![];
            for w in 0..b {
                obs.extend_from_slice(&xa[w * cfg.obs * fa..(w + 1) * cfg.obs * fa]);
                obs.extend_from_slice(&xb[w * cfg.obs * fb..(w + 1) * cfg.obs * fb]);
                want.extend_from_slice(&ya[w * cfg.pred * fa..(w + 1) * cfg.pred * fa]);
                want.extend_from_slice(&yb[w * cfg.pred * fb..(w + 1) * cfg.pred * fb]);
            }
            let got = ort.predict(b, &obs, &flat(&text)).unwrap();
            let d = max_diff(&want, &got);
            eprintln!("robot-agent variant {i}, batch {b}: max |candle − ort| {d:.2e}");
            assert!(d < 1e-4, "robot-agent variant {i}, batch {b}: {d}");
        }
    }
    let stem = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/hri");
    let ck = Checkpoint::load(&stem, &dev).unwrap();
    let mut ort = OrtBackend::from_checkpoint(&stem, ck.meta.model.clone(), 0).unwrap();
    let mut candle = CandleBackend::new(ck, dev);
    let d = echo_models::disagreement(&mut candle, &mut ort, 16).unwrap();
    eprintln!("models/hri, batch 16: max |candle − ort| {d:.2e}");
    assert!(d <= echo_models::PARITY_TOLERANCE, "models/hri: {d}");
}

#[test]
fn wrong_sizes_are_errors() {
    if !runtime_available() {
        return;
    }
    let cfg = ForecasterConfig {
        d_model: 16,
        heads: 2,
        ..Default::default()
    };
    let weights = common::random_weights(&cfg);
    let scratch = tempfile::tempdir().unwrap();
    let path = scratch.path().join("sizes.onnx");
    std::fs::write(&path, build(weights, &cfg).unwrap().encode_to_vec()).unwrap();
    let mut ort = OrtBackend::load(&path, cfg.clone(), 1).unwrap();
    assert!(ort.predict(2, &[0.0; 10], &[]).is_err());
}
