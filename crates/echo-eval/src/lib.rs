//! Evaluation: metrics as the multi-person forecasting benchmarks compute them, windows cut
//! from interactions, a [`Predictor`] trait that every forecaster implements, the zero- and
//! constant-velocity baselines, and a harness that prints the paper-style table.

pub mod behaviour;
pub mod harness;
pub mod live;
pub mod metrics;
pub mod render;
pub mod symmetry;
pub mod window;

pub use harness::{evaluate, Report};
pub use symmetry::Symmetrized;
pub use window::{
    windows, DampedVelocity, Predictor, Window, HORIZONS_S, OBS_FRAMES, PRED_FRAMES, RATE_HZ,
};
