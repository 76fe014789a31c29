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

use candle_core::{DType, Device, Result, Tensor, D};
use candle_nn::VarBuilder;
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
    /// Text embedding size (0: no text token — the "w/o Text" ablation).
    pub text_dim: usize,
    /// Output = last observed frame + decoded displacement (false: the "w/o Baseline"
    /// ablation, the decoder outputs the future frames themselves).
    pub displacement: bool,
    /// Tokens are DCT coefficients of the padded sequence over time, and the decoder's output
    /// is transformed back (the "w/ DCT" ablation).
    pub dct: bool,
    /// Interleaved refinement — each round refines A by B, then B by the refined A (false: the
    /// "w/o Iterative Refinement" ablation — all rounds refine A by B's self-intent, then all
    /// rounds refine B by the final A).
    pub interleaved: bool,
    /// Values per frame of agent A and agent B: 73 for a person (see [`crate::features`]);
    /// a robot agent has its own size (joint angles + base).
    pub agent_features: [usize; 2],
    /// Initialisation only: the cross-attention blocks' output layers start at zero, so the
    /// untrained social branch passes each agent's self intent through unchanged (the
    /// single-agent model) and training learns the partner's influence as a correction
    /// (false: random like every other layer — checkpoints from before this setting).
    pub social_identity_init: bool,
    /// With `displacement`: the decoded displacement is added to a damped constant-velocity
    /// extrapolation of the last two observed frames instead of the last frame alone:
    /// `base_k = x_T + (x_T − x_{T−1})·Σ_{i=1..k} r^i`, `r = exp(−1/(τ·15 Hz))`, τ this many
    /// seconds (0: the last frame, as in the paper). Real people carry momentum; the prior lets
    /// the network learn corrections to it instead of velocity itself.
    pub velocity_prior_s: f64,
    /// With `velocity_prior_s`: the prior extrapolates a person's root (position and heading)
    /// only, and holds the local pose (the 66 pelvis-relative joint values): limbs are not
    /// predictable by momentum the way the body's travel is.
    pub velocity_prior_root_only: bool,
}

/// Values of a person's local pose at the start of their features (22 joints × 3).
const LOCAL_POSE: usize = 66;

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
            displacement: true,
            dct: false,
            interleaved: true,
            agent_features: [FEATURES, FEATURES],
            social_identity_init: false,
            velocity_prior_s: 0.0,
            velocity_prior_root_only: false,
        }
    }
}

impl ForecasterConfig {
    /// Gains of the velocity prior per predicted frame and value, row-major `pred × features`:
    /// [`Self::prior_gains`] in every column, or only in a person's root columns (the last
    /// [`crate::features::FEATURES`] − 66) with `velocity_prior_root_only`.
    pub fn prior_gain_matrix(&self, features: usize) -> Vec<f32> {
        let gains = self.prior_gains();
        let root_only = self.velocity_prior_root_only && features == crate::features::FEATURES;
        let mut m = Vec::with_capacity(self.pred * features);
        for g in gains {
            m.extend((0..features).map(|c| if root_only && c < LOCAL_POSE { 0.0 } else { g }));
        }
        m
    }

    /// Gains of the velocity prior per predicted frame: `Σ_{i=1..k} r^i` (all zero without it).
    pub fn prior_gains(&self) -> Vec<f32> {
        if self.velocity_prior_s.is_nan() || self.velocity_prior_s <= 0.0 || !self.displacement {
            return vec![0.0; self.pred];
        }
        let r = (-1.0 / (self.velocity_prior_s * 15.0)).exp();
        let mut acc = 0.0;
        (1..=self.pred)
            .map(|k| {
                acc += r.powi(k as i32);
                acc as f32
            })
            .collect()
    }

    /// Frames in the model (observed + predicted).
    pub fn frames(&self) -> usize {
        self.obs + self.pred
    }
}

/// A linear layer `y = x Wᵀ + b`, stored as candle's (`weight` (out, in), `bias` (out)) and
/// initialised the same way; the bias is added by [`crate::ops::bias_add`], whose gradient is
/// one pass over the rows.
struct Linear {
    weight: Tensor,
    bias: Tensor,
}

impl Linear {
    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let dims = x.dims();
        let i = dims[dims.len() - 1];
        let mut out = dims.to_vec();
        let last = out.len() - 1;
        out[last] = self.weight.dim(0)?;
        let y = x
            .reshape((x.elem_count() / i, i))?
            .matmul(&self.weight.t()?)?;
        crate::ops::bias_add(&y, &self.bias)?.reshape(out)
    }
}

