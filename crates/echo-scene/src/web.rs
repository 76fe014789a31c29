//! The built-in browser viewer: a small HTTP server that serves a three.js page and the latest
//! [`Scene`] as JSON, so that a robot can be watched with nothing but a browser.
//!
//! Routes: `/` (the page), `/viewer.js` (its script), `/vendor/three.module.js` and
//! `/vendor/OrbitControls.js` (three.js from the npm registry, unpacked by `scripts/setup` into
//! `.cache/web`; [`locate_assets`]), `/scene.json` (`{"seq": n, "scene": {…}}`, 204 before the
//! first scene). The page polls `/scene.json` ten times a second and redraws what changed.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, RwLock};

use axum::body::Bytes;
use axum::extract::State;
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::Router;

use crate::{Scene, SceneError};

const INDEX_HTML: &str = include_str!("../web/index.html");
const VIEWER_JS: &str = include_str!("../web/viewer.js");
/// three.js' ES module, as `scripts/setup` names it.
pub const THREE_JS: &str = "three.module.js";
/// three.js' orbit controls (imports `three`).
pub const ORBIT_JS: &str = "OrbitControls.js";

/// Where three.js is looked for, in order: `$ECHO_WEB_ASSETS`, then `web` in every
/// fetched-asset directory ([`echo_assets::cache_dirs`]).
pub fn asset_dirs() -> Vec<PathBuf> {
    let mut v = vec![];
    if let Ok(p) = std::env::var("ECHO_WEB_ASSETS") {
        v.push(PathBuf::from(p));
    }
    v.extend(echo_assets::cache_dirs("web"));
    v
}

/// The first of [`asset_dirs`] that holds three.js and its orbit controls.
pub fn locate_assets() -> Option<PathBuf> {
    asset_dirs()
        .into_iter()
        .find(|d| d.join(THREE_JS).is_file() && d.join(ORBIT_JS).is_file())
}

struct Shared {
    /// The sequence number of the latest scene (0: none yet) and its `/scene.json` body,
    /// made once per scene; every poll answers with a cheap copy of it.
    latest: RwLock<(u64, Bytes)>,
    three: Option<Bytes>,
    orbit: Option<Bytes>,
    /// `/scene.json` requests answered.
    polls: AtomicU64,
}

/// A running viewer server.
pub struct WebViewer {
    addr: SocketAddr,
    shared: Arc<Shared>,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    task: tokio::task::JoinHandle<()>,
}

impl WebViewer {
    /// Serve on `host:port` (port 0: any free port) with three.js from `assets` (a directory
    /// holding [`THREE_JS`] and [`ORBIT_JS`]). Without them the page still loads and says how to
    /// install them.
    pub async fn start(host: &str, port: u16, assets: Option<&Path>) -> Result<Self, SceneError> {
        let read = |name: &str| -> Result<Option<Bytes>, SceneError> {
            let Some(dir) = assets else { return Ok(None) };
            let path = dir.join(name);
            std::fs::read(&path)
                .map(|s| Some(Bytes::from(s)))
                .map_err(|source| SceneError::Io { path, source })
        };
        let shared = Arc::new(Shared {
            latest: RwLock::new((0, Bytes::new())),
            three: read(THREE_JS)?,
            orbit: read(ORBIT_JS)?,
            polls: AtomicU64::new(0),
        });
        let app = Router::new()
            .route("/", get(index))
            .route("/viewer.js", get(viewer_js))
            .route("/vendor/three.module.js", get(three_js))
            .route("/vendor/OrbitControls.js", get(orbit_js))
            .route("/scene.json", get(scene_json))
            .with_state(shared.clone());
        let listener = tokio::net::TcpListener::bind((host, port))
            .await
            .map_err(|e| SceneError::Web(format!("binding {host}:{port}: {e}")))?;
        let addr = listener
            .local_addr()
            .map_err(|e| SceneError::Web(e.to_string()))?;
        let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
        let task = tokio::spawn(async move {
            let serve = axum::serve(listener, app).with_graceful_shutdown(async move {
                let _ = stopped.await;
            });
            if let Err(e) = serve.await {
                eprintln!("viewer server: {e}");
            }
        });
        Ok(WebViewer {
            addr,
            shared,
            stop: Some(stop),
            task,
        })
    }

    /// The address served.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The page's address.
    pub fn url(&self) -> String {
        let host = if self.addr.ip().is_unspecified() {
            "localhost".to_string()
        } else {
            self.addr.ip().to_string()
        };
        format!("http://{host}:{}/", self.addr.port())
    }

    /// Whether three.js was found (else the page shows how to install it).
    pub fn has_three(&self) -> bool {
        self.shared.three.is_some() && self.shared.orbit.is_some()
    }

    /// Make `scene` the one the page draws next.
    pub fn publish(&self, scene: &Scene) {
        let json = match serde_json::to_string(scene) {
            Ok(j) => j,
            Err(_) => return,
        };
        let mut latest = self
            .shared
            .latest
            .write()
            .unwrap_or_else(|p| p.into_inner());
        let seq = latest.0 + 1;
        *latest = (
            seq,
            Bytes::from(format!("{{\"seq\":{seq},\"scene\":{json}}}")),
        );
    }

    /// Scenes published so far.
    pub fn published(&self) -> u64 {
        self.shared
            .latest
            .read()
            .unwrap_or_else(|p| p.into_inner())
            .0
    }

    /// `/scene.json` requests answered so far.
    pub fn polls(&self) -> u64 {
        self.shared.polls.load(Ordering::Relaxed)
    }

    /// Stop serving.
    pub async fn stop(mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        let _ = (&mut self.task).await;
    }
}

fn text(content_type: &'static str, body: impl IntoResponse) -> Response {
    (
        [
            (header::CONTENT_TYPE, content_type),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response()
}

async fn index() -> Response {
    text("text/html; charset=utf-8", INDEX_HTML)
}

async fn viewer_js() -> Response {
    text("text/javascript; charset=utf-8", VIEWER_JS)
}

fn vendor(file: &Option<Bytes>, name: &str) -> Response {
    match file {
        Some(s) => text("text/javascript; charset=utf-8", s.clone()),
        None => (
            StatusCode::NOT_FOUND,
            format!("{name} is not installed: run scripts/setup (it unpacks three.js from the npm registry into .cache/web) or set ECHO_WEB_ASSETS"),
        )
            .into_response(),
    }
}

async fn three_js(State(s): State<Arc<Shared>>) -> Response {
    vendor(&s.three, THREE_JS)
}

async fn orbit_js(State(s): State<Arc<Shared>>) -> Response {
    vendor(&s.orbit, ORBIT_JS)
}

async fn scene_json(State(s): State<Arc<Shared>>) -> Response {
    s.polls.fetch_add(1, Ordering::Relaxed);
    let (seq, body) = s.latest.read().unwrap_or_else(|p| p.into_inner()).clone();
    if seq == 0 {
        return StatusCode::NO_CONTENT.into_response();
    }
    text("application/json", body)
}
