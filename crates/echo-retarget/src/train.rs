//! Training without paired data: human poses from the motion data, robot poses sampled
//! uniformly within the soft limits. Losses (weights in [`TrainConfig`]):
//! - triplet on the latent codes: for a human pose, of two robot poses the one whose limb
//!   directions are closer (S = Σ_limbs (1 − cos)) must be nearer in latent space (margin);
//! - robot reconstruction: L1 of decode(encode_robot(q)) − q, in normalised joint units;
//! - latent consistency: L1 of encode_robot(decode(z_h)) − z_h;
//! - limb direction (optional): 1 − cos between the human's limb directions and the retargeted
//!   robot's (differentiable FK), the loss that makes the mapping geometrically faithful.

use std::time::Instant;

use anyhow::Result;
use candle_core::{DType, Device, Tensor, D};
use candle_nn::{AdamW, Optimizer, ParamsAdamW, VarBuilder, VarMap};
use echo_motion::synth::{generate_split, Split};
use echo_robot::RobotModel;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::fk::BatchFk;
use crate::human::{features, limb_directions, HUMAN_FEATURES};
use crate::net::{arm_joints, arm_limits, ImitationNet, NetConfig, LIMB_FRAMES};

/// Training settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// Optimiser steps.
    pub steps: usize,
    /// Batch size.
    pub batch: usize,
    /// Learning rate.
    pub lr: f64,
    /// Triplet loss weight and margin.
    pub w_triplet: f64,
    /// Triplet margin.
    pub margin: f64,
    /// Robot reconstruction weight.
    pub w_recon: f64,
    /// Latent consistency weight.
    pub w_latent: f64,
    /// Limb-direction (FK) loss weight; 0 reproduces the paper's losses only.
    pub w_direction: f64,
    /// Clips of the training split the human poses come from.
    pub clips: u64,
    /// Seed.
    pub seed: u64,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            steps: 3000,
            batch: 256,
            lr: 1e-3,
            w_triplet: 10.0,
            margin: 0.05,
            w_recon: 5.0,
            w_latent: 1.0,
            w_direction: 1.0,
            clips: 650,
            seed: 1,
        }
    }
}

/// Human poses as features and limb directions (body frame).
pub struct HumanSet {
    /// (n × 16) features.
    pub features: Vec<f32>,
    /// (n × 4 × 3) unit limb directions.
    pub directions: Vec<f32>,
    /// Poses.
    pub n: usize,
}

impl HumanSet {
    /// Every `stride`-th frame of both people of clips `range` of `split`.
    pub fn from_split(split: Split, range: std::ops::Range<u64>, stride: usize) -> HumanSet {
        let clips = generate_split(split, range, 2, &|| {});
        let mut s = HumanSet {
            features: vec![],
            directions: vec![],
            n: 0,
        };
        for c in &clips {
            for f in (0..c.frames.len()).step_by(stride.max(1)) {
                for p in 0..2 {
                    s.push(&c.joints(f, p));
                }
            }
        }
        s
    }

    /// Add one pose (skipped when degenerate).
    pub fn push(&mut self, p: &[nalgebra::Vector3<f64>; echo_motion::skeleton::NUM_JOINTS]) {
        if let (Some(f), Some(d)) = (features(p), limb_directions(p)) {
            self.features.extend_from_slice(&f);
            for v in d {
                self.directions.extend([v.x as f32, v.y as f32, v.z as f32]);
            }
            self.n += 1;
        }
    }

    fn batch(&self, idx: &[usize], dev: &Device) -> candle_core::Result<(Tensor, Tensor)> {
        let mut f = Vec::with_capacity(idx.len() * HUMAN_FEATURES);
        let mut d = Vec::with_capacity(idx.len() * 12);
        for &i in idx {
            f.extend_from_slice(&self.features[i * HUMAN_FEATURES..(i + 1) * HUMAN_FEATURES]);
            d.extend_from_slice(&self.directions[i * 12..(i + 1) * 12]);
        }
        Ok((
            Tensor::from_vec(f, (idx.len(), HUMAN_FEATURES), dev)?,
            Tensor::from_vec(d, (idx.len(), 4, 3), dev)?,
        ))
    }
}

/// Unit limb directions (b, 4, 3) of robot arm poses (b, 14), in the base (= torso) axes.
pub fn robot_directions(fk: &BatchFk, q: &Tensor) -> candle_core::Result<Tensor> {
    let p = fk.forward(q)?; // (b, 6, 3): L shoulder, elbow, wrist, R shoulder, elbow, wrist
    let seg = |a: usize, b: usize| -> candle_core::Result<Tensor> {
        let v = (p.narrow(1, b, 1)? - p.narrow(1, a, 1)?)?;
        let n = (v.sqr()?.sum_keepdim(D::Minus1)? + 1e-9)?.sqrt()?;
        v.broadcast_div(&n)
    };
    Tensor::cat(&[seg(0, 1)?, seg(1, 2)?, seg(3, 4)?, seg(4, 5)?], 1)
}

/// The FK the retargeter uses (arm joints variable, torso at its default height).
pub fn limb_fk(model: &RobotModel) -> Result<BatchFk> {
    let names = arm_joints();
    let refs: Vec<&str> = names.iter().map(|s| s.as_str()).collect();
    Ok(BatchFk::new(
        model,
        &refs,
        &[("torso_lift_joint", 0.15)],
        &LIMB_FRAMES,
    )?)
}

