//! Training: windows of generated interactions as tensors, AdamW with warm-up then exponential
//! decay, gradient clipping, validation JPE every epoch, best checkpoint kept, early stopping.
//! Loss: MSE of both agents' future features (L_self + L_soc over the two agents) plus the
//! interaction loss on B's position relative to A (`w_interaction`).

use std::time::Instant;

use candle_core::{DType, Device, Tensor};
use candle_nn::{AdamW, Optimizer, ParamsAdamW, VarBuilder, VarMap};
use echo_eval::evaluate;
use echo_eval::window::{windows, Window};
use echo_motion::synth::{generate_split, Split};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use serde::{Deserialize, Serialize};

use crate::features::{encode, encode_frames, FEATURES};
use crate::model::{interaction_loss, mse, Forecaster, ForecasterConfig};
use crate::predictor::ModelPredictor;

/// Training settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// Training clips (types cycle).
    pub train_clips: u64,
    /// Validation clips.
    pub val_clips: u64,
    /// Window stride, frames at 15 Hz.
    pub stride: usize,
    /// Batch size.
    pub batch: usize,
    /// Peak learning rate.
    pub lr: f64,
    /// Warm-up steps.
    pub warmup: usize,
    /// Learning-rate decay per epoch after warm-up.
    pub decay: f64,
    /// Epochs at most.
    pub epochs: usize,
    /// Stop after this many epochs without validation improvement.
    pub patience: usize,
    /// Wall-clock budget, minutes.
    pub max_minutes: f64,
    /// Global gradient-norm clip.
    pub clip_grad: f64,
    /// Weight of the interaction loss.
    pub w_interaction: f64,
    /// Seed (shuffling, initialisation).
    pub seed: u64,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            train_clips: 2600,
            val_clips: 130,
            stride: 3,
            batch: 64,
            lr: 1e-3,
            warmup: 200,
            decay: 0.9,
            epochs: 30,
            patience: 4,
            max_minutes: 15.0,
            clip_grad: 1.0,
            w_interaction: 1.0,
            seed: 1,
        }
    }
}

/// Windows as flat feature arrays.
pub struct Batches {
    obs: Vec<f32>,
    fut: Vec<f32>,
    n: usize,
    cfg: ForecasterConfig,
}

impl Batches {
    /// Encode windows (canonical frame per window).
    pub fn new(ws: &[Window], cfg: &ForecasterConfig) -> Batches {
        let mut obs = Vec::with_capacity(ws.len() * 2 * cfg.obs * FEATURES);
        let mut fut = Vec::with_capacity(ws.len() * 2 * cfg.pred * FEATURES);
        for w in ws {
            let (c, o) = encode_frames(&w.obs);
            for agent in &o {
                for f in agent {
                    obs.extend_from_slice(f);
                }
            }
            for a in 0..2 {
                for f in &w.future {
                    fut.extend_from_slice(&encode(&c, &f[a]));
                }
            }
        }
        Batches {
            obs,
            fut,
            n: ws.len(),
            cfg: cfg.clone(),
        }
    }

    /// Number of windows.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether empty.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    fn batch(&self, idx: &[usize], dev: &Device) -> candle_core::Result<(Tensor, Tensor)> {
        let (so, sf) = (2 * self.cfg.obs * FEATURES, 2 * self.cfg.pred * FEATURES);
        let mut o = Vec::with_capacity(idx.len() * so);
        let mut f = Vec::with_capacity(idx.len() * sf);
        for &i in idx {
            o.extend_from_slice(&self.obs[i * so..(i + 1) * so]);
            f.extend_from_slice(&self.fut[i * sf..(i + 1) * sf]);
        }
        Ok((
            Tensor::from_vec(o, (idx.len(), 2, self.cfg.obs, FEATURES), dev)?,
            Tensor::from_vec(f, (idx.len(), 2, self.cfg.pred, FEATURES), dev)?,
        ))
    }
}

/// One epoch's record.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EpochLog {
    /// Epoch.
    pub epoch: usize,
    /// Mean training loss.
    pub train_loss: f64,
    /// Validation JPE at the horizons, mm.
    pub val_jpe: Vec<f64>,
    /// Seconds since the start.
    pub elapsed_s: f64,
}