fn linear(i: usize, o: usize, vb: VarBuilder) -> Result<Linear> {
    let bound = 1.0 / (i as f64).sqrt();
    Ok(Linear {
        weight: vb.get_with_hints((o, i), "weight", candle_nn::init::DEFAULT_KAIMING_NORMAL)?,
        bias: vb.get_with_hints(
            o,
            "bias",
            candle_nn::Init::Uniform {
                lo: -bound,
                up: bound,
            },
        )?,
    })
}

/// Layer norm over the model width, differentiable ([`crate::ops::layer_norm`]); the
/// parameters are stored as `weight` and `bias` (gain 1, shift 0 when training starts).
struct LayerNorm {
    weight: Tensor,
    bias: Tensor,
}

fn layer_norm(d: usize, vb: VarBuilder) -> Result<LayerNorm> {
    Ok(LayerNorm {
        weight: vb.get_with_hints(d, "weight", candle_nn::init::ONE)?,
        bias: vb.get_with_hints(d, "bias", candle_nn::init::ZERO)?,
    })
}

impl LayerNorm {
    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        crate::ops::layer_norm(x, &self.weight, &self.bias, 1e-5)
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
        Ok(Mlp {
            a: linear(i, h, vb.pp("fc1"))?,
            b: zero_linear(h, o, vb.pp("fc2"))?,
        })
    }

    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        self.b.forward(&crate::ops::gelu(&self.a.forward(x)?)?)
    }
}

/// A linear layer whose weight and bias start at zero (when training; loaded weights win).
fn zero_linear(i: usize, o: usize, vb: VarBuilder) -> Result<Linear> {
    let w = vb.get_with_hints((o, i), "weight", candle_nn::init::ZERO)?;
    let b = vb.get_with_hints(o, "bias", candle_nn::init::ZERO)?;
    Ok(Linear { weight: w, bias: b })
}

struct Attention {
    q: Linear,
    k: Linear,
    v: Linear,
    o: Linear,
    heads: usize,
}

