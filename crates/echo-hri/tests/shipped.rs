//! The shipped HRI checkpoint (models/hri, produced by `echoctl train hri --social none`, see
//! scripts/train-hri) loads and its robot forecasts beat the zero-velocity robot on held-out test
//! windows (JPE* of the robot's kinematic points against the retargeted reference).

use echo_hri::eval::{evaluate, human_baselines, human_forecast, model_forecasts, zero_velocity};
use echo_motion::synth::{generate_split, Split, KINDS};
use echo_robot::collision::RobotBody;
use echo_robot::RobotModel;

#[test]
fn shipped_hri_checkpoint_beats_zero_velocity_on_the_test_split() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let ck = echo_models::Checkpoint::load(&root.join("models/hri"), &candle_core::Device::Cpu)
        .expect("models/hri.{safetensors,json}");
    assert!(ck.meta.command.contains("train hri"), "{}", ck.meta.command);
    assert!(ck.meta.hri_training.is_some(), "an HRI checkpoint");
    let model = RobotModel::tiago_dual();
    let body = RobotBody::tiago(&model).unwrap();
    let r = echo_retarget::Retargeter::load(&root.join("models/retargeter"), model.clone())
        .expect("models/retargeter");
    // Test split: seeds disjoint from training.
    let clips = generate_split(Split::Test, 0..KINDS.len() as u64, 2, &|| {});
    let mut ws = vec![];
    for c in &clips {
        ws.extend(echo_hri::data::windows(
            &echo_retarget::hri::convert(c, &r).unwrap(),
            10,
        ));
    }
    let refs: Vec<_> = ws.iter().collect();
    let mut fc = vec![];
    for chunk in refs.chunks(64) {
        fc.extend(model_forecasts(&ck.model, ck.text.as_ref(), chunk, None).unwrap());
    }
    let m = evaluate("hri", &refs, &fc, &r, &model, &body).unwrap();
    let z = evaluate("zv", &refs, &zero_velocity(&refs), &r, &model, &body).unwrap();
    eprintln!(
        "{} windows: model JPE* {:?} mm, zero-velocity {:?} mm",
        refs.len(),
        m.jpe,
        z.jpe
    );
    for (i, (a, b)) in m.jpe.iter().zip(&z.jpe).enumerate() {
        assert!(
            a < b,
            "horizon {i}: model {a:.1} mm must beat zero velocity {b:.1} mm"
        );
    }
    // The model's other agent, the partner: beyond the first frames it beats holding the pose
    // and extrapolating the last step (at 0.2 s constant velocity is hard to beat: RESULTS).
    let base = human_baselines(&refs);
    let partner = human_forecast("hri", &refs, &ck.model, ck.text.as_ref(), None).unwrap();
    for k in 1..3 {
        let (zv, cv, model) = (base[0].jpe[k], base[1].jpe[k], partner.jpe[k]);
        eprintln!("partner JPE horizon {k}: model {model:.1}, zero velocity {zv:.1}, constant velocity {cv:.1} mm");
        assert!(
            model < zv && model < cv,
            "horizon {k}: {model:.1} vs {zv:.1} / {cv:.1}"
        );
    }
}
