//! Inference backends: anything that maps observed features (and prompt embeddings) of a batch
//! of windows to forecast features. The candle model is one; the ONNX Runtime session is another.

use candle_core::{Device, Tensor};

use crate::checkpoint::Checkpoint;
use crate::model::ForecasterConfig;

/// A forecaster at inference time.
pub trait Backend: Send {
    /// Name for logs and status ("candle-cpu", "onnxruntime", …).
    fn name(&self) -> String;
    /// The architecture it runs (sizes of inputs and outputs).
    fn config(&self) -> &ForecasterConfig;
    /// `obs`: per window, agent A's obs × F_a values then agent B's obs × F_b (for two people
    /// that is b × 2 × obs × 73); `text`: b × text_dim values (empty when the model reads no
    /// text). Returns per window A's pred × F_a values then B's pred × F_b.
    fn predict(&mut self, b: usize, obs: &[f32], text: &[f32]) -> anyhow::Result<Vec<f32>>;
}

/// Check the sizes of a backend call.
pub fn check_sizes(
    cfg: &ForecasterConfig,
    b: usize,
    obs: &[f32],
    text: &[f32],
) -> anyhow::Result<()> {
    let per = cfg.obs * (cfg.agent_features[0] + cfg.agent_features[1]);
    anyhow::ensure!(
        obs.len() == b * per,
        "observed features: {} values for a batch of {b}, expected {}",
        obs.len(),
        b * per
    );
    anyhow::ensure!(
        text.len() == b * cfg.text_dim,
        "text embeddings: {} values for a batch of {b}, expected {}",
        text.len(),
        b * cfg.text_dim
    );
    Ok(())
}

/// The candle model of a checkpoint.
pub struct CandleBackend {
    ck: Checkpoint,
    dev: Device,
}

impl CandleBackend {
    /// Wrap a loaded checkpoint.
    pub fn new(ck: Checkpoint, dev: Device) -> Self {
        CandleBackend { ck, dev }
    }

    /// The checkpoint (its sentence encoder, metadata).
    pub fn checkpoint(&self) -> &Checkpoint {
        &self.ck
    }
}

impl Backend for CandleBackend {
    fn name(&self) -> String {
        match &self.dev {
            Device::Cpu => "candle-cpu".into(),
            d => format!("candle-{d:?}").to_lowercase(),
        }
    }

    fn config(&self) -> &ForecasterConfig {
        self.ck.model.config()
    }

    fn predict(&mut self, b: usize, obs: &[f32], text: &[f32]) -> anyhow::Result<Vec<f32>> {
        let cfg = self.ck.model.config().clone();
        check_sizes(&cfg, b, obs, text)?;
        let t = if cfg.text_dim > 0 {
            Some(Tensor::from_slice(text, (b, cfg.text_dim), &self.dev)?)
        } else {
            None
        };
        let [fa, fb] = cfg.agent_features;
        let x = Tensor::from_slice(obs, (b, cfg.obs * (fa + fb)), &self.dev)?;
        let xa = x.narrow(1, 0, cfg.obs * fa)?.reshape((b, cfg.obs, fa))?;
        let xb = x
            .narrow(1, cfg.obs * fa, cfg.obs * fb)?
            .reshape((b, cfg.obs, fb))?;
        let [ya, yb] = self.ck.model.forward_social(&xa, &xb, t.as_ref())?;
        let y = Tensor::cat(&[ya.flatten_from(1)?, yb.flatten_from(1)?], 1)?;
        Ok(y.flatten_all()?.to_vec1::<f32>()?)
    }
}

/// Largest difference two backends may have on the same inputs to count as the same model
/// (0.1 mm in the metre-scale features).
pub const PARITY_TOLERANCE: f32 = 1e-4;

