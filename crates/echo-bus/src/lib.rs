//! Echo's Zenoh bus.
//!
//! * [`keys`]: every key expression, one function each, namespaced per robot.
//! * [`topics`]: each edge of the data flow as a typed [`Topic`] (key + message type + delivery policy).
//! * [`config`]: opening a Zenoh session from a config file, CLI flags or the environment.
//! * [`Bus`]: typed publishers and inboxes; decode errors are counted in [`Stats`] and logged, never panics.
//! * [`ingress`]: the decode → validate → sequence check step, usable without a network.
//! * [`liveliness`]: service liveliness tokens and watchers.
//! * [`shutdown`]: SIGINT/SIGTERM handling.
//! * [`testkit`]: free ports, loopback configs and timeouts for tests.

pub mod config;
pub mod inbox;
pub mod ingress;
pub mod keys;
pub mod liveliness;
pub mod observer;
pub mod shutdown;
pub mod stats;
pub mod telemetry;
pub mod testkit;
pub mod topics;

mod bus;

pub use bus::{Bus, Publisher};
pub use config::BusArgs;
pub use inbox::{Inbox, Received};
pub use ingress::{Ingress, Rejection};
pub use keys::RobotId;
pub use stats::Stats;
pub use topics::{Delivery, Topic};
