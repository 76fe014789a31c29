//! Training with the retargeter's frozen encoder/decoder around the robot agent: the model sees
//! latents, its losses fall, and only the forecaster's weights are trained.

use echo_hri::codec::RobotCodec;
use echo_hri::train::{gripper_fk, hri_model_config, train, HriTrainConfig, Social};
use echo_motion::synth::{generate_split, Split};

#[test]
fn frozen_retargeter_training_learns_and_leaves_the_retargeter_alone() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let model = echo_robot::RobotModel::tiago_dual();
    let r = echo_retarget::Retargeter::load(&root.join("models/retargeter"), model.clone())
        .expect("models/retargeter");
    let codec = RobotCodec::new(&r);
    let mut ws = vec![];
    for c in &generate_split(Split::Train, 0..3, 2, &|| {}) {
        ws.extend(echo_hri::data::windows(
            &echo_retarget::hri::convert(c, &r).unwrap(),
            6,
        ));
    }
    let cfg = hri_model_config(0, Some(&codec));
    assert_eq!(cfg.agent_features[1], codec.latent() + 10);
    let fk = gripper_fk(&model, &r).unwrap();
    let t = HriTrainConfig {
        epochs: 4,
        batch: 16,
        warmup: 5,
        social: Social::Adaptive,
        frozen_retargeter: true,
        ..Default::default()
    };
    // The option and the codec must agree.
    let plain = HriTrainConfig {
        frozen_retargeter: false,
        ..t.clone()
    };
    assert!(train(&cfg, &plain, &ws, None, &fk, Some(&codec), |_, _, _| {}).is_err());

    let (vm, log) = train(&cfg, &t, &ws, None, &fk, Some(&codec), |_, _, _| {}).unwrap();
    eprintln!(
        "{} windows; loss per epoch {:?}",
        ws.len(),
        log.iter().map(|l| l.total).collect::<Vec<_>>()
    );
    assert!(log.last().unwrap().total < log[0].total);
    let names: Vec<String> = vm.data().lock().unwrap().keys().cloned().collect();
    assert!(names
        .iter()
        .all(|n| !n.contains("robot_enc") && !n.contains("robot_dec")));
}