/// Σ over limbs of (1 − cos) between direction sets (b, 4, 3) → (b,).
fn dissimilarity(a: &Tensor, b: &Tensor) -> candle_core::Result<Tensor> {
    (4.0 - (a * b)?.sum(D::Minus1)?.sum(D::Minus1)?)?.affine(1.0, 0.0)
}

/// One step's losses.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
pub struct StepLog {
    /// Step.
    pub step: usize,
    /// Total.
    pub total: f64,
    /// Triplet.
    pub triplet: f64,
    /// Robot reconstruction.
    pub recon: f64,
    /// Latent consistency.
    pub latent: f64,
    /// Limb direction.
    pub direction: f64,
}

/// Train; returns the weights and a loss record every 50 steps.
pub fn train(
    net_cfg: &NetConfig,
    t: &TrainConfig,
    model: &RobotModel,
    humans: &HumanSet,
    mut on_log: impl FnMut(&StepLog),
) -> Result<(VarMap, Vec<StepLog>)> {
    anyhow::ensure!(humans.n > 0, "no human poses to train on");
    let dev = Device::Cpu;
    let vm = VarMap::new();
    let net = ImitationNet::new(
        net_cfg.clone(),
        model,
        VarBuilder::from_varmap(&vm, DType::F32, &dev),
    )?;
    let fk = limb_fk(model)?;
    let lim = arm_limits(model);
    let mut opt = AdamW::new(
        vm.all_vars(),
        ParamsAdamW {
            lr: t.lr,
            weight_decay: 0.0,
            ..Default::default()
        },
    )?;
    let mut rng = rand::rngs::StdRng::seed_from_u64(t.seed);
    let mut log = vec![];
    let started = Instant::now();
    for step in 0..t.steps {
        let idx: Vec<usize> = (0..t.batch)
            .map(|_| rng.random_range(0..humans.n))
            .collect();
        let (h, hd) = humans.batch(&idx, &dev)?;
        let q: Vec<f32> = (0..t.batch)
            .flat_map(|_| {
                lim.iter()
                    .map(|l| rng.random_range(l.0..l.1) as f32)
                    .collect::<Vec<_>>()
            })
            .collect();
        let q = Tensor::from_vec(q, (t.batch, lim.len()), &dev)?;
        let zh = net.encode_human(&h)?;
        let zr = net.encode_robot(&q)?;
        // Robot reconstruction (normalised units).
        let recon = (net.normalise(&net.decode(&zr)?)? - net.normalise(&q)?)?
            .abs()?
            .mean_all()?;
        // Latent consistency of the retargeted pose.
        let qh = net.decode(&zh)?;
        let latent = (net.encode_robot(&qh)? - &zh)?.abs()?.mean_all()?;
        // Triplet: robot pose i and a shuffled one; the one closer in limb directions is positive.
        let rd = robot_directions(&fk, &q)?.detach();
        let perm: Vec<u32> = (0..t.batch as u32)
            .map(|i| (i + 1 + rng.random_range(0..t.batch as u32 - 1)) % t.batch as u32)
            .collect();
        let perm = Tensor::from_vec(perm, t.batch, &dev)?;
        let rd2 = rd.index_select(&perm, 0)?;
        let zr2 = zr.index_select(&perm, 0)?;
        let first_closer = dissimilarity(&hd, &rd)?
            .lt(&dissimilarity(&hd, &rd2)?)?
            .to_dtype(DType::F32)?
            .unsqueeze(1)?;
        let pos =
            (zr.broadcast_mul(&first_closer)? + zr2.broadcast_mul(&(1.0 - &first_closer)?)?)?;
        let neg =
            (zr2.broadcast_mul(&first_closer)? + zr.broadcast_mul(&(1.0 - &first_closer)?)?)?;
        let dist = |a: &Tensor, b: &Tensor| -> candle_core::Result<Tensor> {
            ((a - b)?.sqr()?.sum(D::Minus1)? + 1e-9)?.sqrt()
        };
        let triplet = ((dist(&zh, &pos)? - dist(&zh, &neg)?)? + t.margin)?
            .relu()?
            .mean_all()?;
        let mut loss = ((triplet.clone() * t.w_triplet)? + (recon.clone() * t.w_recon)?)?;
        loss = (loss + (latent.clone() * t.w_latent)?)?;
        let mut direction = 0.0;
        if t.w_direction > 0.0 {
            let d = (dissimilarity(&hd, &robot_directions(&fk, &qh)?)? / 4.0)?.mean_all()?;
            direction = d.to_scalar::<f32>()? as f64;
            loss = (loss + (d * t.w_direction)?)?;
        }
        opt.backward_step(&loss)?;
        if step % 50 == 0 || step + 1 == t.steps {
            let l = StepLog {
                step,
                total: loss.to_scalar::<f32>()? as f64,
                triplet: triplet.to_scalar::<f32>()? as f64,
                recon: recon.to_scalar::<f32>()? as f64,
                latent: latent.to_scalar::<f32>()? as f64,
                direction,
            };
            anyhow::ensure!(
                l.total.is_finite(),
                "loss became {} at step {step}",
                l.total
            );
            on_log(&l);
            log.push(l);
        }
    }
    let _ = started;
    Ok((vm, log))
}
