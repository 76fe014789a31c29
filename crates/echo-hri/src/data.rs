//! HRI windows: the human (agent A, 73 features) and the robot (agent B: 17 joint values, base
//! position and heading in the window frame, 24 features), observed 0.53 s and predicted 1.0 s
//! at 15 Hz, plus what the social losses need — the reference person's wrists (whom the robot
//! stands in for) and the adaptive proximity weight of the original pair per future frame.

use echo_models::features::{encode, Canonical, FEATURES};
use echo_motion::sensors::contact_and_proximity;
use echo_motion::skeleton::{j, NUM_JOINTS};
use echo_retarget::hri::HriClip;
use nalgebra::Vector3;

pub use echo_models::robot_agent::{
    decode_robot, encode_robot, robot_joint_names, ROBOT_FEATURES, ROBOT_JOINTS,
};
/// Observed frames.
pub const OBS: usize = 8;
/// Predicted frames (1.0 s).
pub const PRED: usize = 15;

/// One HRI window.
#[derive(Debug, Clone)]
pub struct HriWindow {
    /// Interaction type.
    pub kind: String,
    /// Descriptions.
    pub texts: Vec<String>,
    /// The window frame (A at the last observed frame).
    pub canon: Canonical,
    /// Human features, observed then future (OBS + PRED).
    pub human: Vec<[f32; FEATURES]>,
    /// Robot features (the retargeted reference), observed then future.
    pub robot: Vec<[f32; ROBOT_FEATURES]>,
    /// Reference person's wrists (L, R) per future frame, window frame.
    pub ref_wrists: Vec<[[f32; 3]; 2]>,
    /// Adaptive proximity weight of the original pair per future frame: `0.5 S_0 + 0.5 S_0.05`.
    pub w_pr: Vec<f32>,
    /// Human A's future joints (world), for the social metrics.
    pub human_world: Vec<[Vector3<f64>; NUM_JOINTS]>,
    /// Reference B's future joints (world).
    pub reference_world: Vec<[Vector3<f64>; NUM_JOINTS]>,
}

/// Cut windows (every `stride` frames at 15 Hz) from an HRI clip recorded at 30 fps.
pub fn windows(c: &HriClip, stride: usize) -> Vec<HriWindow> {
    let step = (c.fps / 15.0).round().max(1.0) as usize;
    let idx: Vec<usize> = (0..c.human.len()).step_by(step).collect();
    let need = OBS + PRED;
    let mut out = vec![];
    let mut s = 0;
    while s + need <= idx.len() {
        let frames = &idx[s..s + need];
        let canon = Canonical::of(&c.human[frames[OBS - 1]]);
        let human = frames
            .iter()
            .map(|f| encode(&canon, &c.human[*f]))
            .collect();
        let robot = frames
            .iter()
            .map(|f| encode_robot(&canon, &c.robot[*f], c.base[*f]))
            .collect();
        let fut = &frames[OBS..];
        let ref_wrists = fut
            .iter()
            .map(|f| {
                [j::L_WRIST, j::R_WRIST].map(|w| {
                    let p = canon.world_to_window(&c.reference[*f][w]);
                    [p.x as f32, p.y as f32, p.z as f32]
                })
            })
            .collect();
        let w_pr = fut
            .iter()
            .map(|f| {
                let (contact, near) = contact_and_proximity(&c.human[*f], &c.reference[*f]);
                0.5 * f32::from(u8::from(contact)) + 0.5 * f32::from(u8::from(near))
            })
            .collect();
        out.push(HriWindow {
            kind: c.kind.clone(),
            texts: c.texts.clone(),
            canon,
            human,
            robot,
            ref_wrists,
            w_pr,
            human_world: fut.iter().map(|f| c.human[*f]).collect(),
            reference_world: fut.iter().map(|f| c.reference[*f]).collect(),
        });
        s += stride.max(1);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn robot_features_round_trip() {
        let a: [Vector3<f64>; NUM_JOINTS] =
            std::array::from_fn(|k| Vector3::new(1.0, 2.0, 0.05 * k as f64));
        let c = Canonical::of(&a);
        let q: Vec<f64> = (0..ROBOT_JOINTS).map(|k| 0.1 * k as f64).collect();
        let base = [3.0, -1.0, 0.7];
        let f = encode_robot(&c, &q, base);
        let (q2, b2) = decode_robot(&c, &f);
        for (x, y) in q.iter().zip(&q2) {
            assert!((x - y).abs() < 1e-6);
        }
        assert!((b2[0] - 3.0).abs() < 1e-5 && (b2[1] + 1.0).abs() < 1e-5);
        let dyaw = (b2[2] - 0.7 + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI)
            - std::f64::consts::PI;
        assert!(dyaw.abs() < 1e-5, "{}", b2[2]);
    }
}
