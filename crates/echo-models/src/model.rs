//! The dual-agent forecaster (paper §3.1–3.3), every size in [`ForecasterConfig`]:
//!
//! 1. per-agent MLP embedding of each frame's features → d;
//! 2. the input is the observed frames padded to T = obs + pred by repeating the last one;
//!    sinusoidal positional embedding added; an optional text token prepended;
//! 3. self intent: `self_layers` pre-LN transformer layers, then `temp_mlp` siMLPe blocks
//!    `x + LN_features(Linear_time(x))` (time weights start at zero: identity);
//! 4. social intent: `rounds` of interleaved cross-attention — A refined by B, then B by the
//!    refined A — each followed by a feed-forward block;
//! 5. per-agent MLP decoder → a displacement per future frame, added to the last observed frame.

use candle_core::{DType, Device, Module, Result, Tensor, D};
use candle_nn::{layer_norm, linear, LayerNorm, Linear, VarBuilder};
use serde::{Deserialize, Serialize};

use crate::features::FEATURES;

/// Architecture sizes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ForecasterConfig {
    /// Observed frames.
    pub obs: usize,
    /// Predicted frames.
    pub pred: usize,
    /// Model width.
    pub d_model: usize,
    /// Attention heads.
    pub heads: usize,
    /// Self-attention layers (self intent).
    pub self_layers: usize,
    /// siMLPe temporal blocks after the self-attention.
    pub temp_mlp: usize,
    /// Rounds of interleaved cross-attention (social intent); 0 = single-agent variant.
    pub rounds: usize,
    /// Text embedding size (0: no text token).
    pub text_dim: usize,
}

impl Default for ForecasterConfig {
    fn default() -> Self {
        ForecasterConfig {
            obs: 8,
            pred: 23,
            d_model: 64,
            heads: 4,
            self_layers: 1,
            temp_mlp: 2,
            rounds: 2,
            text_dim: 0,
        }
    }
}

impl ForecasterConfig {
    /// Frames in the model (observed + predicted).
    pub fn frames(&self) -> usize {
        self.obs + self.pred
    }
}

struct Mlp {
    a: Linear,
    b: Linear,
}

impl Mlp {
    fn new(i: usize, h: usize, o: usize, vb: VarBuilder) -> Result<Mlp> {
        Ok(Mlp {
            a: linear(i, h, vb.pp("fc1"))?,
            b: linear(h, o, vb.pp("fc2"))?,
        })
    }

    /// An MLP whose output layer starts at zero: the decoders begin as the displacement
    /// baseline (repeat the last observed frame) and learn corrections from there.
    fn zero_out(i: usize, h: usize, o: usize, vb: VarBuilder) -> Result<Mlp> {
        let w = vb
            .pp("fc2")
            .get_with_hints((o, h), "weight", candle_nn::init::ZERO)?;
        let b = vb
            .pp("fc2")
            .get_with_hints(o, "bias", candle_nn::init::ZERO)?;
        Ok(Mlp {
            a: linear(i, h, vb.pp("fc1"))?,
            b: Linear::new(w, Some(b)),
        })
    }

    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        self.b.forward(&self.a.forward(x)?.gelu()?)
    }
}

struct Attention {
    q: Linear,
    k: Linear,
    v: Linear,
    o: Linear,
    heads: usize,
}

impl Attention {
    fn new(d: usize, heads: usize, vb: VarBuilder) -> Result<Attention> {
        Ok(Attention {
            q: linear(d, d, vb.pp("q"))?,
            k: linear(d, d, vb.pp("k"))?,
            v: linear(d, d, vb.pp("v"))?,
            o: linear(d, d, vb.pp("o"))?,
            heads,
        })
    }

    /// Attention of `x` (queries) over `ctx` (keys and values): (b, t, d) → (b, t, d).
    fn forward(&self, x: &Tensor, ctx: &Tensor) -> Result<Tensor> {
        let (b, tq, d) = x.dims3()?;
        let tk = ctx.dim(1)?;
        let h = self.heads;
        let dh = d / h;
        let split = |t: Tensor, n: usize| -> Result<Tensor> {
            t.reshape((b, n, h, dh))?.transpose(1, 2)?.contiguous()
        };
        let q = split(self.q.forward(x)?, tq)?;
        let k = split(self.k.forward(ctx)?, tk)?;
        let v = split(self.v.forward(ctx)?, tk)?;
        let att = (q.matmul(&k.t()?.contiguous()?)? / (dh as f64).sqrt())?;
        let att = candle_nn::ops::softmax_last_dim(&att)?;
        let y = att.matmul(&v)?.transpose(1, 2)?.reshape((b, tq, d))?;
        self.o.forward(&y)
    }
}

/// Pre-LN block: attention (self or cross) then feed-forward, both residual.
struct Block {
    ln_q: LayerNorm,
    ln_kv: LayerNorm,
    att: Attention,
    ln_ff: LayerNorm,
    ff: Mlp,
}

