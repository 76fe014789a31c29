//! Logging setup shared by every binary: `RUST_LOG` filter (default `info`, Zenoh at `warn`),
//! compact output on stderr. (`echoctl router` adds its access-control denial log on top.)

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
