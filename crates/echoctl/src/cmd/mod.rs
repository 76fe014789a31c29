//! One module per `echoctl` verb.

pub mod bench;
pub mod bench_camera;
pub mod bench_sizes;
pub mod data;
pub mod demo;
pub mod eval;
pub mod export;
pub mod fleet;
pub mod list;
pub mod mock_perception;
pub mod mock_robot;
pub mod monitor;
pub mod prompt;
pub mod record;
pub mod router;
pub mod scene;
pub mod soak;
pub mod train;
pub mod up;
