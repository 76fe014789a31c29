//! The forecaster as an evaluation [`Predictor`], and windows as the backends' input.

use candle_core::{Device, Tensor};
use echo_eval::metrics::Frame;
use echo_eval::{Predictor, Window};
use echo_models::features::{decode, encode_frames, Canonical, FEATURES};
use echo_models::model::Forecaster;
use echo_models::Checkpoint;
use echo_text::SentenceEncoder;

/// Observed features of windows in the backends' layout (per window: A's frames, then B's),
/// using each window's last `obs` frames, and the window frames used.
pub fn encode_observed(ws: &[&Window], obs: usize) -> (Vec<Canonical>, Vec<f32>) {
    let mut canon = Vec::with_capacity(ws.len());
    let mut data = Vec::with_capacity(ws.len() * 2 * obs * FEATURES);
    for w in ws {
        let (c, agents) = encode_frames(&w.obs[w.obs.len() - obs..]);
        for a in &agents {
            for f in a {
                data.extend_from_slice(f);
            }
        }
        canon.push(c);
    }
    (canon, data)
}

/// A checkpoint as an evaluation predictor.
pub trait CheckpointPredictor {
    /// A predictor over this checkpoint, named `name` in tables.
    fn predictor(&self, name: &str) -> ModelPredictor<'_>;
}

impl CheckpointPredictor for Checkpoint {
    fn predictor(&self, name: &str) -> ModelPredictor<'_> {
        ModelPredictor::new(&self.model, self.device().clone(), name, self.text.as_ref())
    }
}

/// A borrowed model that predicts windows in batches (a window's first description is its
/// prompt when the model reads text).
pub struct ModelPredictor<'a> {
    model: &'a Forecaster,
    dev: Device,
    name: String,
    text: Option<&'a SentenceEncoder>,
}

impl<'a> ModelPredictor<'a> {
    /// Wrap a model; `text` is needed when the model has a text token.
    pub fn new(
        model: &'a Forecaster,
        dev: Device,
        name: &str,
        text: Option<&'a SentenceEncoder>,
    ) -> Self {
        ModelPredictor {
            model,
            dev,
            name: name.to_string(),
            text,
        }
    }

    fn prompts(&self, batch: &[&Window]) -> Option<Tensor> {
        let cfg = self.model.config();
        let enc = self.text.filter(|_| cfg.text_dim > 0)?;
        let texts: Vec<&str> = batch
            .iter()
            .map(|w| w.texts.first().map(|s| s.as_str()).unwrap_or(""))
            .collect();
        let v = enc.embed(&texts).ok()?;
        Tensor::from_vec(v.concat(), (batch.len(), enc.dim()), &self.dev).ok()
    }
}

impl Predictor for ModelPredictor<'_> {
    fn name(&self) -> String {
        self.name.clone()
    }

    fn predict(&mut self, batch: &[&Window]) -> Vec<Vec<Frame>> {
        let cfg = self.model.config();
        let (canon, data) = encode_observed(batch, cfg.obs);
        let text = self.prompts(batch);
        let out = Tensor::from_vec(data, (batch.len(), 2, cfg.obs, FEATURES), &self.dev)
            .and_then(|x| self.model.forward(&x, text.as_ref()))
            .and_then(|y| y.flatten_all()?.to_vec1::<f32>());
        let Ok(v) = out else {
            // A model failure must not look like a prediction: hold the last frame.
            return batch
                .iter()
                .map(|w| vec![w.obs[w.obs.len() - 1].clone(); cfg.pred])
                .collect();
        };
        let per = 2 * cfg.pred * FEATURES;
        canon
            .iter()
            .enumerate()
            .map(|(i, c)| {
                (0..cfg.pred)
                    .map(|k| {
                        (0..2)
                            .map(|a| {
                                let o = i * per + (a * cfg.pred + k) * FEATURES;
                                decode(c, &v[o..o + FEATURES])
                            })
                            .collect()
                    })
                    .collect()
            })
            .collect()
    }
}
