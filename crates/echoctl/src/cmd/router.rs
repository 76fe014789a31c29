//! `echoctl router`: a Zenoh router from the same library the services use (the upstream
//! `zenohd` reads the same configuration file, deploy/zenoh/router.json5). With access control
//! on, every message it denies is logged as a warning naming the sender's identity (its
//! certificate's common name).

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use anyhow::{anyhow, Result};
use echo_bus::BusArgs;
use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::util::SubscriberInitExt;
use tracing_subscriber::Layer;

/// Options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Network (the mode is forced to router; default listen tcp/0.0.0.0:7447).
    #[command(flatten)]
    pub bus: BusArgs,
}

/// Run a router until SIGINT/SIGTERM.
pub async fn run(mut args: Args) -> Result<()> {
    args.bus.mode = Some("router".into());
    if args.bus.listen.is_empty() && args.bus.zenoh_config.is_none() {
        args.bus.listen = vec!["tcp/0.0.0.0:7447".into()];
    }
    let cfg = args.bus.for_service("router").zenoh_config()?;
    let acl = cfg
        .get_json("access_control/enabled")
        .is_ok_and(|v| v == "true");
    let session = zenoh::open(cfg)
        .await
        .map_err(|e| anyhow!("starting the router: {e}"))?;
    tracing::info!(zid = %session.zid(), listen = ?args.bus.listen, access_control = acl, "router running");
    echo_bus::shutdown::signal().await;
    session
        .close()
        .await
        .map_err(|e| anyhow!("closing the router: {e}"))
}

/// Where Zenoh's access control reports its decisions (at trace level).
const ACL_TARGET: &str = "zenoh::net::routing::interceptor::access_control";

/// Lines of denials logged per second at most (all are counted).
pub const DENIALS_LOGGED_PER_S: u32 = 20;

/// Message kinds Zenoh evaluates, one decision each, when it caches a key's permissions for a
/// face.
const PRECOMPUTED_KINDS: u32 = 9;

/// Identities remembered at most (one per connection seen; forgotten all at once beyond).
const IDENTITIES_KEPT: usize = 4096;

