//! Batch assembly: the model's inputs for every robot with a new frame, each scene once or as
//! its symmetric copies, in one batch.

use super::*;
use echo_models::features::Canonical;
use echo_models::model::ForecasterConfig;
use echo_motion::symmetry::Symmetry;

/// One robot's scene in the batch: what its forecast needs besides the model's output.
pub(super) struct Scene {
    pub robot: String,
    pub stamp: u64,
    pub partner: u32,
    pub interaction: Option<Interaction>,
    pub arm: Option<bool>,
}

/// The batch's inputs.
pub(super) struct Batch {
    /// The scenes, in batch order (each `group.len()` rows).
    pub scenes: Vec<Scene>,
    /// The canonical frame of every row.
    pub canon: Vec<Canonical>,
    /// Observed features, row-major.
    pub obs: Vec<f32>,
    /// Each scene's prompt.
    pub prompts: Vec<String>,
    /// Each scene's measured robot joints.
    pub measured: Vec<[f64; ROBOT_STATE]>,
}

impl ForecastServer {
    /// Take every robot's pending frame and encode its last `cfg.obs` frames, once per
    /// symmetry in `group` (the robot agent, when the model has one, in its own base frame).
    pub(super) fn assemble(
        &mut self,
        cfg: &ForecasterConfig,
        group: &[Symmetry],
        robot_agent: bool,
    ) -> Batch {
        let mut robots = vec![];
        let mut canon = vec![];
        let mut obs = vec![];
        let mut prompts: Vec<String> = vec![];
        let mut measured = vec![];
        for (name, slot) in self.slots.iter_mut() {
            let Some(stamp) = slot.pending.take() else {
                continue;
            };
            let Some(frames) = slot.history.last(cfg.obs) else {
                continue;
            };
            let pairs: Vec<Vec<[Vector3<f64>; NUM_JOINTS]>> =
                frames.iter().map(|p| p.pair.to_vec()).collect();
            for g in group {
                let seen: Vec<_> = pairs.iter().map(|p| g(p)).collect();
                let (c, agents) = encode_frames(&seen);
                for f in &agents[0] {
                    obs.extend_from_slice(f);
                }
                if robot_agent {
                    // The robot in its own base frame (the skeletons' frame): base at the origin.
                    for f in &frames {
                        obs.extend_from_slice(&encode_robot(&c, &f.robot, [0.0; 3]));
                    }
                } else {
                    for f in &agents[1] {
                        obs.extend_from_slice(f);
                    }
                }
                canon.push(c);
            }
            measured.push(slot.robot_q);
            prompts.push(slot.prompt.clone());
            robots.push(Scene {
                robot: name.clone(),
                stamp,
                partner: slot.pair.map(|p| p.0).unwrap_or(0),
                interaction: slot.interaction,
                arm: slot.contact_arm,
            });
        }
        Batch {
            scenes: robots,
            canon,
            obs,
            prompts,
            measured,
        }
    }
}
