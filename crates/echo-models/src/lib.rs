//! The dual-agent social forecaster in candle: window features, the model, training, and a
//! [`echo_eval::Predictor`] so the evaluation harness scores it like any baseline.

pub mod backend;
pub mod checkpoint;
pub mod features;
pub mod model;
pub mod optim;
pub mod predictor;
pub mod robot_agent;
pub mod train;

pub use backend::{disagreement, Backend, CandleBackend, ZeroVelocityBackend, PARITY_TOLERANCE};
pub use checkpoint::{Checkpoint, CheckpointMeta};
pub use predictor::ModelPredictor;
