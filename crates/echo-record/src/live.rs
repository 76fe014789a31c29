//! Recording from and replaying onto a live Zenoh session.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;

use anyhow::{anyhow, Context, Result};
use echo_bus::shutdown::Shutdown;
use echo_msgs::now_ns;
use tokio::sync::mpsc;

use crate::{Recorded, Recorder};

/// Messages buffered between the subscribers and the file writer; beyond this the newest are
/// dropped and counted (the disk is slower than the bus).
pub const RECORD_QUEUE: usize = 65_536;

/// What a recording session wrote.
#[derive(Debug, Default, Clone)]
pub struct RecordSummary {
    /// Messages written, per key.
    pub per_key: BTreeMap<String, u64>,
    /// Messages dropped because the writer fell behind.
    pub dropped: u64,
}

impl RecordSummary {
    /// Messages written in total.
    pub fn total(&self) -> u64 {
        self.per_key.values().sum()
    }
}

/// Record every sample on `key_exprs` into the MCAP file `out` until `stop` triggers or
/// `duration` passes. Receive times are taken in the subscriber callback.
pub async fn record(
    session: &zenoh::Session,
    key_exprs: &[String],
    out: &Path,
    duration: Option<Duration>,
    mut stop: Shutdown,
) -> Result<RecordSummary> {
    let file = std::fs::File::create(out).with_context(|| format!("creating {}", out.display()))?;
    let mut recorder = Recorder::new(std::io::BufWriter::new(file))?;
    let (tx, mut rx) = mpsc::channel::<(String, u64, Vec<u8>)>(RECORD_QUEUE);
    let dropped = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
    let mut subs = vec![];
    for k in key_exprs {
        let (tx, dropped) = (tx.clone(), dropped.clone());
        let sub = session
            .declare_subscriber(k.as_str())
            .callback(move |s| {
                let item = (
                    s.key_expr().as_str().to_string(),
                    now_ns(),
                    s.payload().to_bytes().into_owned(),
                );
                if tx.try_send(item).is_err() {
                    dropped.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                }
            })
            .await
            .map_err(|e| anyhow!("subscribing to {k}: {e}"))?;
        subs.push(sub);
    }
    drop(tx);
    tracing::info!(keys = ?key_exprs, file = %out.display(), "recording");
    let mut summary = RecordSummary::default();
    let deadline = duration.map(|d| tokio::time::Instant::now() + d);
    loop {
        let until_deadline = async {
            match deadline {
                Some(d) => tokio::time::sleep_until(d).await,
                None => std::future::pending().await,
            }
        };
        tokio::select! {
            item = rx.recv() => match item {
                Some((key, t, payload)) => {
                    recorder.write(&key, t, &payload)?;
                    *summary.per_key.entry(key).or_insert(0) += 1;
                }
                None => break,
            },
            _ = stop.wait() => break,
            _ = until_deadline => break,
        }
    }
    for s in subs {
        let _ = s.undeclare().await;
    }
    while let Ok((key, t, payload)) = rx.try_recv() {
        recorder.write(&key, t, &payload)?;
        *summary.per_key.entry(key).or_insert(0) += 1;
    }
    recorder.finish()?;
    summary.dropped = dropped.load(std::sync::atomic::Ordering::Relaxed);
    Ok(summary)
}

/// How to play a recording back.
#[derive(Debug, Clone)]
pub struct ReplayOptions {
    /// Playback speed (1 = the original rate, 2 = twice as fast; 0 = as fast as possible).
    pub speed: f64,
    /// Rewrite `header.stamp_ns` to the replay time, so receivers that judge age see fresh data.
    pub restamp: bool,
    /// Only keys that contain one of these substrings (all when empty).
    pub only: Vec<String>,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions {
            speed: 1.0,
            restamp: true,
            only: vec![],
        }
    }
}

/// Publish `records` on their keys with their original spacing divided by `speed`. Returns the
/// number of messages published.
pub async fn replay(
    session: &zenoh::Session,
    records: &[Recorded],
    opts: &ReplayOptions,
    mut stop: Shutdown,
) -> Result<u64> {
    if !(opts.speed.is_finite() && opts.speed >= 0.0) {
        anyhow::bail!("replay speed must be ≥ 0, got {}", opts.speed);
    }
    let Some(first) = records.first().map(|r| r.log_time_ns) else {
        return Ok(0);
    };
    let start = tokio::time::Instant::now();
    let mut sent = 0;
    for r in records {
        if !opts.only.is_empty() && !opts.only.iter().any(|o| r.key.contains(o.as_str())) {
            continue;
        }
        if opts.speed > 0.0 {
            let offset = (r.log_time_ns.saturating_sub(first)) as f64 / 1e9 / opts.speed;
            let at = start + Duration::from_secs_f64(offset);
            tokio::select! {
                _ = tokio::time::sleep_until(at) => {}
                _ = stop.wait() => break,
            }
        } else if stop.is_triggered() {
            break;
        }
        let payload = if opts.restamp {
            restamp(&r.payload, now_ns())
        } else {
            r.payload.clone()
        };
        session
            .put(r.key.as_str(), payload)
            .await
            .map_err(|e| anyhow!("publishing on {}: {e}", r.key))?;
        sent += 1;
    }
    Ok(sent)
}

/// The payload with `header.stamp_ns` set to `t` (unchanged when it is not an Echo message).
pub fn restamp(payload: &[u8], t: u64) -> Vec<u8> {
    let Ok(mut v) = serde_json::from_slice::<serde_json::Value>(payload) else {
        return payload.to_vec();
    };
    match v.pointer_mut("/header/stamp_ns") {
        Some(s) if s.is_u64() => *s = serde_json::Value::from(t),
        _ => return payload.to_vec(),
    }
    serde_json::to_vec(&v).unwrap_or_else(|_| payload.to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn restamp_touches_only_the_header_stamp() {
        let p = br#"{"header":{"stamp_ns":5,"seq":3},"x":[1,2]}"#;
        let v: serde_json::Value = serde_json::from_slice(&restamp(p, 99)).unwrap();
        assert_eq!(v["header"]["stamp_ns"], 99);
        assert_eq!(v["header"]["seq"], 3);
        assert_eq!(v["x"][1], 2);
        assert_eq!(restamp(b"garbage", 1), b"garbage");
        assert_eq!(restamp(br#"{"a":1}"#, 1), br#"{"a":1}"#);
    }
}