/// Train a forecaster; returns the best weights (by validation JPE at 1.0 s) and the log.
pub fn train(
    cfg: &ForecasterConfig,
    t: &TrainConfig,
    dev: &Device,
    mut on_step: impl FnMut(usize, usize, f64),
    mut on_epoch: impl FnMut(&EpochLog),
) -> anyhow::Result<(VarMap, Vec<EpochLog>)> {
    let started = Instant::now();
    let train_clips = generate_split(Split::Train, 0..t.train_clips, 2, &|| {});
    let val_clips = generate_split(Split::Val, 0..t.val_clips, 2, &|| {});
    let train_w: Vec<Window> = train_clips
        .iter()
        .flat_map(|c| windows(c, t.stride))
        .collect();
    let val_w: Vec<Window> = val_clips.iter().flat_map(|c| windows(c, 8)).collect();
    drop(train_clips);
    let data = Batches::new(&train_w, cfg);
    drop(train_w);

    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, dev);
    let model = Forecaster::new(cfg.clone(), vb)?;
    let mut opt = AdamW::new(
        varmap.all_vars(),
        ParamsAdamW {
            lr: t.lr,
            weight_decay: 1e-4,
            ..Default::default()
        },
    )?;
    let mut rng = rand::rngs::StdRng::seed_from_u64(t.seed);
    let mut order: Vec<usize> = (0..data.len()).collect();
    let steps_per_epoch = data.len().div_ceil(t.batch.max(1));
    let mut step = 0usize;
    let mut best: Option<(f64, Vec<(String, Tensor)>)> = None;
    let mut since_best = 0;
    let mut log = vec![];
    for epoch in 0..t.epochs {
        order.shuffle(&mut rng);
        let mut total = 0.0;
        for (k, idx) in order.chunks(t.batch.max(1)).enumerate() {
            let lr = if step < t.warmup {
                t.lr * (step + 1) as f64 / t.warmup as f64
            } else {
                t.lr * t.decay.powf(step as f64 / steps_per_epoch as f64)
            };
            opt.set_learning_rate(lr);
            let (obs, fut) = data.batch(idx, dev)?;
            let pred = model.forward(&obs, None)?;
            let loss = (mse(&pred, &fut)? + (interaction_loss(&pred, &fut)? * t.w_interaction)?)?;
            let mut grads = loss.backward()?;
            // Global gradient-norm clipping.
            let vars = varmap.all_vars();
            let mut norm2 = 0f64;
            for v in &vars {
                if let Some(g) = grads.get(v) {
                    norm2 += g.sqr()?.sum_all()?.to_scalar::<f32>()? as f64;
                }
            }
            let norm = norm2.sqrt();
            if norm > t.clip_grad {
                let s = t.clip_grad / norm;
                for v in &vars {
                    if let Some(g) = grads.get(v) {
                        let scaled = (g * s)?;
                        grads.insert(v, scaled);
                    }
                }
            }
            opt.step(&grads)?;
            let l = loss.to_scalar::<f32>()? as f64;
            total += l;
            step += 1;
            on_step(k + 1, steps_per_epoch, l);
            if started.elapsed().as_secs_f64() > t.max_minutes * 60.0 {
                break;
            }
        }
        // Validation: JPE of the model through the evaluation harness.
        let mut p = ModelPredictor::new(&model, dev.clone(), "validation");
        let r = evaluate(&mut p, &val_w, 128);
        let e = EpochLog {
            epoch,
            train_loss: total / steps_per_epoch as f64,
            val_jpe: r.overall.jpe.clone(),
            elapsed_s: started.elapsed().as_secs_f64(),
        };
        on_epoch(&e);
        let score = e.val_jpe[2];
        if best.as_ref().is_none_or(|(b, _)| score < *b) {
            let snapshot = varmap
                .data()
                .lock()
                .map_err(|_| anyhow::anyhow!("poisoned weights"))?
                .iter()
                .map(|(k, v)| Ok((k.clone(), v.as_tensor().copy()?)))
                .collect::<candle_core::Result<Vec<_>>>()?;
            best = Some((score, snapshot));
            since_best = 0;
        } else {
            since_best += 1;
        }
        log.push(e);
        if since_best >= t.patience || started.elapsed().as_secs_f64() > t.max_minutes * 60.0 {
            break;
        }
    }
    if let Some((_, snap)) = best {
        let data = varmap
            .data()
            .lock()
            .map_err(|_| anyhow::anyhow!("poisoned weights"))?;
        for (k, v) in snap {
            if let Some(var) = data.get(&k) {
                var.set(&v)?;
            }
        }
    }
    Ok((varmap, log))
}
