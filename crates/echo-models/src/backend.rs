//! Inference backends: anything that maps observed features (and prompt embeddings) of a batch
//! of windows to forecast features. The candle model is one; the ONNX Runtime session is another.

use candle_core::{Device, Tensor};

use crate::features::FEATURES;
use crate::model::ForecasterConfig;
use crate::predictor::Checkpoint;

/// A forecaster at inference time.
pub trait Backend: Send {
    /// Name for logs and status ("candle-cpu", "onnxruntime", …).
    fn name(&self) -> String;
    /// The architecture it runs (sizes of inputs and outputs).
    fn config(&self) -> &ForecasterConfig;
    /// `obs`: b × 2 × obs × FEATURES values; `text`: b × text_dim values (empty when the model
    /// reads no text). Returns b × 2 × pred × FEATURES values.
    fn predict(&mut self, b: usize, obs: &[f32], text: &[f32]) -> anyhow::Result<Vec<f32>>;
}

/// Check the sizes of a backend call.
pub fn check_sizes(
    cfg: &ForecasterConfig,
    b: usize,
    obs: &[f32],
    text: &[f32],
) -> anyhow::Result<()> {
    anyhow::ensure!(
        obs.len() == b * 2 * cfg.obs * FEATURES,
        "observed features: {} values for a batch of {b}, expected {}",
        obs.len(),
        b * 2 * cfg.obs * FEATURES
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
        let x = Tensor::from_slice(obs, (b, 2, cfg.obs, FEATURES), &self.dev)?;
        let t = if cfg.text_dim > 0 {
            Some(Tensor::from_slice(text, (b, cfg.text_dim), &self.dev)?)
        } else {
            None
        };
        Ok(self
            .ck
            .model
            .forward(&x, t.as_ref())?
            .flatten_all()?
            .to_vec1::<f32>()?)
    }
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
        let mut out = Vec::with_capacity(b * 2 * p * FEATURES);
        for ia in 0..2 * b {
            let o = (ia * n + n - 1) * FEATURES;
            for _ in 0..p {
                out.extend_from_slice(&obs[o..o + FEATURES]);
            }
        }
        Ok(out)
    }
}
