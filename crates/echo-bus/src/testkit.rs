//! Test helpers: free loopback ports, loopback session flags, and a timeout around awaits
//! so no test relies on multicast or can hang.

use std::future::Future;
use std::time::Duration;

pub use crate::config::{free_port, free_ports, loopback_mesh};

/// Await `f` for at most `secs` seconds; panics with `what` on timeout (tests only).
pub async fn within<F: Future>(secs: f64, what: &str, f: F) -> F::Output {
    match tokio::time::timeout(Duration::from_secs_f64(secs), f).await {
        Ok(v) => v,
        Err(_) => panic!("timed out after {secs} s waiting for {what}"),
    }
}
