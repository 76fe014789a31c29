//! The dual-agent social forecaster in candle, as served: window features, the model,
//! checkpoints and the inference backends. Training and the evaluation predictor are in
//! `echo-train`.

pub mod backend;
pub mod checkpoint;
pub mod features;
pub mod model;
pub mod ops;
pub mod robot_agent;
pub mod threads;
pub mod train_config;

pub use backend::{disagreement, Backend, CandleBackend, ZeroVelocityBackend, PARITY_TOLERANCE};
pub use checkpoint::{Checkpoint, CheckpointMeta};
pub use train_config::TrainConfig;
