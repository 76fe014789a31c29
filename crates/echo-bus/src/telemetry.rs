//! Logging setup shared by every binary: `RUST_LOG` filter (default `info`, Zenoh at `warn`),
//! compact output on stderr. Routers also report access-control denials.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::util::SubscriberInitExt;
use tracing_subscriber::Layer;

/// Where Zenoh's access control reports its decisions (at trace level).
const ACL_TARGET: &str = "zenoh::net::routing::interceptor::access_control";

fn default_filter() -> tracing_subscriber::EnvFilter {
    tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| {
        tracing_subscriber::EnvFilter::new("info,zenoh=warn,zenoh_transport=warn")
    })
}

/// Initialise tracing once; later calls are ignored.
pub fn init() {
    let _ = tracing_subscriber::fmt()
        .with_env_filter(default_filter())
        .with_writer(std::io::stderr)
        .with_target(false)
        .compact()
        .try_init();
}

/// Like [`init`], and every message that Zenoh's access control denies is logged as a warning
/// `access denied: …` (at most [`DENIALS_LOGGED_PER_S`] lines a second; the rest only counted).
/// Returns the denial counter.
pub fn init_with_access_log() -> Arc<AtomicU64> {
    let denied = Arc::new(AtomicU64::new(0));
    let fmt = tracing_subscriber::fmt::layer()
        .with_writer(std::io::stderr)
        .with_target(false)
        .compact()
        .with_filter(default_filter());
    let acl = AccessLog {
        denied: denied.clone(),
        window: std::sync::Mutex::new((std::time::Instant::now(), 0)),
    }
    .with_filter(
        tracing_subscriber::filter::Targets::new().with_target(ACL_TARGET, tracing::Level::TRACE),
    );
    let _ = tracing_subscriber::registry()
        .with(fmt)
        .with(acl)
        .try_init();
    denied
}

/// Lines of denials logged per second at most.
pub const DENIALS_LOGGED_PER_S: u32 = 20;

/// Message kinds Zenoh evaluates when it caches a key's permissions.
const PRECOMPUTED_KINDS: u32 = 9;

thread_local! {
    static PRECOMPUTED: std::cell::Cell<u32> = const { std::cell::Cell::new(0) };
}

struct AccessLog {
    denied: Arc<AtomicU64>,
    window: std::sync::Mutex<(std::time::Instant, u32)>,
}

#[derive(Default)]
struct MessageText(String);

impl tracing::field::Visit for MessageText {
    fn record_debug(&mut self, field: &tracing::field::Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            self.0 = format!("{value:?}");
        }
    }
}

impl<S: tracing::Subscriber> Layer<S> for AccessLog {
    fn on_event(
        &self,
        event: &tracing::Event<'_>,
        _ctx: tracing_subscriber::layer::Context<'_, S>,
    ) {
        let mut text = MessageText::default();
        event.record(&mut text);
        // When a key is first seen, Zenoh evaluates every message kind for it in advance and
        // logs each decision; those are not attempts. (Exact when each identity matches one
        // subject, as in deploy/zenoh/router-secure.json5.)
        if text.0.contains("caching permissions") {
            PRECOMPUTED.with(|c| c.set(PRECOMPUTED_KINDS));
            return;
        }
        if text.0.contains("authorized to") && PRECOMPUTED.with(|c| c.get()) > 0 {
            PRECOMPUTED.with(|c| c.set(c.get() - 1));
            return;
        }
        if !(text.0.contains("unauthorized") || text.0.contains("did not match any")) {
            return;
        }
        let n = self.denied.fetch_add(1, Ordering::Relaxed) + 1;
        let mut w = self.window.lock().unwrap_or_else(|e| e.into_inner());
        if w.0.elapsed().as_secs_f64() >= 1.0 {
            *w = (std::time::Instant::now(), 0);
        }
        if w.1 < DENIALS_LOGGED_PER_S {
            w.1 += 1;
            eprintln!(
                "{} WARN access denied: {} (denials so far: {n})",
                humantime_now(),
                text.0
            );
        }
    }
}

fn humantime_now() -> String {
    let ns = echo_msgs::now_ns();
    format!("{}.{:06}", ns / 1_000_000_000, (ns % 1_000_000_000) / 1000)
}
