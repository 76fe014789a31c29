//! Training: windows of generated interactions as tensors, AdamW with warm-up then exponential
//! decay, global gradient-norm clipping, validation JPE every epoch, best weights kept, early
//! stopping, and a resumable state saved after every epoch.
//!
//! Loss (paper §3.3), over both agents' future features in the window frame:
//! `w_soc·L_soc + w_self·L_self + w_interaction·L_int + w_bone·L_bone` where L_soc and L_self are
//! the MSE of the social and the individual (pre-cross-attention) forecasts, L_int the MSE of the
//! A-to-B joint distance matrices (Eq. 3) and L_bone the MSE of bone lengths.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use candle_core::backprop::GradStore;
use candle_core::{DType, Device, Tensor};
use candle_nn::{VarBuilder, VarMap};
use echo_eval::evaluate;
use echo_eval::window::{windows, Window};
use echo_motion::synth::{generate_split, Split};
use echo_text::SentenceEncoder;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use echo_models::features::{encode, encode_frames, FEATURES};
use echo_models::model::{bone_loss, interaction_loss, mse, Forecaster, ForecasterConfig};
pub use echo_models::TrainConfig;

use crate::optim::AdamW;
use crate::predictor::ModelPredictor;

/// One optimisation step on a batch (`obs` (b, 2, obs, F), `fut` (b, 2, pred, F), prompts
/// (b, text_dim) when the model reads text): [`batch_loss`], backward, [`update`]. Returns
/// the loss before the update.
pub fn train_step(
    model: &Forecaster,
    opt: &mut AdamW,
    t: &TrainConfig,
    obs: &Tensor,
    fut: &Tensor,
    text: Option<&Tensor>,
) -> anyhow::Result<f64> {
    let loss = batch_loss(model, t, obs, fut, text)?;
    update(opt, t, &loss.backward()?)?;
    Ok(loss.to_scalar::<f32>()? as f64)
}

/// The weighted training loss of a batch (the forward pass).
pub fn batch_loss(
    model: &Forecaster,
    t: &TrainConfig,
    obs: &Tensor,
    fut: &Tensor,
    text: Option<&Tensor>,
) -> candle_core::Result<Tensor> {
    let (soc, ind) = model.forward_both(obs, text)?;
    let mut loss = (mse(&soc, fut)? * t.w_soc)?;
    if t.w_self > 0.0 {
        loss = (loss + (mse(&ind, fut)? * t.w_self)?)?;
    }
    if t.w_interaction > 0.0 {
        loss = (loss + (interaction_loss(&soc, fut)? * t.w_interaction)?)?;
    }
    if t.w_bone > 0.0 {
        loss = (loss + (bone_loss(&soc, fut)? * t.w_bone)?)?;
    }
    Ok(loss)
}

/// Global-norm clipping of `grads` to `t.clip_grad`, then one AdamW update at the
/// optimiser's current rate.
pub fn update(opt: &mut AdamW, t: &TrainConfig, grads: &GradStore) -> candle_core::Result<()> {
    let norm = opt.grad_norm(grads)?;
    let scale = if norm > t.clip_grad {
        t.clip_grad / norm
    } else {
        1.0
    };
    opt.step(grads, scale)
}

/// Prompt embeddings: every distinct description once.
pub struct TextTable {
    dim: usize,
    emb: Vec<f32>,
    index: HashMap<String, usize>,
}

impl TextTable {
    /// Embed every distinct text of `ws`.
    pub fn build(enc: &SentenceEncoder, ws: &[&[Window]]) -> anyhow::Result<TextTable> {
        let mut texts: Vec<&str> = ws
            .iter()
            .flat_map(|w| w.iter().flat_map(|w| w.texts.iter().map(|s| s.as_str())))
            .collect();
        texts.sort_unstable();
        texts.dedup();
        let vecs = enc.embed(&texts)?;
        let mut emb = Vec::with_capacity(texts.len() * enc.dim());
        let mut index = HashMap::new();
        for (i, (t, v)) in texts.iter().zip(vecs).enumerate() {
            emb.extend_from_slice(&v);
            index.insert((*t).to_string(), i);
        }
        Ok(TextTable {
            dim: enc.dim(),
            emb,
            index,
        })
    }

    /// Distinct prompts.
    pub fn len(&self) -> usize {
        self.index.len()
    }

    /// Whether empty.
    pub fn is_empty(&self) -> bool {
        self.index.is_empty()
    }

