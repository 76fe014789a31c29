//! Online forecasting for the forecaster service, independent of the network:
//!
//! - [`contact`]: contact interactions (handshake, handover, high five) — a learned plan that
//!   brings a gripper near the partner's forecast hand is refined by inverse kinematics so the
//!   gripper reaches the hand;
//! - [`gesture`]: waving back — the oscillation a regressed forecast averages out, added to the
//!   arm the learned plan raises;
//! - [`failover`]: which of a primary and its standbys serves a robot (lowest live rank);
//! - [`history`]: a per-robot ring buffer of both agents at the model rate; short gaps are
//!   filled by interpolation (and counted), long gaps or reordered frames reset or are rejected;
//! - [`proxy`]: the robot as the second agent — its kinematic points (FK from the URDF) laid on
//!   the 22-joint skeleton, so a human-human model sees where the robot's hands and head are;
//! - [`server`]: agent pairing per robot, prompts (embedded once, cached), and one batched
//!   forward pass for every robot whose history advanced, producing [`echo_msgs::Forecast`]s.

pub mod contact;
pub mod failover;
pub mod gesture;
pub mod history;
pub mod proxy;
pub mod server;

pub use history::{History, HistoryError, Push};
pub use proxy::RobotProxy;
pub use server::{ForecastServer, ServeError, ServerConfig};
