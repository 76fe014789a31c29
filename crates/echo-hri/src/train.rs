//! HRI training (paper Eq. 6): the human–robot forecaster learns the robot's joint angles and base
//! from retargeted interactions, with
//! - L_self, L_soc: MSE of the individual and social forecasts of both agents' features;
//! - L_int: MSE between the distance matrix of the human's hands to the robot's grippers (world,
//!   through differentiable FK) and that of the human's hands to the reference person's hands;
//! - L_imit: MSE between the robot's grippers and the reference person's hands;
//!
//! combined per future frame as `w·(λ_int L_int + λ_imit L_imit) + (1 − w)·(λ_self L_self +
//! λ_soc L_soc)` with `w` the original pair's proximity weight (`Adaptive`), or plainly summed
//! (`Fixed`), or without the social terms (`None`).

use std::collections::HashMap;
use std::time::Instant;

use anyhow::Result;
use candle_core::{DType, Device, Tensor, D};
use candle_nn::{VarBuilder, VarMap};
use echo_models::features::FEATURES;
use echo_models::model::{joint_positions, rotate, Forecaster, ForecasterConfig};
use echo_retarget::fk::BatchFk;
use echo_retarget::Retargeter;
use echo_robot::RobotModel;
use echo_text::SentenceEncoder;
use echo_train::optim::AdamW;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::codec::RobotCodec;
use crate::data::{HriWindow, OBS, PRED, ROBOT_FEATURES, ROBOT_JOINTS};

/// How the interaction and imitation losses enter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Social {
    /// Movement losses only.
    None,
    /// Movement + interaction + imitation, fixed weights.
    Fixed,
    /// Eq. 6: weighted per frame by the proximity of the original pair.
    Adaptive,
}

/// Settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HriTrainConfig {
    /// Training clips.
    pub clips: u64,
    /// Window stride, frames at 15 Hz.
    pub stride: usize,
    /// Batch size.
    pub batch: usize,
    /// Peak learning rate.
    pub lr: f64,
    /// Warm-up steps.
    pub warmup: usize,
    /// Epochs.
    pub epochs: usize,
    /// Wall-clock budget, minutes.
    pub max_minutes: f64,
    /// λ_self.
    pub w_self: f64,
    /// λ_soc.
    pub w_soc: f64,
    /// λ_int.
    pub w_int: f64,
    /// λ_imit.
    pub w_imit: f64,
    /// Social loss mode.
    pub social: Social,
    /// Seed.
    pub seed: u64,
    /// The retargeter's encoder/decoder, frozen, wrap the robot agent ([`crate::codec`]).
    #[serde(default)]
    pub frozen_retargeter: bool,
    /// Share of training windows whose observed robot frames are all replaced by the last one
    /// (a robot standing still, as the real one often is when a person comes; the future, a
    /// displacement from that last frame, is unchanged).
    #[serde(default)]
    pub still_robot: f64,
}

impl Default for HriTrainConfig {
    fn default() -> Self {
        HriTrainConfig {
            clips: 1300,
            stride: 3,
            batch: 64,
            lr: 1e-3,
            warmup: 100,
            epochs: 4,
            max_minutes: 30.0,
            w_self: 1.0,
            w_soc: 1.0,
            w_int: 1.0,
            w_imit: 1.0,
            social: Social::Adaptive,
            seed: 1,
            frozen_retargeter: false,
            still_robot: 0.0,
        }
    }
}

/// The HRI model's architecture: the human–human one with a robot agent.
/// With `codec`, the robot agent's features are the codec's.
pub fn hri_model_config(text_dim: usize, codec: Option<&RobotCodec>) -> ForecasterConfig {
    ForecasterConfig {
        pred: PRED,
        text_dim,
        agent_features: [
            FEATURES,
            codec.map_or(ROBOT_FEATURES, |c| c.model_features()),
        ],
        ..Default::default()
    }
}

/// Social and individual forecasts of a batch, robot features decoded through `codec`.
fn forward(
    model: &Forecaster,
    b: &Batch,
    codec: Option<&RobotCodec>,
) -> candle_core::Result<([Tensor; 2], [Tensor; 2])> {
    let Some(c) = codec else {
        return model.forward_pair(&b.obs_a, &b.obs_b, b.text.as_ref());
    };
    let ([sa, sb], [ia, ib]) =
        model.forward_pair(&b.obs_a, &c.to_model(&b.obs_b)?, b.text.as_ref())?;
    Ok(([sa, c.from_model(&sb)?], [ia, c.from_model(&ib)?]))
}