impl Attention {
    /// `zero_out`: the output projection starts at zero (the attention adds nothing).
    fn new(d: usize, heads: usize, zero_out: bool, vb: VarBuilder) -> Result<Attention> {
        Ok(Attention {
            q: linear(d, d, vb.pp("q"))?,
            k: linear(d, d, vb.pp("k"))?,
            v: linear(d, d, vb.pp("v"))?,
            o: if zero_out {
                zero_linear(d, d, vb.pp("o"))?
            } else {
                linear(d, d, vb.pp("o"))?
            },
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
        // The scale on q (t·dh values) rather than on the scores (t·t); kᵀ as a strided view
        // (the matrix product reads it column-major, no copy).
        let q = (split(self.q.forward(x)?, tq)? * (1.0 / (dh as f64).sqrt()))?;
        let k = split(self.k.forward(ctx)?, tk)?;
        let v = split(self.v.forward(ctx)?, tk)?;
        let att = crate::ops::softmax_last_dim(&q.matmul(&k.t()?)?)?;
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
    /// `identity`: both residual branches start at zero, so the block starts as the identity.
    fn new(d: usize, heads: usize, identity: bool, vb: VarBuilder) -> Result<Block> {
        Ok(Block {
            ln_q: layer_norm(d, vb.pp("ln_q"))?,
            ln_kv: layer_norm(d, vb.pp("ln_kv"))?,
            att: Attention::new(d, heads, identity, vb.pp("att"))?,
            ln_ff: layer_norm(d, vb.pp("ln_ff"))?,
            ff: if identity {
                Mlp::zero_out(d, 2 * d, d, vb.pp("ff"))?
            } else {
                Mlp::new(d, 2 * d, d, vb.pp("ff"))?
            },
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
            time: Linear { weight: w, bias: b },
            ln: layer_norm(d, vb.pp("ln"))?,
        })
    }

    /// `Linear_time` as `W x + b` over each window's (t, d) matrix: no transposes.
    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let (b, t, _) = x.dims3()?;
        let w = self.time.weight.broadcast_left(b)?;
        let y = w
            .matmul(x)?
            .broadcast_add(&self.time.bias.reshape((1, t, 1))?)?;
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
    /// Orthonormal DCT-II matrix over the T frames (when `dct`).
    dct: Option<Tensor>,
}

/// Orthonormal DCT-II matrix: `C = D x` along time, `x = Dᵀ C`.
pub fn dct_matrix(t: usize, dev: &Device) -> Result<Tensor> {
    let mut v = vec![0f32; t * t];
    for k in 0..t {
        let s = if k == 0 {
            (1.0 / t as f64).sqrt()
        } else {
            (2.0 / t as f64).sqrt()
        };
        for n in 0..t {
            v[k * t + n] =
                (s * (std::f64::consts::PI / t as f64 * (n as f64 + 0.5) * k as f64).cos()) as f32;
        }
    }
    Tensor::from_vec(v, (t, t), dev)
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
                Mlp::new(cfg.agent_features[0], d, d, vb.pp("embed_a"))?,
                Mlp::new(cfg.agent_features[1], d, d, vb.pp("embed_b"))?,
            ],
            text: if cfg.text_dim > 0 {
                Some(linear(cfg.text_dim, d, vb.pp("text"))?)
            } else {
                None
            },
            self_blocks: (0..cfg.self_layers)
                .map(|i| Block::new(d, cfg.heads, false, vb.pp(format!("self.{i}"))))
                .collect::<Result<_>>()?,
            temp: (0..cfg.temp_mlp)
                .map(|i| TempMlp::new(t, d, vb.pp(format!("temp.{i}"))))
                .collect::<Result<_>>()?,
            cross: (0..cfg.rounds)
                .map(|i| {
                    let id = cfg.social_identity_init;
                    Ok([
                        Block::new(d, cfg.heads, id, vb.pp(format!("cross.{i}.a")))?,
                        Block::new(d, cfg.heads, id, vb.pp(format!("cross.{i}.b")))?,
                    ])
                })
                .collect::<Result<_>>()?,
            decode: if cfg.displacement {
                [
                    Mlp::zero_out(d, d, cfg.agent_features[0], vb.pp("decode_a"))?,
                    Mlp::zero_out(d, d, cfg.agent_features[1], vb.pp("decode_b"))?,
                ]
            } else {
                [
                    Mlp::new(d, d, cfg.agent_features[0], vb.pp("decode_a"))?,
                    Mlp::new(d, d, cfg.agent_features[1], vb.pp("decode_b"))?,
                ]
            },
            pe: sinusoidal(cfg.frames(), d, vb.device())?,
            dct: if cfg.dct {
                Some(dct_matrix(cfg.frames(), vb.device())?)
            } else {
                None
            },
            cfg,
        })
    }

    /// Configuration.
    pub fn config(&self) -> &ForecasterConfig {
        &self.cfg
    }

    /// `obs`: (b, 2, obs, FEATURES) observed features; `text`: (b, text_dim), required when
    /// the model has a text token. Returns (b, 2, pred, FEATURES): the social (final) forecast.
    pub fn forward(&self, obs: &Tensor, text: Option<&Tensor>) -> Result<Tensor> {
        let (xa, xb) = self.split_agents(obs)?;
        let [sa, sb] = self.forward_social(&xa, &xb, text)?;
        Tensor::stack(&[sa, sb], 1)
    }

    /// The social forecast and the individual one (the self-intent features before any
    /// cross-attention, through the same decoder: what L_self supervises); both agents of the
    /// same size, stacked as (b, 2, pred, F).
    pub fn forward_both(&self, obs: &Tensor, text: Option<&Tensor>) -> Result<(Tensor, Tensor)> {
        let (xa, xb) = self.split_agents(obs)?;
        let ([sa, sb], [ia, ib]) = self.forward_pair(&xa, &xb, text)?;
        Ok((Tensor::stack(&[sa, sb], 1)?, Tensor::stack(&[ia, ib], 1)?))
    }

    /// (b, 2, obs, F) → each agent's (b, obs, F), the shape checked.
    fn split_agents(&self, obs: &Tensor) -> Result<(Tensor, Tensor)> {
        let (_, agents, n_obs, f) = obs.dims4()?;
        if agents != 2 || n_obs != self.cfg.obs || self.cfg.agent_features != [f, f] {
            candle_core::bail!(
                "observed features must be (b, 2, {}, {:?}), got {:?}",
                self.cfg.obs,
                self.cfg.agent_features,
                obs.dims()
            );
        }
        Ok((
            obs.narrow(1, 0, 1)?.squeeze(1)?,
            obs.narrow(1, 1, 1)?.squeeze(1)?,
        ))
    }

    /// Agents of any sizes: `xa` (b, obs, F_a), `xb` (b, obs, F_b) → social `[a, b]` and
    /// individual `[a, b]` forecasts, (b, pred, F_i) each (training: both are supervised).
    pub fn forward_pair(
        &self,
        xa: &Tensor,
        xb: &Tensor,
        text: Option<&Tensor>,
    ) -> Result<([Tensor; 2], [Tensor; 2])> {
        let s = self.self_intent(xa, xb, text)?;
        let (ha, hb) = self.social_intent(&s.h[0], &s.h[1])?;
        Ok((
            [s.decode(self, 0, &ha)?, s.decode(self, 1, &hb)?],
            [s.decode(self, 0, &s.h[0])?, s.decode(self, 1, &s.h[1])?],
        ))
    }

    /// The social forecast alone, `[a, b]`, (b, pred, F_i) each: what serving needs (the
    /// individual forecast is not decoded).
    pub fn forward_social(
        &self,
        xa: &Tensor,
        xb: &Tensor,
        text: Option<&Tensor>,
    ) -> Result<[Tensor; 2]> {
        let s = self.self_intent(xa, xb, text)?;
        let (ha, hb) = self.social_intent(&s.h[0], &s.h[1])?;
        Ok([s.decode(self, 0, &ha)?, s.decode(self, 1, &hb)?])
    }

    /// Embedding, positions, text token, then the self-intent layers. The self-attention and
    /// temporal blocks are shared by both agents, so both run through them as one batch of 2b.
    fn self_intent(&self, xa: &Tensor, xb: &Tensor, text: Option<&Tensor>) -> Result<SelfIntent> {
        let (b, n_obs, _) = xa.dims3()?;
        for (i, x) in [xa, xb].iter().enumerate() {
            let (bi, ni, fi) = x.dims3()?;
            if bi != b || ni != self.cfg.obs || fi != self.cfg.agent_features[i] {
                candle_core::bail!(
                    "agent {i}: observed features must be (b, {}, {}), got {:?}",
                    self.cfg.obs,
                    self.cfg.agent_features[i],
                    x.dims()
                );
            }
        }
        let text = match (&self.text, text) {
            (Some(p), Some(t)) => Some(p.forward(t)?.unsqueeze(1)?), // (b, 1, d)
            (Some(_), None) => candle_core::bail!("this model needs a text embedding"),
            (None, _) => None,
        };
        let t = self.cfg.frames();
        let mut embedded = Vec::with_capacity(2);
        let mut bases = Vec::with_capacity(2);
        for (a, x) in [xa, xb].iter().enumerate() {
            let f = x.dim(2)?;
            let last = x.narrow(1, n_obs - 1, 1)?; // (b, 1, f)
            let mut padded = Tensor::cat(
                &[
                    (*x).clone(),
                    last.broadcast_as((b, t - n_obs, f))?.contiguous()?,
                ],
                1,
            )?;
            if let Some(d) = &self.dct {
                padded = d.broadcast_matmul(&padded)?;
            }
            let mut h = self.embed[a].forward(&padded)?.broadcast_add(&self.pe)?;
            if let Some(tok) = &text {
                h = Tensor::cat(&[tok.clone(), h], 1)?;
            }
            embedded.push(h);
            // The base the displacement is added to: the last frame, plus the damped velocity.
            let base = if self.cfg.velocity_prior_s > 0.0 {
                let prev = x.narrow(1, n_obs - 2, 1)?;
                let v = (&last - &prev)?; // (b, 1, f)
                let g = Tensor::from_vec(
                    self.cfg.prior_gain_matrix(f),
                    (1, self.cfg.pred, f),
                    x.device(),
                )?;
                last.broadcast_add(&v.broadcast_mul(&g)?)?
            } else {
                last
            };
            bases.push(base);
        }
        let mut h = Tensor::cat(&embedded, 0)?; // (2b, T', d): A's windows, then B's
        for blk in &self.self_blocks {
            h = blk.forward(&h, &h)?;
        }
        for tm in &self.temp {
            h = tm.forward(&h)?;
        }
        let [ba, bb]: [Tensor; 2] = bases
            .try_into()
            .map_err(|_| candle_core::Error::Msg("two agents".into()))?;
        Ok(SelfIntent {
            h: [h.narrow(0, 0, b)?, h.narrow(0, b, b)?],
            bases: [ba, bb],
            skip: usize::from(text.is_some()),
            n_obs,
        })
    }

    /// Rounds of cross-attention: each agent refined by the other.
    fn social_intent(&self, ha: &Tensor, hb: &Tensor) -> Result<(Tensor, Tensor)> {
        let (mut ha, mut hb) = (ha.clone(), hb.clone());
        if self.cfg.interleaved {
            for [ca, cb] in &self.cross {
                ha = ca.forward(&ha, &hb)?;
                hb = cb.forward(&hb, &ha)?;
            }
        } else {
            for [ca, _] in &self.cross {
                ha = ca.forward(&ha, &hb)?;
            }
            for [_, cb] in &self.cross {
                hb = cb.forward(&hb, &ha)?;
            }
        }
        Ok((ha, hb))
    }
}

