//! Stand-ins for the world around Echo, free of any network:
//!
//! * [`perception::MockPerception`]: people following scripts, seen by the head camera as a pose
//!   estimator would report them (3D or pixels + depth keypoints, noise, dropped joints and
//!   frames, latency, a bystander).
//! * [`mission::Mission`]: the partner of a human–robot mission (walk up and shake hands, hand
//!   an object over, wave) and the interactions it performs, for the demo and system tests.
//! * [`robot::SimRobot`]: the TIAGo++ controllers — follows commanded joint trajectories with a
//!   first-order response within the velocity limits and reports joint states.

pub mod mission;
pub mod perception;
pub mod robot;
pub mod scenario;
