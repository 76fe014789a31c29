//! Per-service counters that become the service's [`ServiceStatus`].

use std::collections::{BTreeMap, VecDeque};
use std::sync::Mutex;
use std::time::Instant;

use echo_msgs::{Header, LatencySummary, ServiceStatus};

/// Thread-safe counters of a service: received / published per edge, rejections by reason,
/// drops by queue policy, and a window of processing latencies.
#[derive(Debug)]
pub struct Stats {
    service: String,
    started: Instant,
    inner: Mutex<Inner>,
}

#[derive(Debug, Default)]
struct Inner {
    received: BTreeMap<String, u64>,
    published: BTreeMap<String, u64>,
    rejected: BTreeMap<String, u64>,
    dropped: BTreeMap<String, u64>,
    last_error: Option<String>,
    latencies_ms: VecDeque<f64>,
    notes: Vec<String>,
}

/// Latency samples kept for the status percentiles.
const LATENCY_WINDOW: usize = 1024;

impl Stats {
    /// Empty counters for `service`.
    pub fn new(service: &str) -> Self {
        Stats {
            service: service.to_string(),
            started: Instant::now(),
            inner: Mutex::new(Inner::default()),
        }
    }

    fn with<R>(&self, f: impl FnOnce(&mut Inner) -> R) -> R {
        let mut g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        f(&mut g)
    }

    /// One message received on `edge`.
    pub fn received(&self, edge: &str) {
        self.with(|i| *i.received.entry(edge.to_string()).or_default() += 1);
    }

    /// One message published on `edge`.
    pub fn published(&self, edge: &str) {
        self.with(|i| *i.published.entry(edge.to_string()).or_default() += 1);
    }

    /// `n` messages dropped by the queue policy on `edge`.
    pub fn dropped(&self, edge: &str, n: u64) {
        self.with(|i| *i.dropped.entry(edge.to_string()).or_default() += n);
    }

    /// A message on `edge` rejected for `reason` (short label) with a full `detail`.
    /// Logs the first rejections of each kind and then every 100th, so a flood cannot flood the log.
    pub fn rejected(&self, edge: &str, reason: &str, detail: &str) {
        let key = format!("{edge}/{reason}");
        let n = self.with(|i| {
            let c = i.rejected.entry(key.clone()).or_default();
            *c += 1;
            i.last_error = Some(format!(
                "{edge}: {}",
                detail.chars().take(300).collect::<String>()
            ));
            *c
        });
        if n <= 5 || n.is_multiple_of(100) {
            tracing::warn!(service = %self.service, edge, reason, count = n, "rejected: {detail}");
        }
    }

    /// Record one processing latency.
    pub fn latency_ms(&self, ms: f64) {
        self.with(|i| {
            if i.latencies_ms.len() == LATENCY_WINDOW {
                i.latencies_ms.pop_front();
            }
            i.latencies_ms.push_back(ms);
        });
    }

    /// Replace the free-form notes.
    pub fn set_notes(&self, notes: Vec<String>) {
        self.with(|i| i.notes = notes);
    }

    /// Rejection count for `edge/reason` (0 if none).
    pub fn rejected_count(&self, edge: &str, reason: &str) -> u64 {
        self.with(|i| {
            i.rejected
                .get(&format!("{edge}/{reason}"))
                .copied()
                .unwrap_or(0)
        })
    }

    /// Total rejections.
    pub fn rejected_total(&self) -> u64 {
        self.with(|i| i.rejected.values().sum())
    }

    /// Received count on `edge`.
    pub fn received_count(&self, edge: &str) -> u64 {
        self.with(|i| i.received.get(edge).copied().unwrap_or(0))
    }

    /// Published count on `edge`.
    pub fn published_count(&self, edge: &str) -> u64 {
        self.with(|i| i.published.get(edge).copied().unwrap_or(0))
    }

    /// Dropped count on `edge`.
    pub fn dropped_count(&self, edge: &str) -> u64 {
        self.with(|i| i.dropped.get(edge).copied().unwrap_or(0))
    }

    /// Snapshot as a status message.
    pub fn to_status(&self, header: Header) -> ServiceStatus {
        let uptime_s = self.started.elapsed().as_secs_f64();
        self.with(|i| ServiceStatus {
            header,
            service: self.service.clone(),
            uptime_s,
            received: i.received.clone(),
            published: i.published.clone(),
            rejected: i.rejected.clone(),
            dropped: i.dropped.clone(),
            last_error: i.last_error.clone(),
            latency: latency_summary(i.latencies_ms.iter().copied()),
            notes: i.notes.clone(),
        })
    }
}

/// Resident memory of process `pid` in MiB (Linux `/proc`; `None` elsewhere or when it is gone).
pub fn process_rss_mib(pid: u32) -> Option<f64> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let kb: f64 = s
        .lines()
        .find(|l| l.starts_with("VmRSS:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()?;
    Some(kb / 1024.0)
}

/// Median and p99 (nearest rank) of samples; `None` when empty.
pub fn latency_summary(samples: impl Iterator<Item = f64>) -> Option<LatencySummary> {
    let mut v: Vec<f64> = samples.filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(LatencySummary {
        median_ms: percentile_sorted(&v, 50.0),
        p99_ms: percentile_sorted(&v, 99.0),
        samples: v.len() as u64,
    })
}

/// Nearest-rank percentile of sorted, non-empty samples.
pub fn percentile_sorted(sorted: &[f64], p: f64) -> f64 {
    let rank = ((p / 100.0) * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_summarises() {
        let s = Stats::new("svc");
        s.received("a");
        s.received("a");
        s.rejected("a", "malformed", "bad json");
        s.dropped("a", 3);
        for i in 1..=100 {
            s.latency_ms(i as f64);
        }
        let st = s.to_status(Header::new("r", "svc", ""));
        assert_eq!(st.received["a"], 2);
        assert_eq!(st.rejected["a/malformed"], 1);
        assert_eq!(st.dropped["a"], 3);
        assert_eq!(st.last_error.as_deref(), Some("a: bad json"));
        let l = st.latency.unwrap();
        assert_eq!((l.median_ms, l.p99_ms, l.samples), (50.0, 99.0, 100));
    }
}
