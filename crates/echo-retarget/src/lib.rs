//! Human-to-robot retargeting for TIAGo++ (ImitationNet, Humanoids 2023, as the paper uses it):
//!
//! - [`human`]: what is read from a skeleton — swing rotations of shoulders and elbows, limb
//!   directions — in a body frame from the shoulders;
//! - [`net`]: human encoder, robot encoder and robot decoder sharing a latent space; outputs
//!   inside the joint limits by construction;
//! - [`fk`]: differentiable batched forward kinematics from the URDF;
//! - [`train`] and [`eval`]: unpaired training (triplet, reconstruction, latent consistency,
//!   limb-direction losses) and the limb-angle evaluation;
//! - [`retargeter`]: the run-time retargeter with the head and torso rules;
//! - [`hri`]: human–human clips → human–robot clips (B becomes the robot) and their social
//!   agreement with the original pair;
//! - [`imitation`]: live imitation plans (mirrored partner → robot plan from the measured state).

pub mod eval;
pub mod fk;
pub mod hri;
pub mod human;
pub mod imitation;
pub mod net;
pub mod retargeter;
pub mod train;

pub use retargeter::{Retargeter, RetargeterMeta, RobotPose};