/// Each agent's self-intent features and what decoding needs.
struct SelfIntent {
    /// (b, T', d) per agent.
    h: [Tensor; 2],
    /// What the displacement is added to, (b, 1 or pred, F_i) per agent.
    bases: [Tensor; 2],
    /// Leading tokens before the frames (the text token).
    skip: usize,
    n_obs: usize,
}

impl SelfIntent {
    /// Agent `a`'s features `h` → its forecast (b, pred, F_a).
    fn decode(&self, m: &Forecaster, a: usize, h: &Tensor) -> Result<Tensor> {
        let (t, pred) = (m.cfg.frames(), m.cfg.pred);
        let y = match &m.dct {
            // Decode every coefficient, back to time, keep the future frames.
            Some(d) => d
                .t()?
                .broadcast_matmul(&m.decode[a].forward(&h.narrow(1, self.skip, t)?)?)?
                .narrow(1, self.n_obs, pred)?,
            None => m.decode[a].forward(&h.narrow(1, self.skip + self.n_obs, pred)?)?,
        };
        if m.cfg.displacement {
            y.broadcast_add(&self.bases[a])
        } else {
            Ok(y)
        }
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

/// Cross product along the last dimension (size 3).
fn cross(a: &Tensor, b: &Tensor) -> Result<Tensor> {
    let c = |t: &Tensor, i: usize| t.narrow(D::Minus1, i, 1);
    let (a0, a1, a2) = (c(a, 0)?, c(a, 1)?, c(a, 2)?);
    let (b0, b1, b2) = (c(b, 0)?, c(b, 1)?, c(b, 2)?);
    Tensor::cat(
        &[
            (a1.broadcast_mul(&b2)? - a2.broadcast_mul(&b1)?)?,
            (a2.broadcast_mul(&b0)? - a0.broadcast_mul(&b2)?)?,
            (a0.broadcast_mul(&b1)? - a1.broadcast_mul(&b0)?)?,
        ],
        D::Minus1,
    )
}

/// Joint positions in the window frame from features (…, FEATURES) → (…, 22, 3):
/// `root + q ⊗ local` with the quaternion normalised (differentiable).
pub fn joint_positions(x: &Tensor) -> Result<Tensor> {
    let j = echo_motion::skeleton::NUM_JOINTS;
    let o = 3 * j;
    let mut shape = x.dims().to_vec();
    let last = shape.len() - 1;
    shape[last] = j;
    shape.push(3);
    let local = x.narrow(D::Minus1, 0, o)?.reshape(shape.as_slice())?;
    let root = x.narrow(D::Minus1, o, 3)?.unsqueeze(last)?;
    let q = x.narrow(D::Minus1, o + 3, 4)?.unsqueeze(last)?;
    rotate(&q, &local)?.broadcast_add(&root)
}

/// Rotate vectors `v` (…, 3) by quaternions `q` (…, 4, `[x, y, z, w]`, normalised here;
/// broadcast over the leading dimensions): `v + w t + u × t`, `t = 2 u × v`.
pub fn rotate(q: &Tensor, v: &Tensor) -> Result<Tensor> {
    let q = q.broadcast_div(&(q.sqr()?.sum_keepdim(D::Minus1)?.sqrt()? + 1e-6)?)?;
    let (u, w) = (q.narrow(D::Minus1, 0, 3)?, q.narrow(D::Minus1, 3, 1)?);
    let t = (cross(&u, v)? * 2.0)?;
    (v + t.broadcast_mul(&w)?)? + cross(&u, &t)?
}

/// Interaction loss (paper Eq. 3): MSE between the predicted and true distance matrices of
/// every joint of A to every joint of B, per future frame. `pred`, `truth`: (b, 2, t, F).
pub fn interaction_loss(pred: &Tensor, truth: &Tensor) -> Result<Tensor> {
    let dm = |x: &Tensor| -> Result<Tensor> {
        let p = joint_positions(x)?; // (b, 2, t, 22, 3)
        let a = p.narrow(1, 0, 1)?.squeeze(1)?.unsqueeze(3)?; // (b, t, 22, 1, 3)
        let b = p.narrow(1, 1, 1)?.squeeze(1)?.unsqueeze(2)?; // (b, t, 1, 22, 3)
        (a.broadcast_sub(&b)?.sqr()?.sum(D::Minus1)? + 1e-8)?.sqrt()
    };
    mse(&dm(pred)?, &dm(truth)?)
}

/// Bone-length loss: MSE between predicted and true bone lengths (local pose), both agents.
pub fn bone_loss(pred: &Tensor, truth: &Tensor) -> Result<Tensor> {
    use echo_motion::skeleton::{NUM_JOINTS, PARENTS};
    let lengths = |x: &Tensor| -> Result<Tensor> {
        let mut shape = x.dims().to_vec();
        let last = shape.len() - 1;
        shape[last] = NUM_JOINTS;
        shape.push(3);
        let l = x
            .narrow(D::Minus1, 0, 3 * NUM_JOINTS)?
            .reshape(shape.as_slice())?;
        let child: Vec<u32> = (1..NUM_JOINTS as u32).collect();
        let parent: Vec<u32> = (1..NUM_JOINTS).map(|k| PARENTS[k] as u32).collect();
        let n = child.len();
        let ci = Tensor::from_vec(child, n, x.device())?;
        let pi = Tensor::from_vec(parent, n, x.device())?;
        let bones = (l.index_select(&ci, last)? - l.index_select(&pi, last)?)?;
        (bones.sqr()?.sum(D::Minus1)? + 1e-8)?.sqrt()
    };
    mse(&lengths(pred)?, &lengths(truth)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_nn::VarMap;

    /// An untrained model with `cfg` on random observations: its forecast, the last observed
    /// frame, and what the prior's gain matrix says the forecast must be.
    fn untrained_prior(cfg: &ForecasterConfig) -> (Tensor, Tensor, Tensor) {
        let dev = Device::Cpu;
        let vm = VarMap::new();
        let m =
            Forecaster::new(cfg.clone(), VarBuilder::from_varmap(&vm, DType::F32, &dev)).unwrap();
        let obs = Tensor::randn(0f32, 1.0, (2, 2, cfg.obs, FEATURES), &dev).unwrap();
        let y = m.forward(&obs, None).unwrap();
        let last = obs.narrow(2, cfg.obs - 1, 1).unwrap();
        let v = (&last - obs.narrow(2, cfg.obs - 2, 1).unwrap()).unwrap();
        let g = Tensor::from_vec(
            cfg.prior_gain_matrix(FEATURES),
            (1, 1, cfg.pred, FEATURES),
            &dev,
        )
        .unwrap();
        let want = last.broadcast_add(&v.broadcast_mul(&g).unwrap()).unwrap();
        (y, last, want)
    }

    fn max_abs_diff(a: &Tensor, b: &Tensor) -> f32 {
        (a - b)
            .unwrap()
            .abs()
            .unwrap()
            .max_all()
            .unwrap()
            .to_scalar()
            .unwrap()
    }

    #[test]
    fn untrained_with_the_velocity_prior_the_forecast_is_damped_velocity() {
        let cfg = ForecasterConfig {
            velocity_prior_s: 0.4,
            ..Default::default()
        };
        let g = cfg.prior_gains();
        assert!(g.windows(2).all(|w| w[1] > w[0]) && g[0] > 0.8 && g[0] < 1.0);
        let (y, _, want) = untrained_prior(&cfg);
        let err = max_abs_diff(&y, &want);
        assert!(err < 1e-5, "{err}");
        // Without it: the gains are zero.
        assert!(ForecasterConfig::default()
            .prior_gains()
            .iter()
            .all(|x| *x == 0.0));
    }

    #[test]
    fn the_root_only_prior_holds_the_local_pose_and_extrapolates_the_root() {
        let cfg = ForecasterConfig {
            velocity_prior_s: 0.4,
            velocity_prior_root_only: true,
            ..Default::default()
        };
        let (y, last, want) = untrained_prior(&cfg);
        assert!(max_abs_diff(&y, &want) < 1e-5);
        // The local pose is the last frame's; the root moves.
        let held = last.broadcast_as(y.shape()).unwrap().contiguous().unwrap();
        let pose = |t: &Tensor| t.narrow(3, 0, LOCAL_POSE).unwrap();
        assert!(max_abs_diff(&pose(&y), &pose(&held)) < 1e-6);
        let root = |t: &Tensor| t.narrow(3, LOCAL_POSE, FEATURES - LOCAL_POSE).unwrap();
        assert!(max_abs_diff(&root(&y), &root(&held)) > 0.1);
        // Other feature sizes (a robot agent) get the prior in every column.
        assert!(cfg.prior_gain_matrix(20).iter().all(|x| *x > 0.0));
    }

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

    /// Gradients reach every parameter: with all weights random (no zero-initialised layer to
    /// stop them), one loss's gradient is non-zero for each variable — layer norms, temporal
    /// blocks, query and key projections included.
    #[test]
    fn every_parameter_receives_a_gradient() {
        let dev = Device::Cpu;
        let cfg = ForecasterConfig {
            text_dim: 12,
            velocity_prior_s: 0.3,
            ..ForecasterConfig::default()
        };
        let vm = VarMap::new();
        let m =
            Forecaster::new(cfg.clone(), VarBuilder::from_varmap(&vm, DType::F32, &dev)).unwrap();
        for (_, v) in vm.data().lock().unwrap().iter() {
            v.set(&Tensor::randn(0f32, 0.2, v.shape(), &dev).unwrap())
                .unwrap();
        }
        let obs = Tensor::randn(0f32, 1.0, (3, 2, cfg.obs, FEATURES), &dev).unwrap();
        let fut = Tensor::randn(0f32, 1.0, (3, 2, cfg.pred, FEATURES), &dev).unwrap();
        let text = Tensor::randn(0f32, 1.0, (3, 12), &dev).unwrap();
        let (soc, ind) = m.forward_both(&obs, Some(&text)).unwrap();
        let loss = (mse(&soc, &fut).unwrap() + mse(&ind, &fut).unwrap()).unwrap();
        let grads = loss.backward().unwrap();
        let data = vm.data().lock().unwrap();
        let mut names: Vec<_> = data.keys().cloned().collect();
        names.sort();
        for name in names {
            let g = grads
                .get(data[&name].as_tensor())
                .unwrap_or_else(|| panic!("{name}: no gradient"));
            let norm = g
                .sqr()
                .unwrap()
                .sum_all()
                .unwrap()
                .to_scalar::<f32>()
                .unwrap();
            assert!(norm > 0.0, "{name}: zero gradient");
        }
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

    #[test]
    fn every_ablation_builds_and_starts_at_its_baseline() {
        let dev = Device::Cpu;
        let base = ForecasterConfig {
            d_model: 16,
            heads: 2,
            ..Default::default()
        };
        let variants = [
            ForecasterConfig {
                dct: true,
                ..base.clone()
            },
            ForecasterConfig {
                temp_mlp: 0,
                ..base.clone()
            },
            ForecasterConfig {
                interleaved: false,
                ..base.clone()
            },
            ForecasterConfig {
                rounds: 0,
                ..base.clone()
            },
            ForecasterConfig {
                displacement: false,
                ..base.clone()
            },
        ];
        let obs = Tensor::randn(0f32, 1.0, (2, 2, base.obs, FEATURES), &dev).unwrap();
        let last = obs.narrow(2, base.obs - 1, 1).unwrap();
        for cfg in variants {
            let vm = VarMap::new();
            let m = Forecaster::new(cfg.clone(), VarBuilder::from_varmap(&vm, DType::F32, &dev))
                .unwrap();
            let (soc, ind) = m.forward_both(&obs, None).unwrap();
            assert_eq!(soc.dims(), &[2, 2, cfg.pred, FEATURES]);
            assert_eq!(ind.dims(), soc.dims());
            let off = soc
                .broadcast_sub(&last)
                .unwrap()
                .abs()
                .unwrap()
                .max_all()
                .unwrap()
                .to_scalar::<f32>()
                .unwrap();
            // Displacement variants (DCT included: Dᵀ·0 = 0) start as "repeat the last frame".
            assert_eq!(off < 1e-5, cfg.displacement, "{cfg:?}: {off}");
        }
        // Wrong input sizes are an error, not a panic.
        let vm = VarMap::new();
        let m =
            Forecaster::new(base.clone(), VarBuilder::from_varmap(&vm, DType::F32, &dev)).unwrap();
        let bad = Tensor::zeros((1, 2, base.obs - 1, FEATURES), DType::F32, &dev).unwrap();
        assert!(m.forward(&bad, None).is_err());
    }

    #[test]
    fn identity_social_init_starts_as_the_single_agent_model() {
        let dev = Device::Cpu;
        let obs = Tensor::randn(0f32, 1.0, (2, 2, 8, FEATURES), &dev).unwrap();
        for identity in [true, false] {
            let cfg = ForecasterConfig {
                d_model: 16,
                heads: 2,
                social_identity_init: identity,
                ..Default::default()
            };
            let vm = VarMap::new();
            let m = Forecaster::new(cfg, VarBuilder::from_varmap(&vm, DType::F32, &dev)).unwrap();
            // Untrained decoders output zero either way: give them weights so the features
            // they decode show.
            for (name, var) in vm.data().lock().unwrap().iter() {
                if name.starts_with("decode_") && name.ends_with("fc2.weight") {
                    let r = Tensor::randn(0f32, 1.0, var.dims(), &dev).unwrap();
                    var.set(&r).unwrap();
                }
            }
            let (soc, ind) = m.forward_both(&obs, None).unwrap();
            let diff = (soc - ind)
                .unwrap()
                .abs()
                .unwrap()
                .max_all()
                .unwrap()
                .to_scalar::<f32>()
                .unwrap();
            // Identity: the social forecast is the individual one; random: the partner shows.
            assert_eq!(diff < 1e-6, identity, "identity {identity}: {diff}");
        }
    }

    #[test]
    fn dct_matrix_is_orthonormal() {
        let d = dct_matrix(31, &Device::Cpu).unwrap();
        let i = d.matmul(&d.t().unwrap()).unwrap().to_vec2::<f32>().unwrap();
        for (r, row) in i.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                let want = if r == c { 1.0 } else { 0.0 };
                assert!((v - want).abs() < 1e-5);
            }
        }
    }

    #[test]
    fn joint_positions_match_the_feature_decoder_and_losses_vanish_on_truth() {
        use crate::features::{decode, encode, Canonical};
        use echo_motion::synth::{generate, Split};
        let clip = generate(&Split::Test.clip(5));
        let c = Canonical::of(&clip.joints(30, 0));
        let mut feats = vec![];
        for p in 0..2 {
            for f in 30..33 {
                feats.extend_from_slice(&encode(&c, &clip.joints(f, p)));
            }
        }
        let x = Tensor::from_vec(feats.clone(), (1, 2, 3, FEATURES), &Device::Cpu).unwrap();
        let p = joint_positions(&x)
            .unwrap()
            .flatten_all()
            .unwrap()
            .to_vec1::<f32>()
            .unwrap();
        for (k, f) in feats.chunks(FEATURES).enumerate() {
            // decode() gives world coordinates, joint_positions() window-frame ones.
            let want = decode(&c, f);
            let got: Vec<nalgebra::Vector3<f64>> = (0..echo_motion::skeleton::NUM_JOINTS)
                .map(|j| {
                    let o = (k * echo_motion::skeleton::NUM_JOINTS + j) * 3;
                    nalgebra::Vector3::new(p[o] as f64, p[o + 1] as f64, p[o + 2] as f64)
                })
                .collect();
            for j in 0..echo_motion::skeleton::NUM_JOINTS {
                let w = c.world_to_window(&want[j]);
                assert!((got[j] - w).norm() < 1e-4, "joint {j}: {} vs {}", got[j], w);
            }
        }
        assert!(
            interaction_loss(&x, &x)
                .unwrap()
                .to_scalar::<f32>()
                .unwrap()
                < 1e-10
        );
        assert!(bone_loss(&x, &x).unwrap().to_scalar::<f32>().unwrap() < 1e-10);
        let y = (&x * 1.1).unwrap();
        assert!(bone_loss(&y, &x).unwrap().to_scalar::<f32>().unwrap() > 1e-6);
    }
}