/// The FK of the two grippers as a function of the 17 robot joints.
pub fn gripper_fk(model: &RobotModel, r: &Retargeter) -> Result<BatchFk> {
    let names: Vec<&str> = r.joint_names().iter().map(|s| s.as_str()).collect();
    Ok(BatchFk::new(
        model,
        &names,
        &[],
        &[
            "gripper_left_grasping_frame",
            "gripper_right_grasping_frame",
        ],
    )?)
}

/// Grippers (b, t, 2, 3) in the window frame from robot features (b, t, 24).
pub fn grippers(fk: &BatchFk, robot: &Tensor) -> candle_core::Result<Tensor> {
    let (b, t, _) = robot.dims3()?;
    let q = robot
        .narrow(D::Minus1, 0, ROBOT_JOINTS)?
        .reshape((b * t, ROBOT_JOINTS))?;
    let p = fk.forward(&q)?.reshape((b, t, 2, 3))?;
    let base = robot.narrow(D::Minus1, ROBOT_JOINTS, 3)?.unsqueeze(2)?;
    let h = robot.narrow(D::Minus1, ROBOT_JOINTS + 3, 4)?.unsqueeze(2)?;
    rotate(&h, &p)?.broadcast_add(&base)
}

/// Human wrists (b, t, 2, 3) from human features (b, t, 73).
pub fn wrists(human: &Tensor) -> candle_core::Result<Tensor> {
    let idx = Tensor::new(&[20u32, 21], human.device())?;
    joint_positions(human)?.index_select(&idx, 2)
}

fn distances(a: &Tensor, b: &Tensor) -> candle_core::Result<Tensor> {
    // (b, t, 2, 3) × (b, t, 2, 3) → (b, t, 4)
    let d = a.unsqueeze(3)?.broadcast_sub(&b.unsqueeze(2)?)?;
    let (n, t, _, _, _) = d.dims5()?;
    (d.sqr()?.sum(D::Minus1)? + 1e-8)?
        .sqrt()?
        .reshape((n, t, 4))
}

/// A batch as tensors.
pub struct Batch {
    obs_a: Tensor,
    obs_b: Tensor,
    fut_a: Tensor,
    fut_b: Tensor,
    ref_wrists: Tensor,
    w: Tensor,
    text: Option<Tensor>,
}

/// Tensors of windows `ws`; `text` gives one embedding per window.
pub fn batch(
    ws: &[&HriWindow],
    text: Option<Vec<f32>>,
    text_dim: usize,
    dev: &Device,
) -> candle_core::Result<Batch> {
    batch_held(ws, text, text_dim, dev, &[])
}

/// [`batch`], with the robot's observed frames held at the last one in the windows `held`
/// marks (missing entries: not held).
pub fn batch_held(
    ws: &[&HriWindow],
    text: Option<Vec<f32>>,
    text_dim: usize,
    dev: &Device,
    held: &[bool],
) -> candle_core::Result<Batch> {
    let n = ws.len();
    let mut oa = vec![];
    let mut ob = vec![];
    let mut fa = vec![];
    let mut fb = vec![];
    let mut rw = vec![];
    let mut w = vec![];
    for (i, x) in ws.iter().enumerate() {
        for f in &x.human[..OBS] {
            oa.extend_from_slice(f);
        }
        let hold = held.get(i).copied().unwrap_or(false);
        for f in &x.robot[..OBS] {
            ob.extend_from_slice(if hold { &x.robot[OBS - 1] } else { f });
        }
        for f in &x.human[OBS..] {
            fa.extend_from_slice(f);
        }
        for f in &x.robot[OBS..] {
            fb.extend_from_slice(f);
        }
        for p in &x.ref_wrists {
            rw.extend(p.iter().flatten().copied());
        }
        w.extend_from_slice(&x.w_pr);
    }
    Ok(Batch {
        obs_a: Tensor::from_vec(oa, (n, OBS, FEATURES), dev)?,
        obs_b: Tensor::from_vec(ob, (n, OBS, ROBOT_FEATURES), dev)?,
        fut_a: Tensor::from_vec(fa, (n, PRED, FEATURES), dev)?,
        fut_b: Tensor::from_vec(fb, (n, PRED, ROBOT_FEATURES), dev)?,
        ref_wrists: Tensor::from_vec(rw, (n, PRED, 2, 3), dev)?,
        w: Tensor::from_vec(w, (n, PRED), dev)?,
        text: match text {
            Some(t) => Some(Tensor::from_vec(t, (n, text_dim), dev)?),
            None => None,
        },
    })
}

