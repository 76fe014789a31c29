//! Test helpers: free loopback ports, loopback session flags, and a timeout around awaits
//! so no test relies on multicast or can hang.

use std::future::Future;
use std::time::Duration;

use crate::BusArgs;

/// A TCP port free on 127.0.0.1 right now.
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("binding an ephemeral loopback port")
}

/// `n` free ports, all distinct.
pub fn free_ports(n: usize) -> Vec<u16> {
    let listeners: Vec<_> = (0..n)
        .map(|_| std::net::TcpListener::bind("127.0.0.1:0").expect("binding an ephemeral port"))
        .collect();
    listeners
        .iter()
        .map(|l| l.local_addr().expect("local addr").port())
        .collect()
}

/// Flags for `n` peers on loopback forming a full mesh (each listens on its own port and
/// connects to every other one), multicast scouting off.
pub fn loopback_mesh(robot: &str, n: usize) -> Vec<BusArgs> {
    let ports = free_ports(n);
    (0..n)
        .map(|i| {
            let others: Vec<u16> = ports
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, p)| *p)
                .collect();
            BusArgs::loopback(robot, &[ports[i]], &others)
        })
        .collect()
}

/// Await `f` for at most `secs` seconds; panics with `what` on timeout (tests only).
pub async fn within<F: Future>(secs: f64, what: &str, f: F) -> F::Output {
    match tokio::time::timeout(Duration::from_secs_f64(secs), f).await {
        Ok(v) => v,
        Err(_) => panic!("timed out after {secs} s waiting for {what}"),
    }
}