/// Logging as every binary's (`RUST_LOG`, default `info`, Zenoh at `warn`, on stderr), plus one
/// warning per message that access control denies:
/// `access denied: forecaster (zid 1f0c…) is unauthorized to Put (ingress) on echo/tiago-1/status/safety (denials so far: 3)`
/// (at most [`DENIALS_LOGGED_PER_S`] lines a second). Returns the denial counter.
pub fn init_logging() -> Arc<AtomicU64> {
    let denied = Arc::new(AtomicU64::new(0));
    let filter = tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| {
        tracing_subscriber::EnvFilter::new("info,zenoh=warn,zenoh_transport=warn")
    });
    let fmt = tracing_subscriber::fmt::layer()
        .with_writer(std::io::stderr)
        .with_target(false)
        .compact()
        .with_filter(filter);
    let acl = AccessLog {
        denied: denied.clone(),
        identities: Mutex::default(),
        window: Mutex::new((std::time::Instant::now(), 0)),
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

/// One access-control trace of Zenoh's.
#[derive(Debug, PartialEq, Eq)]
enum AclTrace<'a> {
    /// It is about to evaluate every message kind for `key` on one face.
    Caching { key: &'a str },
    /// A decision on a message of session `zid`. `subject` is the matched subject
    /// (`Interface(lo)+CertCommonName(forecaster)+…`) when evaluated now, `None` when taken
    /// from the cache (logged with the zid only).
    Decision {
        zid: &'a str,
        subject: Option<&'a str>,
        allowed: bool,
        action: &'a str,
        key: &'a str,
    },
    /// Session `zid` matches no subject: the default permission applies to all it sends.
    Unmatched { zid: &'a str },
}

fn parse(msg: &str) -> Option<AclTrace<'_>> {
    if let Some((_, rest)) = msg.split_once("caching permissions for `") {
        return Some(AclTrace::Caching {
            key: rest.split('`').next()?,
        });
    }
    if let Some((zid, _)) = msg.split_once(" did not match any configured ACL subject") {
        return Some(AclTrace::Unmatched { zid });
    }
    let (who, allowed, what) = if let Some((w, a)) = msg.split_once(" is unauthorized to ") {
        (w, false, a)
    } else {
        let (w, a) = msg.split_once(" is authorized to ")?;
        (w, true, a)
    };
    let (action, key) = what.rsplit_once(" on ")?;
    // Undeclarations from the cache print their key as `Some(key)`.
    let key = key
        .strip_prefix("Some(")
        .and_then(|k| k.strip_suffix(')'))
        .unwrap_or(key);
    let (zid, subject) = match who.strip_prefix("Using cached result: ") {
        Some(zid) => (zid, None),
        None => {
            let (zid, subject) = who.split_once(" on ")?;
            (zid, Some(subject))
        }
    };
    Some(AclTrace::Decision {
        zid,
        subject,
        allowed,
        action,
        key,
    })
}

/// The identity a subject stands for: its certificate's common name, else the whole subject.
fn identity(subject: &str) -> &str {
    subject
        .split('+')
        .find_map(|part| part.strip_prefix("CertCommonName(")?.strip_suffix(')'))
        .unwrap_or(subject)
}

thread_local! {
    /// The key whose permissions Zenoh is caching on this thread, and how many of its decisions
    /// are still to come: those are evaluations in advance, not attempts.
    static PRECOMPUTING: std::cell::RefCell<Option<(String, u32)>> =
        const { std::cell::RefCell::new(None) };
}

struct AccessLog {
    denied: Arc<AtomicU64>,
    /// zid → identity, learnt from the decisions Zenoh logs with the subject (a connection's
    /// first decision on a key always is; the cached ones that follow name the zid only).
    identities: Mutex<HashMap<String, String>>,
    window: Mutex<(std::time::Instant, u32)>,
}

impl AccessLog {
    fn observe(&self, msg: &str) -> Option<String> {
        let Some(trace) = parse(msg) else {
            PRECOMPUTING.with(|p| p.take());
            return None;
        };
        match trace {
            AclTrace::Caching { key } => {
                PRECOMPUTING.with(|p| *p.borrow_mut() = Some((key.to_string(), PRECOMPUTED_KINDS)));
                None
            }
            AclTrace::Unmatched { .. } => {
                PRECOMPUTING.with(|p| p.take());
                Some(msg.to_string())
            }
            AclTrace::Decision {
                zid,
                subject,
                allowed,
                action,
                key,
            } => {
                let in_advance = PRECOMPUTING.with(|p| {
                    let mut p = p.borrow_mut();
                    match p.as_mut() {
                        Some((k, n)) if subject.is_some() && k == key && *n > 0 => {
                            *n -= 1;
                            true
                        }
                        _ => {
                            *p = None;
                            false
                        }
                    }
                });
                let mut ids = self.identities.lock().unwrap_or_else(|e| e.into_inner());
                if let Some(s) = subject {
                    if !ids.contains_key(zid) {
                        if ids.len() >= IDENTITIES_KEPT {
                            ids.clear();
                        }
                        ids.insert(zid.to_string(), identity(s).to_string());
                    }
                }
                if allowed || in_advance {
                    return None;
                }
                let who = ids.get(zid).map_or("unknown identity", String::as_str);
                Some(format!(
                    "{who} (zid {zid}) is unauthorized to {action} on {key}"
                ))
            }
        }
    }
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
        let Some(denial) = self.observe(&text.0) else {
            return;
        };
        let n = self.denied.fetch_add(1, Ordering::Relaxed) + 1;
        let mut w = self.window.lock().unwrap_or_else(|e| e.into_inner());
        if w.0.elapsed().as_secs_f64() >= 1.0 {
            *w = (std::time::Instant::now(), 0);
        }
        if w.1 < DENIALS_LOGGED_PER_S {
            w.1 += 1;
            let ns = echo_msgs::now_ns();
            eprintln!(
                "{}.{:06} WARN access denied: {denial} (denials so far: {n})",
                ns / 1_000_000_000,
                (ns % 1_000_000_000) / 1000
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SUBJECT: &str = "Interface(lo)+CertCommonName(forecaster)+Tls+7a3e";

    fn log() -> AccessLog {
        AccessLog {
            denied: Arc::default(),
            identities: Mutex::default(),
            window: Mutex::new((std::time::Instant::now(), 0)),
        }
    }

    #[test]
    fn traces_parse() {
        assert_eq!(
            parse("ACL (ingress): caching permissions for `echo/r/status/safety` ..."),
            Some(AclTrace::Caching {
                key: "echo/r/status/safety"
            })
        );
        assert_eq!(
            parse(&format!(
                "7a3e on {SUBJECT} is unauthorized to Put (ingress) on echo/r/command"
            )),
            Some(AclTrace::Decision {
                zid: "7a3e",
                subject: Some(SUBJECT),
                allowed: false,
                action: "Put (ingress)",
                key: "echo/r/command",
            })
        );
        assert_eq!(
            parse("Using cached result: 7a3e is unauthorized to Declare/Undeclare Liveliness Token (ingress) on Some(echo/r/alive/safety)"),
            Some(AclTrace::Decision {
                zid: "7a3e",
                subject: None,
                allowed: false,
                action: "Declare/Undeclare Liveliness Token (ingress)",
                key: "echo/r/alive/safety",
            })
        );
        assert_eq!(
            parse("51c0 did not match any configured ACL subject. Default permission `Deny` will be applied on all messages"),
            Some(AclTrace::Unmatched { zid: "51c0" })
        );
        assert_eq!(parse("Access control is enabled"), None);
        assert_eq!(identity(SUBJECT), "forecaster");
        assert_eq!(identity("Username(ops)"), "Username(ops)");
    }

    #[test]
    fn cached_denials_name_the_identity_and_advance_evaluations_are_not_attempts() {
        let log = log();
        let key = "echo/r/status/safety";
        assert_eq!(
            log.observe(&format!(
                "ACL (ingress): caching permissions for `{key}` ..."
            )),
            None
        );
        for (verdict, action) in [
            ("unauthorized", "Query (ingress)"),
            ("unauthorized", "Put (ingress)"),
            ("authorized", "Declare/Undeclare Subscriber (ingress)"),
        ] {
            let line = format!("7a3e on {SUBJECT} is {verdict} to {action} on {key}");
            assert_eq!(log.observe(&line), None, "{line}");
        }
        assert_eq!(
            log.observe(&format!(
                "Using cached result: 7a3e is unauthorized to Put (ingress) on {key}"
            ))
            .as_deref(),
            Some("forecaster (zid 7a3e) is unauthorized to Put (ingress) on echo/r/status/safety")
        );
        assert_eq!(
            log.observe(
                "Using cached result: 7a3e is authorized to Put (ingress) on echo/r/forecast"
            ),
            None
        );
        // Evaluated now (not cached), outside a caching run: an attempt.
        assert_eq!(
            log.observe(&format!(
                "7a3e on {SUBJECT} is unauthorized to Put (ingress) on echo/r/command"
            ))
            .as_deref(),
            Some("forecaster (zid 7a3e) is unauthorized to Put (ingress) on echo/r/command")
        );
        // A session that matched no subject is logged once, and its cached denials by zid.
        assert!(log
            .observe("51c0 did not match any configured ACL subject. Default permission `Deny` will be applied on all messages")
            .is_some_and(|l| l.starts_with("51c0 did not match")));
        assert_eq!(
            log.observe(
                "Using cached result: 51c0 is unauthorized to Put (ingress) on echo/r/command"
            )
            .as_deref(),
            Some("unknown identity (zid 51c0) is unauthorized to Put (ingress) on echo/r/command")
        );
    }
}