/// Mean of each loss over a batch.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
pub struct Losses {
    /// Weighted total.
    pub total: f64,
    /// L_self.
    pub self_: f64,
    /// L_soc.
    pub soc: f64,
    /// L_int.
    pub int: f64,
    /// L_imit.
    pub imit: f64,
}

fn per_frame_mse(a: &Tensor, b: &Tensor) -> candle_core::Result<Tensor> {
    (a - b)?.sqr()?.mean(D::Minus1)
}

/// The loss of a batch (a scalar tensor to back-propagate) and its parts.
pub fn loss(
    model: &Forecaster,
    fk: &BatchFk,
    t: &HriTrainConfig,
    b: &Batch,
    codec: Option<&RobotCodec>,
) -> candle_core::Result<(Tensor, Losses)> {
    let ([sa, sb], [ia, ib]) = forward(model, b, codec)?;
    let self_ = ((per_frame_mse(&ia, &b.fut_a)? + per_frame_mse(&ib, &b.fut_b)?)? * 0.5)?;
    let soc = ((per_frame_mse(&sa, &b.fut_a)? + per_frame_mse(&sb, &b.fut_b)?)? * 0.5)?;
    let ee = grippers(fk, &sb)?;
    let dm_pred = distances(&wrists(&sa)?, &ee)?;
    let dm_true = distances(&wrists(&b.fut_a)?, &b.ref_wrists)?;
    let int = per_frame_mse(&dm_pred, &dm_true)?;
    let imit = (ee - &b.ref_wrists)?
        .sqr()?
        .mean(D::Minus1)?
        .mean(D::Minus1)?;
    let movement = ((&self_ * t.w_self)? + (&soc * t.w_soc)?)?;
    let social = ((&int * t.w_int)? + (&imit * t.w_imit)?)?;
    let per_frame = match t.social {
        Social::None => movement,
        Social::Fixed => (movement + social)?,
        Social::Adaptive => ((&b.w * &social)? + ((1.0 - &b.w)? * movement)?)?,
    };
    let total = per_frame.mean_all()?;
    let s =
        |x: &Tensor| -> candle_core::Result<f64> { Ok(x.mean_all()?.to_scalar::<f32>()? as f64) };
    let parts = Losses {
        total: total.to_scalar::<f32>()? as f64,
        self_: s(&self_)?,
        soc: s(&soc)?,
        int: s(&int)?,
        imit: s(&imit)?,
    };
    Ok((total, parts))
}

/// The social forecast of a batch: per window, the robot features per future frame.
pub fn forecast(
    model: &Forecaster,
    b: &Batch,
    codec: Option<&RobotCodec>,
) -> candle_core::Result<Vec<Vec<Vec<f32>>>> {
    let ([_, sb], _) = forward(model, b, codec)?;
    sb.to_vec3::<f32>()
}

/// The social forecast of the human agent (window features per future frame) of a batch.
pub fn forecast_human(
    model: &Forecaster,
    b: &Batch,
    codec: Option<&RobotCodec>,
) -> candle_core::Result<Vec<Vec<Vec<f32>>>> {
    let ([sa, _], _) = forward(model, b, codec)?;
    sa.to_vec3::<f32>()
}

/// Prompt embeddings of every distinct description.
pub fn embed_texts(enc: &SentenceEncoder, ws: &[HriWindow]) -> Result<HashMap<String, Vec<f32>>> {
    let mut texts: Vec<&str> = ws
        .iter()
        .flat_map(|w| w.texts.iter().map(|s| s.as_str()))
        .collect();
    texts.sort_unstable();
    texts.dedup();
    let v = enc.embed(&texts)?;
    Ok(texts.into_iter().map(String::from).zip(v).collect())
}

