//! How well a retargeter maps human arms onto the robot: the mean angle between each human limb
//! direction and the robot's (upper arms, forearms), joint-limit compliance, and throughput.

use std::time::Instant;

use anyhow::Result;
use candle_core::{Device, Tensor};
use echo_robot::RobotModel;
use serde::{Deserialize, Serialize};

use crate::human::HUMAN_FEATURES;
use crate::net::{arm_limits, ImitationNet};
use crate::train::{limb_fk, robot_directions, HumanSet};

/// Evaluation results.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Evaluation {
    /// Poses evaluated.
    pub poses: usize,
    /// Mean angle per limb (L upper, L fore, R upper, R fore), degrees.
    pub limb_deg: [f64; 4],
    /// Mean over limbs, degrees.
    pub mean_deg: f64,
    /// Median over poses of the per-pose mean, degrees.
    pub median_deg: f64,
    /// Share of output joint values inside the soft limits.
    pub within_limits: f64,
    /// Poses per second (batch 256, CPU).
    pub poses_per_s: f64,
}

/// Evaluate `net` on `humans`.
pub fn evaluate(net: &ImitationNet, model: &RobotModel, humans: &HumanSet) -> Result<Evaluation> {
    evaluate_with(model, humans, |h| Ok(net.retarget(h)?))
}

/// Evaluate a constant robot arm pose (e.g. the home pose) as if it were a retargeter: the
/// baseline any retargeter must beat.
pub fn evaluate_constant(model: &RobotModel, humans: &HumanSet, q: &[f64]) -> Result<Evaluation> {
    let row: Vec<f32> = q.iter().map(|v| *v as f32).collect();
    evaluate_with(model, humans, |h| {
        let b = h.dim(0)?;
        let t = Tensor::from_vec(row.repeat(b), (b, row.len()), h.device())?;
        Ok(t)
    })
}

/// Evaluate any map from human features (b, 16) to arm joints (b, 14).
pub fn evaluate_with(
    model: &RobotModel,
    humans: &HumanSet,
    mut map: impl FnMut(&Tensor) -> Result<Tensor>,
) -> Result<Evaluation> {
    let dev = Device::Cpu;
    let fk = limb_fk(model)?;
    let lim = arm_limits(model);
    let (mut sums, mut per_pose, mut inside, mut total) = ([0f64; 4], vec![], 0usize, 0usize);
    let mut busy = 0.0;
    for start in (0..humans.n).step_by(256) {
        let end = (start + 256).min(humans.n);
        let b = end - start;
        let h = Tensor::from_slice(
            &humans.features[start * HUMAN_FEATURES..end * HUMAN_FEATURES],
            (b, HUMAN_FEATURES),
            &dev,
        )?;
        let t = Instant::now();
        let q = map(&h)?;
        let qv = q.to_vec2::<f32>()?;
        busy += t.elapsed().as_secs_f64();
        for row in &qv {
            for (v, l) in row.iter().zip(&lim) {
                total += 1;
                if (*v as f64) >= l.0 - 1e-6 && (*v as f64) <= l.1 + 1e-6 {
                    inside += 1;
                }
            }
        }
        let rd = robot_directions(&fk, &q)?.to_vec3::<f32>()?;
        for (i, r) in rd.iter().enumerate() {
            let mut pose = 0.0;
            for (l, sum) in sums.iter_mut().enumerate() {
                let o = (start + i) * 12 + l * 3;
                let hd = &humans.directions[o..o + 3];
                let c = (hd[0] * r[l][0] + hd[1] * r[l][1] + hd[2] * r[l][2]).clamp(-1.0, 1.0);
                let a = (c as f64).acos().to_degrees();
                *sum += a;
                pose += a / 4.0;
            }
            per_pose.push(pose);
        }
    }
    let n = humans.n.max(1) as f64;
    let limb_deg = sums.map(|s| s / n);
    per_pose.sort_by(f64::total_cmp);
    Ok(Evaluation {
        poses: humans.n,
        limb_deg,
        mean_deg: limb_deg.iter().sum::<f64>() / 4.0,
        median_deg: per_pose
            .get(per_pose.len() / 2)
            .copied()
            .unwrap_or(f64::NAN),
        within_limits: inside as f64 / total.max(1) as f64,
        poses_per_s: humans.n as f64 / busy.max(1e-9),
    })
}
