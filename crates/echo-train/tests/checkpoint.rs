//! The shipped human–human checkpoints (models/forecaster and models/forecaster-synthetic,
//! produced by `echoctl train forecaster`) load and beat the zero- and constant-velocity
//! baselines on held-out synthetic test windows at every horizon of 0.5 s and beyond, and their
//! single-agent variants on reaction types; models/forecaster also on a held-out real capture
//! at every horizon.

use echo_eval::symmetry::Symmetrized;
use echo_eval::window::{windows, ConstantVelocity, ZeroVelocity};
use echo_eval::{evaluate, HORIZONS_S};
use echo_models::Checkpoint;
use echo_motion::synth::{generate_split, Split, KINDS};
use echo_train::CheckpointPredictor;

/// Both shipped human–human forecasters: `forecaster` (real and synthetic data) and
/// `forecaster-synthetic` (synthetic only, the model before real captures).
const SHIPPED: [(&str, &str); 2] = [
    ("forecaster", "forecaster-single-agent"),
    ("forecaster-synthetic", "forecaster-synthetic-single-agent"),
];

fn models() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models")
}

#[test]
fn shipped_checkpoints_beat_the_baselines_on_the_test_split() {
    // Test split: seeds disjoint from training and validation.
    let clips = generate_split(Split::Test, 0..4 * KINDS.len() as u64, 2, &|| {});
    let w: Vec<_> = clips.iter().flat_map(|c| windows(c, 8)).collect();
    let zv = evaluate(&mut ZeroVelocity, &w, 64);
    let cv = evaluate(&mut ConstantVelocity, &w, 64);
    for (name, _) in SHIPPED {
        let ck = Checkpoint::load(&models().join(name), &candle_core::Device::Cpu)
            .unwrap_or_else(|e| panic!("models/{name}.{{safetensors,json}}: {e}"));
        assert!(
            ck.meta.command.contains("train forecaster"),
            "made by the documented command: {}",
            ck.meta.command
        );
        let model = evaluate(&mut ck.predictor(name), &w, 64);
        for (i, h) in HORIZONS_S.iter().enumerate().filter(|(_, h)| **h >= 0.5) {
            let (m, z, c) = (model.overall.jpe[i], zv.overall.jpe[i], cv.overall.jpe[i]);
            eprintln!("{name}, {h} s: {m:.1} mm, zero-velocity {z:.1}, constant-velocity {c:.1}");
            assert!(m < z && m < c, "at {h} s {name} ({m:.1} mm) must beat zero ({z:.1}) and constant velocity ({c:.1})");
        }
    }
}

/// Each shipped single-agent variant (the same data, epochs and schedule, no cross-attention)
/// loses to its full model on test clips neither saw, at every horizon from 0.5 s: the
/// synthetic-only pair on the reaction types, where the partner's motion decides one's own
/// (wave back, bow back and handover; each type up to 1.0 s), the shipped pair over every
/// type. (The shipped pair does not keep the per-type lead on waves and bows at 0.5–1.0 s:
/// docs/RESULTS.md.)
#[test]
fn shipped_checkpoints_beat_their_single_agent_variants() {
    let dev = candle_core::Device::Cpu;
    let reactions = ["wave", "bow", "handover"];
    let clips = generate_split(Split::Test, 0..8 * KINDS.len() as u64, 2, &|| {});
    let all: Vec<_> = clips.iter().flat_map(|c| windows(c, 8)).collect();
    let reaction: Vec<_> = all
        .iter()
        .filter(|w| {
            serde_json::to_value(w.kind)
                .ok()
                .and_then(|v| v.as_str().map(|s| reactions.contains(&s)))
                .unwrap_or(false)
        })
        .cloned()
        .collect();
    for (name, variant) in SHIPPED {
        let full = Checkpoint::load(&models().join(name), &dev).expect("the full model");
        let single = Checkpoint::load(&models().join(variant), &dev).expect("its variant");
        assert_eq!(
            single.meta.model.rounds, 0,
            "{variant} has no cross-attention"
        );
        assert_eq!(
            single.meta.training.data, full.meta.training.data,
            "{variant} saw {name}'s data"
        );
        let (w, kinds): (&[_], &[&str]) = match name {
            "forecaster-synthetic" => (&reaction, &reactions),
            _ => (&all, &[]),
        };
        let f = evaluate(&mut full.predictor("full"), w, 64);
        let s = evaluate(&mut single.predictor("single-agent"), w, 64);
        for (i, h) in HORIZONS_S.iter().enumerate().filter(|(_, h)| **h >= 0.5) {
            let (a, b) = (f.overall.jpe[i], s.overall.jpe[i]);
            eprintln!(
                "{name}, {h} s, {} windows: full {a:.1} mm, single-agent {b:.1}",
                w.len()
            );
            assert!(
                a < b,
                "at {h} s {name} ({a:.1} mm) must beat {variant} ({b:.1})"
            );
            if *h <= 1.0 {
                for k in kinds {
                    let (a, b) = (f.per_kind[*k].jpe[i], s.per_kind[*k].jpe[i]);
                    assert!(
                        a < b,
                        "{name}, {k} at {h} s: full {a:.1} mm, single-agent {b:.1}"
                    );
                }
            }
        }
    }
}