/// Train; returns the weights and the mean losses per epoch.
pub fn train(
    cfg: &ForecasterConfig,
    t: &HriTrainConfig,
    windows: &[HriWindow],
    text: Option<&SentenceEncoder>,
    fk: &BatchFk,
    codec: Option<&RobotCodec>,
    mut on_step: impl FnMut(usize, usize, &Losses),
) -> Result<(VarMap, Vec<Losses>)> {
    anyhow::ensure!(
        codec.is_some() == t.frozen_retargeter,
        "the frozen-retargeter option and the codec passed disagree"
    );
    anyhow::ensure!(!windows.is_empty(), "no HRI windows to train on");
    let dev = Device::Cpu;
    let table = match (text, cfg.text_dim > 0) {
        (Some(e), true) => Some(embed_texts(e, windows)?),
        (None, true) => anyhow::bail!("the model reads text: a sentence encoder is needed"),
        _ => None,
    };
    let vm = VarMap::new();
    let model = Forecaster::new(cfg.clone(), VarBuilder::from_varmap(&vm, DType::F32, &dev))?;
    let mut opt = AdamW::from_varmap(&vm, t.lr, 1e-4)?;
    let started = Instant::now();
    let mut step = 0usize;
    let mut log = vec![];
    let steps = windows.len().div_ceil(t.batch.max(1));
    for epoch in 0..t.epochs {
        let mut rng = rand::rngs::StdRng::seed_from_u64(t.seed.wrapping_mul(1000) + epoch as u64);
        let mut order: Vec<usize> = (0..windows.len()).collect();
        order.shuffle(&mut rng);
        let mut sum = Losses::default();
        let mut n = 0.0;
        for (k, idx) in order.chunks(t.batch.max(1)).enumerate() {
            opt.lr = if step < t.warmup {
                t.lr * (step + 1) as f64 / t.warmup as f64
            } else {
                t.lr * 0.9f64.powf(step as f64 / steps as f64)
            };
            let ws: Vec<&HriWindow> = idx.iter().map(|i| &windows[*i]).collect();
            let txt = table.as_ref().map(|tab| {
                ws.iter()
                    .flat_map(|w| {
                        let pick = &w.texts[rng
                            .random_range(0..w.texts.len().max(1))
                            .min(w.texts.len().saturating_sub(1))];
                        tab.get(pick)
                            .cloned()
                            .unwrap_or_else(|| vec![0.0; cfg.text_dim])
                    })
                    .collect::<Vec<f32>>()
            });
            let held: Vec<bool> = ws
                .iter()
                .map(|_| t.still_robot > 0.0 && rng.random::<f64>() < t.still_robot)
                .collect();
            let b = batch_held(&ws, txt, cfg.text_dim, &dev, &held)?;
            let (l, parts) = loss(&model, fk, t, &b, codec)?;
            anyhow::ensure!(
                parts.total.is_finite(),
                "loss became {} at step {step}",
                parts.total
            );
            let grads = l.backward()?;
            let norm = opt.grad_norm(&grads)?;
            opt.step(&grads, if norm > 1.0 { 1.0 / norm } else { 1.0 })?;
            step += 1;
            n += 1.0;
            sum.total += parts.total;
            sum.self_ += parts.self_;
            sum.soc += parts.soc;
            sum.int += parts.int;
            sum.imit += parts.imit;
            on_step(k + 1, steps, &parts);
            if started.elapsed().as_secs_f64() > t.max_minutes * 60.0 {
                break;
            }
        }
        log.push(Losses {
            total: sum.total / n,
            self_: sum.self_ / n,
            soc: sum.soc / n,
            int: sum.int / n,
            imit: sum.imit / n,
        });
        if started.elapsed().as_secs_f64() > t.max_minutes * 60.0 {
            break;
        }
    }
    Ok((vm, log))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_held_window_shows_a_still_robot_ending_where_it_ended() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let model = echo_robot::RobotModel::tiago_dual();
        let r = Retargeter::load(&root.join("models/retargeter"), model).unwrap();
        let clips =
            echo_motion::synth::generate_split(echo_motion::synth::Split::Train, 0..1, 1, &|| {});
        let ws = crate::data::windows(&echo_retarget::hri::convert(&clips[0], &r).unwrap(), 6);
        let refs: Vec<&HriWindow> = ws.iter().take(2).collect();
        let dev = Device::Cpu;
        let plain = batch(&refs, None, 0, &dev).unwrap();
        let held = batch_held(&refs, None, 0, &dev, &[false, true]).unwrap();
        let (p, h) = (
            plain.obs_b.to_vec3::<f32>().unwrap(),
            held.obs_b.to_vec3::<f32>().unwrap(),
        );
        // The first window is untouched; the second holds its last frame throughout.
        assert_eq!(p[0], h[0]);
        assert!(h[1].iter().all(|f| *f == p[1][OBS - 1]));
        assert_ne!(
            p[1][0],
            p[1][OBS - 1],
            "the reference robot moved in this window"
        );
        // Everything else, futures included, is as before.
        assert_eq!(
            plain.fut_b.to_vec3::<f32>().unwrap(),
            held.fut_b.to_vec3::<f32>().unwrap()
        );
        assert_eq!(
            plain.obs_a.to_vec3::<f32>().unwrap(),
            held.obs_a.to_vec3::<f32>().unwrap()
        );
    }
}
