//! Forecaster inference on CPU: the shipped checkpoint at batch 1 and 16, candle and ONNX
//! Runtime, on observed windows of generated test interactions (prompt embedding precomputed,
//! as the service caches it). `cargo bench -p echo-onnx`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use echo_models::{Backend, CandleBackend, Checkpoint};

fn bench(c: &mut Criterion) {
    let stem = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/forecaster");
    let dev = candle_core::Device::Cpu;
    let mut ck = Checkpoint::load(&stem, &dev).expect("models/forecaster");
    let cfg = ck.meta.model.clone();
    let emb = ck
        .text
        .take()
        .map(|e| {
            e.embed_one("One person waves, and the other waves back.")
                .expect("embedding")
        })
        .unwrap_or_default();
    let mut backends: Vec<Box<dyn Backend>> = vec![Box::new(CandleBackend::new(ck, dev))];
    match echo_onnx::OrtBackend::from_checkpoint(&stem, cfg.clone(), 0) {
        Ok(b) => backends.push(Box::new(b)),
        Err(e) => eprintln!("onnxruntime not benchmarked: {e}"),
    }
    let clips =
        echo_motion::synth::generate_split(echo_motion::synth::Split::Test, 0..13, 2, &|| {});
    let windows: Vec<_> = clips
        .iter()
        .flat_map(|c| echo_eval::window::windows(c, 4))
        .collect();
    let mut g = c.benchmark_group("forecaster");
    for b in [1usize, 16] {
        let ws: Vec<&echo_eval::Window> = windows.iter().cycle().take(b).collect();
        let (_, obs) = echo_train::encode_observed(&ws, cfg.obs);
        let text: Vec<f32> = (0..b).flat_map(|_| emb.iter().copied()).collect();
        for be in backends.iter_mut() {
            let name = be.name();
            g.bench_with_input(BenchmarkId::new(name, b), &b, |bench, &b| {
                bench.iter(|| be.predict(b, &obs, &text).expect("forward"))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
