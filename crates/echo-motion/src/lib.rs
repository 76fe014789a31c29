//! Human motion: the 22-joint SMPL body skeleton, rotation conversions, forward and inverse
//! kinematics, and scripted single-person motions used by the mock perception publisher.
//!
//! World convention: REP-103, z up, metres.

pub mod bvh;
pub mod capture;
pub mod dataset;
pub mod intergen;
pub mod params;
pub mod posing;
pub mod rotation;
pub mod scripted;
pub mod sensors;
pub mod skeleton;
pub mod splits;
pub mod symmetry;
pub mod synth;
pub mod text;

pub use skeleton::{Body, Pose, NUM_JOINTS, PARENTS};
