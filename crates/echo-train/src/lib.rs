//! Training the dual-agent forecaster and scoring it: the training loop (resumable, with its
//! own AdamW), and [`ModelPredictor`], an [`echo_eval::Predictor`] over a model so the
//! evaluation harness scores it like any baseline. Serving needs none of this (`echo-models`).

pub mod optim;
pub mod predictor;
pub mod train;

pub use predictor::{encode_observed, CheckpointPredictor, ModelPredictor};