/// Largest absolute difference between two backends' outputs on one deterministic batch of `b`
/// windows (observed features uniform in ±1, prompt embeddings in ±0.1): the start-up check
/// that a faster backend runs the same model. Errors when either fails or their shapes differ.
pub fn disagreement(a: &mut dyn Backend, other: &mut dyn Backend, b: usize) -> anyhow::Result<f32> {
    use rand::{Rng, SeedableRng};
    let cfg = a.config().clone();
    anyhow::ensure!(
        other.config().agent_features == cfg.agent_features
            && other.config().obs == cfg.obs
            && other.config().pred == cfg.pred
            && other.config().text_dim == cfg.text_dim,
        "the backends run differently shaped models"
    );
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let per = cfg.obs * (cfg.agent_features[0] + cfg.agent_features[1]);
    let obs: Vec<f32> = (0..b * per).map(|_| rng.random_range(-1.0..1.0)).collect();
    let text: Vec<f32> = (0..b * cfg.text_dim)
        .map(|_| rng.random_range(-0.1..0.1))
        .collect();
    let (x, y) = (a.predict(b, &obs, &text)?, other.predict(b, &obs, &text)?);
    anyhow::ensure!(
        x.len() == y.len(),
        "{} against {} outputs",
        x.len(),
        y.len()
    );
    Ok(x.iter()
        .zip(&y)
        .map(|(p, q)| (p - q).abs())
        .fold(
            0.0,
            |m: f32, d| if d.is_nan() { f32::INFINITY } else { m.max(d) },
        ))
}

/// The zero-velocity forecaster as a backend: every future frame is the last observed one.
/// A baseline to serve side by side with a model, and a model-free backend for tests.
pub struct ZeroVelocityBackend {
    cfg: ForecasterConfig,
}

impl ZeroVelocityBackend {
    /// Shaped like `cfg` (observed and predicted frames; reads no text).
    pub fn new(cfg: ForecasterConfig) -> Self {
        ZeroVelocityBackend {
            cfg: ForecasterConfig { text_dim: 0, ..cfg },
        }
    }
}

impl Backend for ZeroVelocityBackend {
    fn name(&self) -> String {
        "zero-velocity".into()
    }

    fn config(&self) -> &ForecasterConfig {
        &self.cfg
    }

    fn predict(&mut self, b: usize, obs: &[f32], text: &[f32]) -> anyhow::Result<Vec<f32>> {
        check_sizes(&self.cfg, b, obs, text)?;
        let (n, p) = (self.cfg.obs, self.cfg.pred);
        let [fa, fb] = self.cfg.agent_features;
        let mut out = Vec::with_capacity(b * p * (fa + fb));
        for i in 0..b {
            let w = i * n * (fa + fb);
            for (start, f) in [(w, fa), (w + n * fa, fb)] {
                let o = start + (n - 1) * f;
                for _ in 0..p {
                    out.extend_from_slice(&obs[o..o + f]);
                }
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Zero velocity, off by `by` everywhere.
    struct Off(ZeroVelocityBackend, f32);

    impl Backend for Off {
        fn name(&self) -> String {
            "off".into()
        }
        fn config(&self) -> &ForecasterConfig {
            self.0.config()
        }
        fn predict(&mut self, b: usize, obs: &[f32], text: &[f32]) -> anyhow::Result<Vec<f32>> {
            Ok(self
                .0
                .predict(b, obs, text)?
                .iter()
                .map(|x| x + self.1)
                .collect())
        }
    }

    #[test]
    fn disagreement_measures_the_largest_output_difference() {
        let cfg = ForecasterConfig::default();
        let mut zv = ZeroVelocityBackend::new(cfg.clone());
        let mut same = Off(ZeroVelocityBackend::new(cfg.clone()), 0.0);
        assert_eq!(disagreement(&mut zv, &mut same, 3).unwrap(), 0.0);
        let mut off = Off(ZeroVelocityBackend::new(cfg.clone()), 2e-3);
        let d = disagreement(&mut zv, &mut off, 3).unwrap();
        assert!((d - 2e-3).abs() < 1e-6 && d > PARITY_TOLERANCE, "{d}");
        let mut nan = Off(ZeroVelocityBackend::new(cfg.clone()), f32::NAN);
        assert_eq!(disagreement(&mut zv, &mut nan, 1).unwrap(), f32::INFINITY);
        let mut other = ZeroVelocityBackend::new(ForecasterConfig { pred: 5, ..cfg });
        assert!(disagreement(&mut zv, &mut other, 1).is_err());
    }
}