    fn row(&self, i: usize) -> &[f32] {
        &self.emb[i * self.dim..(i + 1) * self.dim]
    }
}

/// Windows as flat feature arrays, with the ids of their descriptions.
pub struct Batches {
    obs: Vec<f32>,
    fut: Vec<f32>,
    texts: Vec<Vec<usize>>,
    n: usize,
    cfg: ForecasterConfig,
}

impl Batches {
    /// Encode windows (canonical frame per window); `table` maps their texts to embeddings.
    pub fn new(ws: &[Window], cfg: &ForecasterConfig, table: Option<&TextTable>) -> Batches {
        let mut obs = Vec::with_capacity(ws.len() * 2 * cfg.obs * FEATURES);
        let mut fut = Vec::with_capacity(ws.len() * 2 * cfg.pred * FEATURES);
        let mut texts = Vec::with_capacity(ws.len());
        for w in ws {
            let (c, o) = encode_frames(&w.obs[w.obs.len() - cfg.obs..]);
            for agent in &o {
                for f in agent {
                    obs.extend_from_slice(f);
                }
            }
            for a in 0..2 {
                for f in &w.future[..cfg.pred] {
                    fut.extend_from_slice(&encode(&c, &f[a]));
                }
            }
            texts.push(match table {
                Some(t) => w
                    .texts
                    .iter()
                    .filter_map(|s| t.index.get(s).copied())
                    .collect(),
                None => vec![],
            });
        }
        Batches {
            obs,
            fut,
            texts,
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

    /// Observed and future features of windows `idx`, and a text embedding per window (one of
    /// its descriptions, drawn with `rng`) when `table` is given.
    fn batch(
        &self,
        idx: &[usize],
        table: Option<&TextTable>,
        rng: &mut impl Rng,
        dev: &Device,
    ) -> candle_core::Result<(Tensor, Tensor, Option<Tensor>)> {
        let (so, sf) = (2 * self.cfg.obs * FEATURES, 2 * self.cfg.pred * FEATURES);
        let mut o = Vec::with_capacity(idx.len() * so);
        let mut f = Vec::with_capacity(idx.len() * sf);
        let mut t = vec![];
        for &i in idx {
            o.extend_from_slice(&self.obs[i * so..(i + 1) * so]);
            f.extend_from_slice(&self.fut[i * sf..(i + 1) * sf]);
            if let Some(tab) = table {
                match self.texts[i].as_slice() {
                    [] => t.extend(std::iter::repeat_n(0.0, tab.dim)),
                    ids => t.extend_from_slice(tab.row(ids[rng.random_range(0..ids.len())])),
                }
            }
        }
        let text = match table {
            Some(tab) => Some(Tensor::from_vec(t, (idx.len(), tab.dim), dev)?),
            None => None,
        };
        Ok((
            Tensor::from_vec(o, (idx.len(), 2, self.cfg.obs, FEATURES), dev)?,
            Tensor::from_vec(f, (idx.len(), 2, self.cfg.pred, FEATURES), dev)?,
            text,
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
    /// Seconds since the start (summed over resumed runs).
    pub elapsed_s: f64,
}

/// Where a run stands after an epoch (saved next to the weights for `--resume`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TrainState {
    /// Next epoch to run.
    pub next_epoch: usize,
    /// Optimiser steps so far.
    pub step: usize,
    /// Best validation JPE at 1.0 s so far, mm.
    pub best: Option<f64>,
    /// Epochs since the best.
    pub since_best: usize,
    /// Per-epoch records.
    pub log: Vec<EpochLog>,
    /// The model being trained (must match on resume).
    pub model: ForecasterConfig,
}

/// Paths of a run's resumable state, from the output stem.
pub struct StatePaths {
    /// JSON [`TrainState`].
    pub state: PathBuf,
    /// Current weights.
    pub weights: PathBuf,
    /// Best weights so far.
    pub best: PathBuf,
    /// Optimiser moments.
    pub optim: PathBuf,
}

impl StatePaths {
    /// `<stem>.resume/{state.json,weights,best,optim.safetensors}`.
    pub fn of(stem: &Path) -> StatePaths {
        let d = stem.with_extension("resume");
        StatePaths {
            state: d.join("state.json"),
            weights: d.join("weights.safetensors"),
            best: d.join("best.safetensors"),
            optim: d.join("optim.safetensors"),
        }
    }
}

/// Progress callbacks.
pub trait Progress {
    /// After each step: step within the epoch, steps per epoch, loss.
    fn step(&mut self, _k: usize, _n: usize, _loss: f64) {}
    /// After each epoch.
    fn epoch(&mut self, _e: &EpochLog) {}
}

/// No progress output.
pub struct Quiet;
impl Progress for Quiet {}

/// Everything a run needs besides the settings.
pub struct Run<'a> {
    /// Device.
    pub dev: Device,
    /// Sentence encoder (required when the model has a text token).
    pub text: Option<&'a SentenceEncoder>,
    /// Stem whose `.resume/` folder receives the state after every epoch (None: not saved).
    pub state: Option<PathBuf>,
    /// Continue from the saved state.
    pub resume: bool,
    /// Start from these weights (`<stem>.safetensors` of a checkpoint of the same model) with a
    /// fresh optimiser: fine-tuning. Ignored when resuming.
    pub init: Option<PathBuf>,
    /// Training and validation windows from the dataset layer (`echo-data`); `None`: the
    /// generator's train and validation splits (`train_clips`, `val_clips`).
    pub data: Option<(Vec<Window>, Vec<Window>)>,
}

/// Train a forecaster; returns the best weights (by validation JPE at 1.0 s) and the log.
pub fn train(
    cfg: &ForecasterConfig,
    t: &TrainConfig,
    run: &Run,
    progress: &mut dyn Progress,
) -> anyhow::Result<(VarMap, Vec<EpochLog>)> {
    let started = Instant::now();
    let dev = &run.dev;
    anyhow::ensure!(
        cfg.text_dim == 0 || run.text.is_some_and(|e| e.dim() == cfg.text_dim),
        "the model has a {}-d text token: a sentence encoder of that size is needed",
        cfg.text_dim
    );
    let text = if cfg.text_dim > 0 { run.text } else { None };
    let (train_w, val_w) = match &run.data {
        Some((tr, va)) => (tr.clone(), va.clone()),
        None => {
            let train_clips = generate_split(Split::Train, 0..t.train_clips, 2, &|| {});
            let val_clips = generate_split(Split::Val, 0..t.val_clips, 2, &|| {});
            let tr: Vec<Window> = train_clips
                .iter()
                .flat_map(|c| windows(c, t.stride))
                .collect();
            let va: Vec<Window> = val_clips.iter().flat_map(|c| windows(c, 8)).collect();
            (tr, va)
        }
    };
    anyhow::ensure!(
        !train_w.is_empty() && !val_w.is_empty(),
        "no training or no validation windows ({} and {})",
        train_w.len(),
        val_w.len()
    );
    let table = match text {
        Some(enc) => Some(TextTable::build(enc, &[&train_w])?),
        None => None,
    };
    let data = Batches::new(&train_w, cfg, table.as_ref());
    drop(train_w);

    let mut varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, dev);
    let model = Forecaster::new(cfg.clone(), vb)?;
    if let (Some(init), false) = (&run.init, run.resume) {
        varmap
            .load(init)
            .map_err(|e| anyhow::anyhow!("initial weights {}: {e}", init.display()))?;
    }
    let mut opt = AdamW::from_varmap(&varmap, t.lr, 1e-4)?;
    let paths = run.state.as_deref().map(StatePaths::of);
    let mut state = TrainState {
        next_epoch: 0,
        step: 0,
        best: None,
        since_best: 0,
        log: vec![],
        model: cfg.clone(),
    };
    let mut best_weights: Option<HashMap<String, Tensor>> = None;
    let mut elapsed_before = 0.0;
    if run.resume {
        let p = paths
            .as_ref()
            .ok_or_else(|| anyhow::anyhow!("resume needs an output stem"))?;
        let s: TrainState = serde_json::from_slice(
            &std::fs::read(&p.state).map_err(|e| anyhow::anyhow!("{}: {e}", p.state.display()))?,
        )
        .map_err(|e| anyhow::anyhow!("{}: {e}", p.state.display()))?;
        anyhow::ensure!(
            s.model == *cfg,
            "{}: saved for a different model ({:?})",
            p.state.display(),
            s.model
        );
        varmap.load(&p.weights)?;
        opt.load(&p.optim)?;
        if p.best.is_file() {
            best_weights = Some(candle_core::safetensors::load(&p.best, dev)?);
        }
        elapsed_before = s.log.last().map(|e| e.elapsed_s).unwrap_or(0.0);
        state = s;
    }
    let steps_per_epoch = data.len().div_ceil(t.batch.max(1));
    let out_of_time = || started.elapsed().as_secs_f64() > t.max_minutes * 60.0;
    while state.next_epoch < t.epochs && state.since_best < t.patience && !out_of_time() {
        let epoch = state.next_epoch;
        // Per-epoch seed: a resumed run shuffles exactly as an uninterrupted one.
        let mut rng = rand::rngs::StdRng::seed_from_u64(t.seed.wrapping_mul(1000) + epoch as u64);
        let mut order: Vec<usize> = (0..data.len()).collect();
        order.shuffle(&mut rng);
        let mut total = 0.0;
        let mut steps = 0;
        for (k, idx) in order.chunks(t.batch.max(1)).enumerate() {
            let step = state.step;
            opt.lr = if step < t.warmup {
                t.lr * (step + 1) as f64 / t.warmup as f64
            } else {
                t.lr * t.decay.powf(step as f64 / steps_per_epoch as f64)
            };
            let (obs, fut, txt) = data.batch(idx, table.as_ref(), &mut rng, dev)?;
            let l = train_step(&model, &mut opt, t, &obs, &fut, txt.as_ref())?;
            anyhow::ensure!(l.is_finite(), "loss became {l} at step {step}");
            total += l;
            steps += 1;
            state.step += 1;
            progress.step(k + 1, steps_per_epoch, l);
            if out_of_time() {
                break;
            }
        }
        // Validation: JPE of the model through the evaluation harness.
        let mut p = ModelPredictor::new(&model, dev.clone(), "validation", text);
        let r = evaluate(&mut p, &val_w, 128);
        let e = EpochLog {
            epoch,
            train_loss: total / steps.max(1) as f64,
            val_jpe: r.overall.jpe.clone(),
            elapsed_s: elapsed_before + started.elapsed().as_secs_f64(),
        };
        progress.epoch(&e);
        let score = e.val_jpe[2];
        if state.best.is_none_or(|b| score < b) {
            best_weights = Some(snapshot(&varmap)?);
            state.best = Some(score);
            state.since_best = 0;
        } else {
            state.since_best += 1;
        }
        state.log.push(e);
        state.next_epoch += 1;
        if let Some(p) = &paths {
            save_state(p, &state, &varmap, &opt, best_weights.as_ref())?;
        }
    }
    if let Some(best) = best_weights {
        let data = varmap
            .data()
            .lock()
            .map_err(|_| anyhow::anyhow!("poisoned weights"))?;
        for (k, v) in best {
            if let Some(var) = data.get(&k) {
                var.set(&v)?;
            }
        }
    }
    Ok((varmap, state.log))
}

fn snapshot(varmap: &VarMap) -> anyhow::Result<HashMap<String, Tensor>> {
    Ok(varmap
        .data()
        .lock()
        .map_err(|_| anyhow::anyhow!("poisoned weights"))?
        .iter()
        .map(|(k, v)| Ok((k.clone(), v.as_tensor().copy()?)))
        .collect::<candle_core::Result<_>>()?)
}

fn save_state(
    p: &StatePaths,
    state: &TrainState,
    varmap: &VarMap,
    opt: &AdamW,
    best: Option<&HashMap<String, Tensor>>,
) -> anyhow::Result<()> {
    if let Some(d) = p.state.parent() {
        std::fs::create_dir_all(d)?;
    }
    varmap.save(&p.weights)?;
    opt.save(&p.optim)?;
    if let Some(b) = best {
        candle_core::safetensors::save(b, &p.best)?;
    }
    // The JSON last: a state file always points at complete tensors.
    let tmp = p.state.with_extension("json.part");
    std::fs::write(&tmp, serde_json::to_vec_pretty(state)?)?;
    std::fs::rename(&tmp, &p.state)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> (ForecasterConfig, TrainConfig) {
        (
            ForecasterConfig {
                d_model: 16,
                heads: 2,
                ..Default::default()
            },
            TrainConfig {
                train_clips: 13,
                val_clips: 13,
                stride: 12,
                batch: 16,
                epochs: 2,
                patience: 5,
                warmup: 4,
                ..Default::default()
            },
        )
    }

    #[test]
    fn training_resumes_from_its_saved_state() {
        let (cfg, mut t) = tiny();
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path().to_path_buf();
        let run = |resume: bool, stem: &Path| Run {
            dev: Device::Cpu,
            text: None,
            state: Some(stem.to_path_buf()),
            resume,
            init: None,
            data: None,
        };
        // One epoch, saved; the state is copied so two runs can resume from it.
        t.epochs = 1;
        let (a, b) = (dir.join("a"), dir.join("b"));
        let (_, first) = train(&cfg, &t, &run(false, &a), &mut Quiet).unwrap();
        let (sa, sb) = (StatePaths::of(&a), StatePaths::of(&b));
        std::fs::create_dir_all(sb.state.parent().unwrap()).unwrap();
        for (x, y) in [
            (&sa.state, &sb.state),
            (&sa.weights, &sb.weights),
            (&sa.best, &sb.best),
            (&sa.optim, &sb.optim),
        ] {
            std::fs::copy(x, y).unwrap();
        }
        t.epochs = 2;
        let (_, ra) = train(&cfg, &t, &run(true, &a), &mut Quiet).unwrap();
        let (_, rb) = train(&cfg, &t, &run(true, &b), &mut Quiet).unwrap();
        // The log continues (epoch 0 kept, epoch 1 added) and resuming is deterministic.
        assert_eq!(ra.len(), 2);
        let close = |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(a, b)| (a - b).abs() < 1e-9);
        assert!(close(&ra[0].val_jpe, &first[0].val_jpe));
        assert_eq!(ra[1].epoch, 1);
        assert!((ra[1].train_loss - rb[1].train_loss).abs() < 1e-9);
        assert!(
            close(&ra[1].val_jpe, &rb[1].val_jpe),
            "{:?} vs {:?}",
            ra[1],
            rb[1]
        );
        let state: TrainState = serde_json::from_slice(&std::fs::read(&sa.state).unwrap()).unwrap();
        assert_eq!(state.next_epoch, 2);
        // A different model cannot resume this state.
        let other = ForecasterConfig { d_model: 32, ..cfg };
        assert!(train(&other, &t, &run(true, &a), &mut Quiet).is_err());
    }

    #[test]
    fn fine_tuning_starts_from_the_given_weights() {
        let (cfg, mut t) = tiny();
        t.epochs = 1;
        let scratch = tempfile::tempdir().unwrap();
        let base = scratch.path().join("base.safetensors");
        let run = |init: Option<PathBuf>| Run {
            dev: Device::Cpu,
            text: None,
            state: None,
            resume: false,
            init,
            data: None,
        };
        let (trained, log) = train(&cfg, &t, &run(None), &mut Quiet).unwrap();
        trained.save(&base).unwrap();
        // An epoch at learning rate 0 from the saved weights: validation starts where the
        // first run ended, not where a fresh model starts.
        let init = run(Some(base.clone()));
        t.lr = 0.0;
        let (tuned, tuned_log) = train(&cfg, &t, &init, &mut Quiet).unwrap();
        let (_, fresh_log) = train(&cfg, &t, &run(None), &mut Quiet).unwrap();
        let d = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f64>();
        assert!(
            d(&tuned_log[0].val_jpe, &log[0].val_jpe) < 1e-6,
            "{:?} vs {:?}",
            tuned_log[0].val_jpe,
            log[0].val_jpe
        );
        assert!(d(&fresh_log[0].val_jpe, &log[0].val_jpe) > 1e-3);
        let w = |v: &VarMap| {
            let data = v.data().lock().unwrap();
            let mut k: Vec<_> = data.keys().cloned().collect();
            k.sort();
            data[&k[0]]
                .as_tensor()
                .flatten_all()
                .unwrap()
                .to_vec1::<f32>()
                .unwrap()
        };
        assert_eq!(w(&tuned), w(&trained));
        // Weights of another model are refused.
        let other = ForecasterConfig { d_model: 32, ..cfg };
        assert!(train(&other, &t, &init, &mut Quiet).is_err());
    }

    #[test]
    fn text_conditioned_training_runs_with_a_tiny_encoder() {
        let (mut cfg, mut t) = tiny();
        let enc = echo_text::tiny::encoder(8).unwrap();
        cfg.text_dim = 8;
        t.epochs = 1;
        let run = Run {
            dev: Device::Cpu,
            text: Some(&enc),
            state: None,
            resume: false,
            init: None,
            data: None,
        };
        let (_, log) = train(&cfg, &t, &run, &mut Quiet).unwrap();
        assert!(log[0].train_loss.is_finite());
        assert!(enc.cached() > 0);
        // Without the encoder the same model cannot train.
        let none = Run { text: None, ..run };
        assert!(train(&cfg, &t, &none, &mut Quiet).is_err());
    }
}
