//! The shipped checkpoint (models/forecaster, produced by `echoctl train forecaster`) loads and
//! beats the zero- and constant-velocity baselines on held-out test windows at every horizon
//! of 0.5 s and beyond.

use echo_eval::window::{windows, ConstantVelocity, ZeroVelocity};
use echo_eval::{evaluate, HORIZONS_S};
use echo_models::Checkpoint;
use echo_motion::synth::{generate_split, Split, KINDS};

#[test]
fn shipped_checkpoint_beats_the_baselines_on_the_test_split() {
    let stem = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/forecaster");
    let ck = Checkpoint::load(&stem, &candle_core::Device::Cpu)
        .expect("models/forecaster.{safetensors,json}");
    assert!(
        ck.meta.command.contains("train forecaster"),
        "made by the documented command: {}",
        ck.meta.command
    );
    // Test split: seeds disjoint from training and validation.
    let clips = generate_split(Split::Test, 0..4 * KINDS.len() as u64, 2, &|| {});
    let w: Vec<_> = clips.iter().flat_map(|c| windows(c, 8)).collect();
    let model = evaluate(&mut ck.predictor("forecaster"), &w, 64);
    let zv = evaluate(&mut ZeroVelocity, &w, 64);
    let cv = evaluate(&mut ConstantVelocity, &w, 64);
    for (i, h) in HORIZONS_S.iter().enumerate().filter(|(_, h)| **h >= 0.5) {
        let (m, z, c) = (model.overall.jpe[i], zv.overall.jpe[i], cv.overall.jpe[i]);
        eprintln!("{h} s: forecaster {m:.1} mm, zero-velocity {z:.1}, constant-velocity {c:.1}");
        assert!(m < z && m < c, "at {h} s the forecaster ({m:.1} mm) must beat zero ({z:.1}) and constant velocity ({c:.1})");
    }
}

/// The shipped single-agent variant (models/forecaster-single-agent: the same clips, epochs and
/// schedule, no cross-attention) loses to the full model where the partner's motion decides
/// one's own: wave back, bow back and handover, on test clips neither saw.
#[test]
fn shipped_checkpoint_beats_the_single_agent_variant_on_reaction_types() {
    let models = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models");
    let dev = candle_core::Device::Cpu;
    let full = Checkpoint::load(&models.join("forecaster"), &dev).expect("models/forecaster");
    let single = Checkpoint::load(&models.join("forecaster-single-agent"), &dev)
        .expect("models/forecaster-single-agent");
    assert_eq!(
        single.meta.model.rounds, 0,
        "the single-agent variant has no cross-attention"
    );
    let kinds = ["wave", "bow", "handover"];
    let clips = generate_split(Split::Test, 0..8 * KINDS.len() as u64, 2, &|| {});
    let w: Vec<_> = clips
        .iter()
        .flat_map(|c| windows(c, 8))
        .filter(|w| {
            serde_json::to_value(w.kind)
                .ok()
                .and_then(|v| v.as_str().map(|s| kinds.contains(&s)))
                .unwrap_or(false)
        })
        .collect();
    let f = evaluate(&mut full.predictor("full"), &w, 64);
    let s = evaluate(&mut single.predictor("single-agent"), &w, 64);
    for (i, h) in HORIZONS_S.iter().enumerate().filter(|(_, h)| **h >= 0.5) {
        let (a, b) = (f.overall.jpe[i], s.overall.jpe[i]);
        eprintln!("{h} s, wave + bow + handover: full {a:.1} mm, single-agent {b:.1}");
        assert!(
            a < b,
            "at {h} s the full model ({a:.1} mm) must beat the single-agent one ({b:.1})"
        );
        if *h <= 1.0 {
            for k in kinds {
                let (a, b) = (f.per_kind[k].jpe[i], s.per_kind[k].jpe[i]);
                assert!(a < b, "{k} at {h} s: full {a:.1} mm, single-agent {b:.1}");
            }
        }
    }
}

/// Real people: on real two-person captures in no training data of the shipped model — CMU
/// 18_01 + 19_01 (walk up and shake hands, `../shared/data/cmu`) and CMU 33_02 + 34_02 (walking
/// towards, around and away from each other; the test capture of `data/cmu`) — the shipped
/// checkpoint beats both zero and constant velocity at every horizon, in JPE and in
/// root-aligned AJPE. 18_01 is skipped (with a message) when `../shared/data/cmu` is not beside
/// the repository, unless ECHO_REQUIRE_ASSETS=1. Ignored until a shipped model passes it
/// (docs/RESULTS.md, "Real people"); run it with
/// `cargo test -p echo-models --test checkpoint -- --ignored`.
#[test]
#[ignore = "the shipped forecaster does not yet beat both baselines on real captures (docs/RESULTS.md)"]
fn shipped_checkpoint_beats_both_baselines_on_real_captures() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let cmu = root.join("../shared/data/cmu");
    let mut captures = vec![(
        format!(
            "bvh:{}+{}@Two people walk towards each other, move around each other and apart.",
            root.join("data/cmu/33_02.bvh").display(),
            root.join("data/cmu/34_02.bvh").display()
        ),
        291,
    )];
    if cmu.join("18_01.bvh").is_file() {
        captures.push((
            format!(
                "bvh:{}+{}@Two people walk up to each other and shake hands.",
                cmu.join("18_01.bvh").display(),
                cmu.join("19_01.bvh").display()
            ),
            8,
        ));
    } else {
        assert!(
            std::env::var("ECHO_REQUIRE_ASSETS").as_deref() != Ok("1"),
            "{} is missing",
            cmu.display()
        );
        eprintln!("18_01 skipped: {} is not there", cmu.display());
    }
    let ck = Checkpoint::load(&root.join("models/forecaster"), &candle_core::Device::Cpu).unwrap();
    for (spec, windows) in captures {
        let per =
            echo_data::captures(&echo_data::Spec::parse(&spec).unwrap(), Split::Test, 0).unwrap();
        let w = echo_data::windows(
            &per,
            &echo_data::Cut {
                stride: 1,
                real_stride: 1,
                augment: echo_data::augment::Augment::NONE,
                seed: 0,
            },
        );
        assert_eq!(w.len(), windows, "{spec}: windows at stride 1");
        let model = evaluate(&mut ck.predictor("forecaster"), &w, 64);
        let zv = evaluate(&mut ZeroVelocity, &w, 64);
        let cv = evaluate(&mut ConstantVelocity, &w, 64);
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
                eprintln!("{spec}: {metric} {h} s: forecaster {m:.1} mm, zero velocity {z:.1}, constant velocity {c:.1}");
                assert!(
                    m < z && m < c,
                    "{metric} at {h} s on {spec}: the forecaster ({m:.1} mm) must beat zero ({z:.1}) and constant velocity ({c:.1})"
                );
            }
        }
    }
}