impl Block {
    fn new(d: usize, heads: usize, vb: VarBuilder) -> Result<Block> {
        Ok(Block {
            ln_q: layer_norm(d, 1e-5, vb.pp("ln_q"))?,
            ln_kv: layer_norm(d, 1e-5, vb.pp("ln_kv"))?,
            att: Attention::new(d, heads, vb.pp("att"))?,
            ln_ff: layer_norm(d, 1e-5, vb.pp("ln_ff"))?,
            ff: Mlp::new(d, 2 * d, d, vb.pp("ff"))?,
        })
    }

    fn forward(&self, x: &Tensor, ctx: &Tensor) -> Result<Tensor> {
        let x = (x + self
            .att
            .forward(&self.ln_q.forward(x)?, &self.ln_kv.forward(ctx)?)?)?;
        &x + self.ff.forward(&self.ln_ff.forward(&x)?)?
    }
}

/// siMLPe temporal block: `x + LN_features(Linear_time(x))`.
struct TempMlp {
    time: Linear,
    ln: LayerNorm,
}

impl TempMlp {
    fn new(t: usize, d: usize, vb: VarBuilder) -> Result<TempMlp> {
        // Zero-initialised time weights: the block starts as the identity.
        let w = vb
            .pp("time")
            .get_with_hints((t, t), "weight", candle_nn::init::ZERO)?;
        let b = vb
            .pp("time")
            .get_with_hints(t, "bias", candle_nn::init::ZERO)?;
        Ok(TempMlp {
            time: Linear::new(w, Some(b)),
            ln: layer_norm(d, 1e-5, vb.pp("ln"))?,
        })
    }

    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let y = self
            .time
            .forward(&x.transpose(1, 2)?.contiguous()?)?
            .transpose(1, 2)?
            .contiguous()?;
        x + self.ln.forward(&y)?
    }
}

/// The forecaster.
pub struct Forecaster {
    cfg: ForecasterConfig,
    embed: [Mlp; 2],
    text: Option<Linear>,
    self_blocks: Vec<Block>,
    temp: Vec<TempMlp>,
    cross: Vec<[Block; 2]>,
    decode: [Mlp; 2],
    pe: Tensor,
}

fn sinusoidal(t: usize, d: usize, dev: &Device) -> Result<Tensor> {
    let mut v = vec![0f32; t * d];
    for p in 0..t {
        for i in 0..d / 2 {
            let w = 1.0 / 10000f64.powf(2.0 * i as f64 / d as f64);
            v[p * d + 2 * i] = (p as f64 * w).sin() as f32;
            v[p * d + 2 * i + 1] = (p as f64 * w).cos() as f32;
        }
    }
    Tensor::from_vec(v, (1, t, d), dev)
}

impl Forecaster {
    /// Build (for training: a `VarMap` builder; for inference: a safetensors builder).
    pub fn new(cfg: ForecasterConfig, vb: VarBuilder) -> Result<Forecaster> {
        let d = cfg.d_model;
        let t = cfg.frames() + usize::from(cfg.text_dim > 0);
        Ok(Forecaster {
            embed: [
                Mlp::new(FEATURES, d, d, vb.pp("embed_a"))?,
                Mlp::new(FEATURES, d, d, vb.pp("embed_b"))?,
            ],
            text: if cfg.text_dim > 0 {
                Some(linear(cfg.text_dim, d, vb.pp("text"))?)
            } else {
                None
            },
            self_blocks: (0..cfg.self_layers)
                .map(|i| Block::new(d, cfg.heads, vb.pp(format!("self.{i}"))))
                .collect::<Result<_>>()?,
            temp: (0..cfg.temp_mlp)
                .map(|i| TempMlp::new(t, d, vb.pp(format!("temp.{i}"))))
                .collect::<Result<_>>()?,
            cross: (0..cfg.rounds)
                .map(|i| {
                    Ok([
                        Block::new(d, cfg.heads, vb.pp(format!("cross.{i}.a")))?,
                        Block::new(d, cfg.heads, vb.pp(format!("cross.{i}.b")))?,
                    ])
                })
                .collect::<Result<_>>()?,
            decode: [
                Mlp::zero_out(d, d, FEATURES, vb.pp("decode_a"))?,
                Mlp::zero_out(d, d, FEATURES, vb.pp("decode_b"))?,
            ],
            pe: sinusoidal(cfg.frames(), d, vb.device())?,
            cfg,
        })
    }

    /// Configuration.
    pub fn config(&self) -> &ForecasterConfig {
        &self.cfg
    }

