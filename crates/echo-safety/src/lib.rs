//! Echo's safety filter: the only path from a plan to the robot.
//!
//! * [`joint`]: one joint's jerk-limited motion, the braking law and the feasible-stop check.
//! * [`filter`]: group-coordinated tracking of a reference under every limit, with the invariant
//!   that a jerk-bounded stop inside the position limits always exists; rollouts that end at rest.
//! * [`measured`]: the measured joint state's source lock and plausibility rules (sensor faults).
//! * [`plan`]: plan validation and the reference a plan gives at a time on the receiver's clock.
//! * [`separation`]: human capsules and speed-and-separation monitoring (ISO/TS 15066 style).
//! * [`supervisor`]: watchdogs, e-stop latch, liveliness, modes, and the command and status per
//!   control cycle.
//!
//! docs/SAFETY.md states every rule with its parameters.

pub mod config;
pub mod filter;
pub mod joint;
pub mod measured;
pub mod plan;
pub mod separation;
pub mod supervisor;

pub mod bench_support;

pub use config::SafetyConfig;
pub use supervisor::{Supervisor, Tick};
