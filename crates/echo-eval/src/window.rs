//! Windows cut from interactions at the model rate, and the predictor interface.
//!
//! At 15 Hz: observe 8 frames (0.53 s, the last observed frame at t = 0), predict 23
//! (1.53 s). The reported horizons 0.2 / 0.5 / 1.0 / 1.5 s are future frames
//! round(h·15) = 3 / 8 / 15 / 23.

use echo_motion::synth::{Clip, FPS};
use echo_msgs::Interaction;
use nalgebra::Vector3;

use crate::metrics::Frame;

/// Model rate, Hz.
pub const RATE_HZ: f64 = 15.0;
/// Observed frames.
pub const OBS_FRAMES: usize = 8;
/// Predicted frames.
pub const PRED_FRAMES: usize = 23;
/// Reported horizons, seconds.
pub const HORIZONS_S: [f64; 4] = [0.2, 0.5, 1.0, 1.5];

/// Future frame index (1-based) of a horizon.
pub fn horizon_frame(h: f64) -> usize {
    (h * RATE_HZ).round() as usize
}

/// One evaluation window.
#[derive(Debug, Clone)]
pub struct Window {
    /// Interaction type.
    pub kind: Interaction,
    /// Descriptions of the clip.
    pub texts: Vec<String>,
    /// Observed frames (both agents).
    pub obs: Vec<Frame>,
    /// True future frames.
    pub future: Vec<Frame>,
    /// Clip seed and start frame (for reproducibility).
    pub origin: (u64, usize),
}

/// Cut windows from a clip: resample to 15 Hz, start every `stride` frames.
pub fn windows(clip: &Clip, stride: usize) -> Vec<Window> {
    let step = (FPS / RATE_HZ).round() as usize;
    let frames: Vec<Frame> = (0..clip.frames.len())
        .step_by(step.max(1))
        .map(|f| (0..2).map(|p| clip.joints(f, p)).collect())
        .collect();
    let need = OBS_FRAMES + PRED_FRAMES;
    let mut out = vec![];
    let mut s = 0;
    while s + need <= frames.len() {
        out.push(Window {
            kind: clip.params.kind,
            texts: clip.texts.clone(),
            obs: frames[s..s + OBS_FRAMES].to_vec(),
            future: frames[s + OBS_FRAMES..s + need].to_vec(),
            origin: (clip.params.seed, s),
        });
        s += stride.max(1);
    }
    out
}

/// Anything that forecasts both agents from an observed window.
pub trait Predictor {
    /// Name in tables.
    fn name(&self) -> String;
    /// Predict `PRED_FRAMES` future frames for each window (batched: learned models run one
    /// forward pass per call).
    fn predict(&mut self, batch: &[&Window]) -> Vec<Vec<Frame>>;
}

/// Repeats the last observed frame.
#[derive(Debug, Default)]
pub struct ZeroVelocity;

impl Predictor for ZeroVelocity {
    fn name(&self) -> String {
        "zero-velocity".into()
    }

    fn predict(&mut self, batch: &[&Window]) -> Vec<Vec<Frame>> {
        batch
            .iter()
            .map(|w| vec![w.obs[w.obs.len() - 1].clone(); PRED_FRAMES])
            .collect()
    }
}

/// Extrapolates every joint with its last observed velocity.
#[derive(Debug, Default)]
pub struct ConstantVelocity;

impl Predictor for ConstantVelocity {
    fn name(&self) -> String {
        "constant-velocity".into()
    }

    fn predict(&mut self, batch: &[&Window]) -> Vec<Vec<Frame>> {
        batch
            .iter()
            .map(|w| {
                let last = &w.obs[w.obs.len() - 1];
                let prev = &w.obs[w.obs.len() - 2];
                (1..=PRED_FRAMES)
                    .map(|k| {
                        last.iter()
                            .zip(prev)
                            .map(|(l, p)| {
                                let mut f = [Vector3::zeros(); 22];
                                for j in 0..22 {
                                    f[j] = l[j] + (l[j] - p[j]) * k as f64;
                                }
                                f
                            })
                            .collect()
                    })
                    .collect()
            })
            .collect()
    }
}

/// Extrapolates every joint with its last observed velocity, decaying with time constant
/// `tau_s`: frame k moves by `v·Σ_{i=1..k} r^i`, `r = exp(−1/(τ·15 Hz))` — between zero velocity
/// (τ → 0) and constant velocity (τ → ∞). Real people carry momentum but do not keep it for
/// long; this is also the prior a forecaster with `velocity_prior_s` adds its output to.
#[derive(Debug, Clone, Copy)]
pub struct DampedVelocity {
    /// Time constant of the decay, s.
    pub tau_s: f64,
}

impl Predictor for DampedVelocity {
    fn name(&self) -> String {
        format!("damped-velocity-{:.2}s", self.tau_s)
    }

    fn predict(&mut self, batch: &[&Window]) -> Vec<Vec<Frame>> {
        let r = (-1.0 / (self.tau_s.max(1e-6) * RATE_HZ)).exp();
        let gains: Vec<f64> = (1..=PRED_FRAMES)
            .scan(0.0, |acc, k| {
                *acc += r.powi(k as i32);
                Some(*acc)
            })
            .collect();
        batch
            .iter()
            .map(|w| {
                let last = &w.obs[w.obs.len() - 1];
                let prev = &w.obs[w.obs.len() - 2];
                gains
                    .iter()
                    .map(|g| {
                        last.iter()
                            .zip(prev)
                            .map(|(l, p)| std::array::from_fn(|j| l[j] + (l[j] - p[j]) * *g))
                            .collect()
                    })
                    .collect()
            })
            .collect()
    }
}

#[cfg(test)]
mod damped_tests {
    use super::*;

    #[test]
    fn damped_velocity_lies_between_zero_and_constant_velocity() {
        let f = |x: f64| vec![[Vector3::new(x, 0.0, 1.0); 22]; 2];
        let w = Window {
            kind: echo_msgs::Interaction::Idle,
            texts: vec![],
            obs: (0..OBS_FRAMES).map(|k| f(k as f64 * 0.1)).collect(),
            future: vec![f(0.0); PRED_FRAMES],
            origin: (0, 0),
        };
        let cv = ConstantVelocity.predict(&[&w]);
        let dv = DampedVelocity { tau_s: 0.5 }.predict(&[&w]);
        let last = 0.1 * (OBS_FRAMES - 1) as f64;
        for k in 0..PRED_FRAMES {
            let (c, d) = (cv[0][k][0][0].x, dv[0][k][0][0].x);
            assert!(d > last && d < c + 1e-12, "frame {k}: {d} vs {c}");
        }
        // The first step is nearly the constant-velocity one; the total stays bounded by v·τ·15.
        assert!((dv[0][0][0][0].x - last - 0.1 * (-1.0f64 / 7.5).exp()).abs() < 1e-9);
        assert!(dv[0][PRED_FRAMES - 1][0][0].x - last < 0.1 * 7.5);
    }
}