    /// `obs`: (b, 2, obs, FEATURES) observed features; `text`: (b, text_dim) when configured.
    /// Returns (b, 2, pred, FEATURES): the last observed frame plus predicted displacements.
    pub fn forward(&self, obs: &Tensor, text: Option<&Tensor>) -> Result<Tensor> {
        let (b, _, n_obs, f) = obs.dims4()?;
        let t = self.cfg.frames();
        let mut agents = Vec::with_capacity(2);
        let mut lasts = Vec::with_capacity(2);
        for a in 0..2 {
            let x = obs.narrow(1, a, 1)?.squeeze(1)?; // (b, obs, f)
            let last = x.narrow(1, n_obs - 1, 1)?; // (b, 1, f)
            let padded = Tensor::cat(
                &[
                    x.clone(),
                    last.broadcast_as((b, t - n_obs, f))?.contiguous()?,
                ],
                1,
            )?;
            let mut h = self.embed[a].forward(&padded)?.broadcast_add(&self.pe)?;
            if let (Some(proj), Some(txt)) = (&self.text, text) {
                let tok = proj.forward(txt)?.unsqueeze(1)?; // (b, 1, d)
                h = Tensor::cat(&[tok, h], 1)?;
            }
            for blk in &self.self_blocks {
                h = blk.forward(&h, &h)?;
            }
            for tm in &self.temp {
                h = tm.forward(&h)?;
            }
            agents.push(h);
            lasts.push(last);
        }
        let (mut ha, mut hb) = (agents[0].clone(), agents[1].clone());
        for [ca, cb] in &self.cross {
            ha = ca.forward(&ha, &hb)?;
            hb = cb.forward(&hb, &ha)?;
        }
        let skip = usize::from(self.text.is_some() && text.is_some());
        let mut outs = Vec::with_capacity(2);
        for (a, h) in [ha, hb].iter().enumerate() {
            let fut = h.narrow(1, skip + n_obs, self.cfg.pred)?;
            let delta = self.decode[a].forward(&fut)?;
            outs.push(delta.broadcast_add(&lasts[a])?.unsqueeze(1)?);
        }
        Tensor::cat(&outs, 1)
    }
}

/// A zero tensor of observed features, for shape checks.
pub fn dummy_obs(b: usize, cfg: &ForecasterConfig, dev: &Device) -> Result<Tensor> {
    Tensor::zeros((b, 2, cfg.obs, FEATURES), DType::F32, dev)
}

/// Mean squared error over every value.
pub fn mse(a: &Tensor, b: &Tensor) -> Result<Tensor> {
    (a - b)?.sqr()?.mean_all()
}

/// Interaction loss: error of the relative root position of B seen from A, per future frame.
pub fn interaction_loss(pred: &Tensor, truth: &Tensor) -> Result<Tensor> {
    let o = 3 * echo_motion::skeleton::NUM_JOINTS;
    let rel = |x: &Tensor| -> Result<Tensor> {
        let ra = x.narrow(1, 0, 1)?.narrow(D::Minus1, o, 3)?;
        let rb = x.narrow(1, 1, 1)?.narrow(D::Minus1, o, 3)?;
        rb - ra
    };
    mse(&rel(pred)?, &rel(truth)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_nn::VarMap;

    #[test]
    fn shapes_and_the_displacement_baseline() {
        let dev = Device::Cpu;
        let vm = VarMap::new();
        let vb = VarBuilder::from_varmap(&vm, DType::F32, &dev);
        let cfg = ForecasterConfig::default();
        let m = Forecaster::new(cfg.clone(), vb).unwrap();
        let obs = Tensor::randn(0f32, 1.0, (3, 2, cfg.obs, FEATURES), &dev).unwrap();
        let y = m.forward(&obs, None).unwrap();
        assert_eq!(y.dims(), &[3, 2, cfg.pred, FEATURES]);
        // Untrained, the decoders output zero: the forecast is the last observed frame repeated.
        assert!(vm
            .data()
            .lock()
            .unwrap()
            .contains_key("decode_a.fc2.weight"));
        let last = obs.narrow(2, cfg.obs - 1, 1).unwrap();
        let diff = (y.broadcast_sub(&last).unwrap())
            .abs()
            .unwrap()
            .max_all()
            .unwrap()
            .to_scalar::<f32>()
            .unwrap();
        assert!(diff < 1e-6, "{diff}");
    }

    #[test]
    fn text_token_and_single_agent_variant_build() {
        let dev = Device::Cpu;
        let vm = VarMap::new();
        let cfg = ForecasterConfig {
            text_dim: 8,
            rounds: 0,
            ..Default::default()
        };
        let m =
            Forecaster::new(cfg.clone(), VarBuilder::from_varmap(&vm, DType::F32, &dev)).unwrap();
        let text = Tensor::ones((2, 8), DType::F32, &dev).unwrap();
        let y = m
            .forward(&dummy_obs(2, &cfg, &dev).unwrap(), Some(&text))
            .unwrap();
        assert_eq!(y.dims(), &[2, 2, cfg.pred, FEATURES]);
    }
}
