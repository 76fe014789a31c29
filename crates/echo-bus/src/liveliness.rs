//! Watching which services are alive.

use std::collections::BTreeSet;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::{anyhow, Result};
use tokio::sync::Notify;
use zenoh::sample::SampleKind;

use crate::keys;

/// The live set of (robot, service) tokens matching a key, updated by a liveliness subscriber
/// (with history, so tokens declared before the watch are seen).
pub struct AliveWatch {
    alive: Arc<Mutex<BTreeSet<(String, String)>>>,
    changed: Arc<Notify>,
    _sub: zenoh::pubsub::Subscriber<()>,
}

impl AliveWatch {
    pub(crate) async fn declare(session: &zenoh::Session, key: &str) -> Result<AliveWatch> {
        let alive = Arc::new(Mutex::new(BTreeSet::new()));
        let changed = Arc::new(Notify::new());
        let (a, c) = (alive.clone(), changed.clone());
        let sub = session
            .liveliness()
            .declare_subscriber(key)
            .history(true)
            .callback(move |sample| {
                if let Some((r, s)) = keys::parse_alive(sample.key_expr().as_str()) {
                    let entry = (r.to_string(), s.to_string());
                    let mut set = a.lock().unwrap_or_else(|e| e.into_inner());
                    match sample.kind() {
                        SampleKind::Put => {
                            if set.insert(entry) {
                                tracing::info!(robot = r, service = s, "service alive");
                            }
                        }
                        SampleKind::Delete => {
                            if set.remove(&entry) {
                                tracing::warn!(robot = r, service = s, "service lost");
                            }
                        }
                    }
                    drop(set);
                    c.notify_waiters();
                }
            })
            .await
            .map_err(|e| anyhow!("liveliness subscriber on {key}: {e}"))?;
        Ok(AliveWatch {
            alive,
            changed,
            _sub: sub,
        })
    }

    /// Whether `service` of `robot` is alive now.
    pub fn is_alive(&self, robot: &str, service: &str) -> bool {
        self.alive
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .contains(&(robot.to_string(), service.to_string()))
    }

    /// Snapshot of the live set.
    pub fn snapshot(&self) -> Vec<(String, String)> {
        self.alive
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .iter()
            .cloned()
            .collect()
    }

    /// A future that completes at the next change of the live set.
    pub fn changed(&self) -> impl std::future::Future<Output = ()> + '_ {
        self.changed.notified()
    }

    /// Wait until every one of `services` of `robot` is alive, or `timeout` passes.
    /// Returns the services still missing.
    pub async fn wait_for(&self, robot: &str, services: &[&str], timeout: Duration) -> Vec<String> {
        let deadline = tokio::time::Instant::now() + timeout;
        loop {
            let notified = self.changed.notified();
            let missing: Vec<String> = services
                .iter()
                .filter(|s| !self.is_alive(robot, s))
                .map(|s| s.to_string())
                .collect();
            if missing.is_empty() || tokio::time::Instant::now() >= deadline {
                return missing;
            }
            let _ = tokio::time::timeout_at(deadline, notified).await;
        }
    }
}
