//! Every backend the service offers loads the shipped checkpoint and forecasts the same window
//! alike (ONNX Runtime within 1e-4 of candle).

use clap::Parser;
use forecaster::{load_backend, Args};

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    args: Args,
}

fn args(backend: &str) -> Args {
    args_for("forecaster", backend)
}

fn args_for(model: &str, backend: &str) -> Args {
    let model = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../models")
        .join(model);
    Cli::parse_from([
        "forecaster",
        "--model",
        model.to_str().unwrap_or_default(),
        "--backend",
        backend,
    ])
    .args
}

/// The default backend is the fastest one that agrees with candle: ONNX Runtime, for the
/// human–human and the human–robot model, where its library is installed; candle otherwise.
#[test]
fn the_default_backend_is_onnx_runtime_where_it_agrees_with_candle() {
    let parsed = Cli::parse_from(["forecaster"]).args;
    assert_eq!(parsed.backend, forecaster::BackendKind::Auto);
    let ort = match echo_onnx::runtime::locate_dylib() {
        Some(_) => "onnxruntime-cpu",
        None => "candle-cpu",
    };
    for (model, want) in [("forecaster", ort), ("hri", ort)] {
        let (b, _, _) = load_backend(&args_for(model, "auto")).unwrap();
        assert_eq!(b.name(), want, "{model}");
    }
}

#[test]
fn candle_onnx_and_zero_velocity_backends_agree_on_shapes_and_values() {
    if echo_onnx::runtime::locate_dylib().is_none() {
        assert!(
            std::env::var("ECHO_REQUIRE_ASSETS").is_err(),
            "ONNX Runtime not installed: run scripts/setup"
        );
        return;
    }
    let (mut candle, text, _) = load_backend(&args("candle")).unwrap();
    let (mut ort, _, _) = load_backend(&args("onnx")).unwrap();
    let (mut zv, _, _) = load_backend(&args("zero-velocity")).unwrap();
    // An unknown backend is refused when the flags are parsed, naming the choices.
    let e = Cli::try_parse_from(["forecaster", "--backend", "tensorrt"])
        .err()
        .expect("tensorrt is not a backend");
    assert!(
        e.to_string().contains("auto, candle, onnx, zero-velocity"),
        "{e}"
    );
    let cfg = candle.config().clone();
    let clip = echo_motion::synth::generate(&echo_motion::synth::Split::Test.clip(0));
    let w = echo_eval::window::windows(&clip, 8);
    let refs: Vec<&echo_eval::Window> = w.iter().take(3).collect();
    let (_, obs) = echo_train::encode_observed(&refs, cfg.obs);
    let emb = text
        .expect("the shipped model reads text")
        .embed_one(&clip.texts[0])
        .unwrap();
    let t: Vec<f32> = (0..3).flat_map(|_| emb.iter().copied()).collect();
    let a = candle.predict(3, &obs, &t).unwrap();
    let b = ort.predict(3, &obs, &t).unwrap();
    let z = zv.predict(3, &obs, &[]).unwrap();
    assert_eq!(a.len(), b.len());
    assert_eq!(a.len(), z.len());
    let d = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0f32, f32::max);
    assert!(d < 1e-4, "candle and ONNX Runtime differ by {d}");
}