/// A real two-person capture, described by a prompt that names no role or side.
fn real_windows(
    a: &std::path::Path,
    b: &std::path::Path,
    prompt: &str,
) -> Vec<echo_eval::window::Window> {
    let spec = format!("bvh:{}+{}@{prompt}", a.display(), b.display());
    let per = echo_data::captures(&echo_data::Spec::parse(&spec).unwrap(), Split::Test, 0).unwrap();
    echo_data::windows(
        &per,
        &echo_data::Cut {
            stride: 1,
            real_stride: 1,
            augment: echo_data::augment::Augment::NONE,
            seed: 0,
        },
    )
}

/// The shipped forecaster, served symmetrized (`forecaster --symmetrize`), against zero and
/// constant velocity at every horizon, in JPE and root-aligned AJPE.
fn beats_both_baselines_on(capture: &str, w: &[echo_eval::window::Window]) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let ck = Checkpoint::load(&root.join("models/forecaster"), &candle_core::Device::Cpu).unwrap();
    let model = evaluate(&mut Symmetrized(ck.predictor("forecaster")), w, 64);
    let zv = evaluate(&mut ZeroVelocity, w, 64);
    let cv = evaluate(&mut ConstantVelocity, w, 64);
    for (i, h) in HORIZONS_S.iter().enumerate() {
        for (metric, m, z, c) in [
            (
                "JPE",
                model.overall.jpe[i],
                zv.overall.jpe[i],
                cv.overall.jpe[i],
            ),
            (
                "AJPE",
                model.overall.ajpe[i],
                zv.overall.ajpe[i],
                cv.overall.ajpe[i],
            ),
        ] {
            eprintln!("{capture}: {metric} {h} s: forecaster {m:.1} mm, zero velocity {z:.1}, constant velocity {c:.1}");
            assert!(
                m < z && m < c,
                "{metric} at {h} s on {capture}: the forecaster ({m:.1} mm) must beat zero ({z:.1}) and constant velocity ({c:.1})"
            );
        }
    }
}

/// Real people walking: CMU 33_02 + 34_02 (two people walking towards, around and away from
/// each other, 21 s; the test capture of `data/cmu`, in no training data of the shipped
/// model), 291 windows.
#[test]
fn shipped_checkpoint_beats_both_baselines_on_a_held_out_real_walking_capture() {
    let cmu = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/cmu");
    let w = real_windows(
        &cmu.join("33_02.bvh"),
        &cmu.join("34_02.bvh"),
        "Two people walk towards each other, move around each other and apart.",
    );
    assert_eq!(w.len(), 291, "windows at stride 1");
    beats_both_baselines_on("33_02 + 34_02", &w);
}

/// Real people shaking hands: CMU 18_01 + 19_01 (walk up, a 0.3 s handshake, both step back;
/// `../shared/data/cmu`), 8 windows. Skipped (with a message) when `../shared/data/cmu` is not
/// beside the repository, unless ECHO_REQUIRE_ASSETS=1. Ignored until a shipped model passes
/// it: the shipped forecaster predicts the stop but not the step back, and loses to holding the
/// pose at 1.0 and 1.5 s (docs/RESULTS.md, "Real people"); run it with
/// `cargo test -p echo-train --test checkpoint -- --ignored`.
#[test]
#[ignore = "the shipped forecaster does not yet forecast the step back after a handshake (docs/RESULTS.md)"]
fn shipped_checkpoint_beats_both_baselines_on_a_real_handshake_capture() {
    let cmu = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/cmu");
    if !cmu.join("18_01.bvh").is_file() {
        assert!(
            std::env::var("ECHO_REQUIRE_ASSETS").as_deref() != Ok("1"),
            "{} is missing",
            cmu.display()
        );
        eprintln!("18_01 skipped: {} is not there", cmu.display());
        return;
    }
    let w = real_windows(
        &cmu.join("18_01.bvh"),
        &cmu.join("19_01.bvh"),
        "Two people walk up to each other and shake hands.",
    );
    assert_eq!(w.len(), 8, "windows at stride 1");
    beats_both_baselines_on("18_01 + 19_01", &w);
}
