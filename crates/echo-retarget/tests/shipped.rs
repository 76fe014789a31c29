//! The shipped retargeter (models/retargeter, from `echoctl train retargeter`) maps held-out
//! human arms onto TIAGo++ within a few degrees per limb, always inside the joint limits, far
//! better than holding the robot's home pose; the head and torso rules stay inside their limits.

use echo_motion::synth::{generate, Split};
use echo_retarget::eval::{evaluate, evaluate_constant};
use echo_retarget::retargeter::{head_rule, torso_rule};
use echo_retarget::train::HumanSet;
use echo_retarget::Retargeter;
use echo_robot::RobotModel;

fn shipped() -> Retargeter {
    let stem = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/retargeter");
    Retargeter::load(&stem, RobotModel::tiago_dual()).expect("models/retargeter")
}

#[test]
fn shipped_retargeter_beats_the_home_pose_on_held_out_poses() {
    let r = shipped();
    assert!(
        r.meta.command.contains("train retargeter"),
        "{}",
        r.meta.command
    );
    let model = RobotModel::tiago_dual();
    let held = HumanSet::from_split(Split::HeldOut, 0..26, 6);
    let ev = evaluate(r.net(), &model, &held).unwrap();
    let home = echo_retarget::net::home_arms();
    let base = evaluate_constant(&model, &held, &home).unwrap();
    eprintln!(
        "held-out split: retargeter {:.1}°, home pose {:.1}° (mean limb angle)",
        ev.mean_deg, base.mean_deg
    );
    assert_eq!(ev.within_limits, 1.0);
    assert!(ev.mean_deg < 12.0, "mean limb angle {:.1}°", ev.mean_deg);
    assert!(ev.mean_deg < base.mean_deg / 3.0);
}

#[test]
fn rules_stay_inside_limits_and_follow_posture() {
    let r = shipped();
    let model = RobotModel::tiago_dual();
    let clip = generate(&Split::Test.clip(5)); // bow and bow back
    let poses: Vec<_> = (0..clip.frames.len()).map(|f| clip.joints(f, 0)).collect();
    let out = r.retarget(&poses).unwrap();
    let mut torso = vec![];
    for p in out.iter().flatten() {
        assert_eq!(p.names.len(), 17);
        for (n, v) in p.names.iter().zip(&p.positions) {
            let l = model.limits(n).unwrap();
            assert!(
                *v >= l.soft_lower - 1e-9 && *v <= l.soft_upper + 1e-9,
                "{n} = {v}"
            );
        }
        torso.push(p.positions[14]);
    }
    assert_eq!(torso.len(), poses.len());
    // Bowing lowers the torso and tilts the head down at some point of the clip.
    let (lo, hi) = torso
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(*v), b.max(*v)));
    assert!(hi - lo > 0.02, "torso range {lo}..{hi}");
    let tilts: Vec<f64> = poses.iter().map(|p| head_rule(&model, p).1).collect();
    let tmax = tilts.iter().cloned().fold(f64::MIN, f64::max);
    assert!(tmax > 0.2, "head tilt at most {tmax}");
    assert!(
        torso_rule(&model, &poses[0]) > 0.2,
        "standing upright: torso high"
    );
}
