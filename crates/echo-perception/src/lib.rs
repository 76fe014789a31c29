//! The perception bridge's logic, free of any network: keypoints from an external pose
//! estimator in, tracked 22-joint skeletons in `base_footprint` out.
//!
//! Per input frame: reject stale / reordered / unusable frames → map the estimator's joints onto
//! SMPL-22 ([`joint_map`]) → lift pixels + depth to 3D ([`lift`]) → camera → `base_footprint` with
//! the head/torso joint state at the capture time ([`camera`]) → associate with tracks, reject
//! implausible bones and teleports, fill short gaps, smooth with a One-Euro filter ([`tracker`],
//! [`one_euro`]) → at every tick of the model-rate grid, interpolate each track, compute root,
//! heading, local positions and local rotations, and pick the partner ([`bridge`]).

pub mod bridge;
pub mod camera;
pub mod config;
pub mod joint_map;
pub mod lift;
pub mod one_euro;
pub mod tracker;

pub use bridge::{BridgeError, PerceptionBridge};
pub use config::BridgeConfig;
