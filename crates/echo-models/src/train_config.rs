//! The record of how a checkpoint was trained: the training settings stored in its metadata
//! (the training loop that reads them lives in `echo-train`).

use serde::{Deserialize, Serialize};

/// Training settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// Training clips (types cycle).
    pub train_clips: u64,
    /// Validation clips.
    pub val_clips: u64,
    /// Window stride, frames at 15 Hz.
    pub stride: usize,
    /// Batch size.
    pub batch: usize,
    /// Peak learning rate.
    pub lr: f64,
    /// Warm-up steps.
    pub warmup: usize,
    /// Learning-rate decay per epoch after warm-up.
    pub decay: f64,
    /// Epochs at most.
    pub epochs: usize,
    /// Stop after this many epochs without validation improvement.
    pub patience: usize,
    /// Wall-clock budget of this run, minutes (a resumed run gets the budget again).
    pub max_minutes: f64,
    /// Global gradient-norm clip.
    pub clip_grad: f64,
    /// Weight of the social loss L_soc.
    pub w_soc: f64,
    /// Weight of the individual loss L_self (0: the "w/o L_ind" ablation).
    pub w_self: f64,
    /// Weight of the interaction (distance-matrix) loss.
    pub w_interaction: f64,
    /// Weight of the bone-length loss.
    pub w_bone: f64,
    /// Seed (shuffling, prompt choice).
    pub seed: u64,
    /// The data spec trained on (`echo-data`; None: the generator's splits).
    pub data: Option<String>,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            train_clips: 2600,
            val_clips: 130,
            stride: 3,
            batch: 64,
            lr: 1e-3,
            warmup: 200,
            decay: 0.9,
            epochs: 30,
            patience: 4,
            max_minutes: 15.0,
            clip_grad: 1.0,
            w_soc: 1.0,
            w_self: 1.0,
            w_interaction: 0.1,
            w_bone: 0.1,
            seed: 1,
            data: None,
        }
    }
}
