//! Echo's bus messages as a 3D scene, independent of any viewer.
//!
//! [`SceneBuilder::on_message`] takes bus messages (key + JSON payload) and keeps the latest of
//! each input: the people (`humans`), the forecast (`forecast`), the robot's measured joints
//! (`robot/state`), the safety filter (`safety/status`) and the announced interaction
//! (`prompt`). [`SceneBuilder::scene`] turns them into a [`Scene`]: spheres, capsules, line
//! strips and text with RGBA colours, in `base_footprint` (x forward, y left, z up, metres):
//!
//! * the partner in blue and other people in grey-blue, a capsule per bone;
//! * the partner's forecast as a fading ghost (later frames more transparent), and the robot's
//!   forecast plan the same way when the forecaster plans for it;
//! * the robot: echo-robot's collision capsules at the measured joints (forward kinematics of the
//!   project's URDF), grey body and base, orange arms;
//! * the head camera's field of view (the URDF's optical frame, else [`builder::fixed_camera_pose`]);
//! * the safety state as a coloured ring and label, and the closest robot–person distance as a
//!   line between the two closest capsule surface points.
//!
//! Viewers: [`render`] rasterises scenes from a fixed side view into an animated GIF
//! ([`render_recording`]); with the `foxglove` feature (default), [`foxglove`] writes MCAP files
//! Foxglove draws in 3D and serves scenes live over the Foxglove WebSocket protocol; with the
//! `web` feature (default), [`web`] serves a three.js page that follows the scenes in a browser.

pub mod builder;
mod font;
#[cfg(feature = "foxglove")]
pub mod foxglove;
pub mod geometry;
pub mod render;
pub mod scene;
pub mod style;
#[cfg(feature = "web")]
pub mod web;

pub use builder::{Input, InputStats, SceneBuilder, SceneOptions};
pub use render::{render_recording, CameraView, RenderOptions, RenderSummary};
pub use scene::{Caption, Entity, EntityKind, Primitive, Rgba, Scene};

/// Errors of scene building, rendering and conversion.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The robot description lacks what the scene needs.
    #[error("robot model: {0}")]
    Robot(echo_robot::RobotError),
    /// The recording could not be read.
    #[error(transparent)]
    Recording(#[from] echo_record::RecordingError),
    /// Writing an output file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Encoding the GIF failed.
    #[error("writing GIF {path}: {message}")]
    Gif {
        /// The file.
        path: std::path::PathBuf,
        /// What the encoder reported.
        message: String,
    },
    /// An option is out of range.
    #[error("invalid option {name}: {message}")]
    Option {
        /// The option.
        name: &'static str,
        /// What is wrong with it.
        message: String,
    },
    /// The recording has no messages.
    #[error("{0}: the recording has no messages")]
    Empty(std::path::PathBuf),
    /// MCAP output failed.
    #[cfg(feature = "foxglove")]
    #[error("writing MCAP: {0}")]
    Mcap(#[from] mcap::McapError),
    /// The browser viewer's server failed.
    #[cfg(feature = "web")]
    #[error("viewer server: {0}")]
    Web(String),
    /// The Foxglove SDK reported an error.
    #[cfg(feature = "foxglove")]
    #[error("foxglove: {0}")]
    Foxglove(String),
}
