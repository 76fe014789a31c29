//! The forecaster on ONNX Runtime through `ort`, loading `libonnxruntime` at run time (the
//! library `scripts/setup` unpacks from the PyPI wheel; on an edge GPU box, a build with the
//! CUDA or TensorRT execution provider).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use anyhow::{anyhow, Result};
use echo_models::backend::check_sizes;
use echo_models::features::FEATURES;
use echo_models::model::ForecasterConfig;
use echo_models::Backend;
use ort::environment::Environment;
use ort::session::Session;
use ort::value::Tensor;

/// File name of the library `scripts/setup` installs.
pub const DYLIB: &str = "libonnxruntime.so.1.31.1";

/// Where ONNX Runtime is looked for, in order: `$ECHO_ORT_DYLIB`, `$ORT_DYLIB_PATH`, then
/// `onnxruntime/` in every fetched-asset directory ([`echo_assets::cache_dirs`]).
pub fn dylib_candidates() -> Vec<PathBuf> {
    let mut v = vec![];
    for var in ["ECHO_ORT_DYLIB", "ORT_DYLIB_PATH"] {
        if let Ok(p) = std::env::var(var) {
            v.push(PathBuf::from(p));
        }
    }
    v.extend(
        echo_assets::cache_dirs("onnxruntime")
            .into_iter()
            .map(|d| d.join(DYLIB)),
    );
    v
}

/// The first candidate that exists.
pub fn locate_dylib() -> Option<PathBuf> {
    dylib_candidates().into_iter().find(|p| p.is_file())
}

static ENV: OnceLock<std::result::Result<Environment, String>> = OnceLock::new();

/// The process's ONNX Runtime environment (one per process), created on first use.
pub fn environment() -> Result<&'static Environment> {
    ENV.get_or_init(|| {
        let lib = locate_dylib().ok_or_else(|| {
            format!(
                "ONNX Runtime not found (looked for {}); run scripts/setup or set ECHO_ORT_DYLIB",
                dylib_candidates()
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })?;
        ort::init_from(&lib)
            .map_err(|e| format!("{}: {e}", lib.display()))?
            .with_name("echo")
            .build()
            .map_err(|e| format!("{}: {e}", lib.display()))
    })
    .as_ref()
    .map_err(|e| anyhow!("{e}"))
}

/// An exported forecaster in an ONNX Runtime session.
pub struct OrtBackend {
    session: Session,
    cfg: ForecasterConfig,
}

impl OrtBackend {
    /// Load `onnx` (exported for `cfg`) with `threads` intra-op threads (0: ONNX Runtime's choice).
    pub fn load(onnx: &Path, cfg: ForecasterConfig, threads: usize) -> Result<OrtBackend> {
        let env = environment()?;
        let mut b = Session::builder(env).map_err(|e| anyhow!("{e}"))?;
        if threads > 0 {
            b = b.with_intra_threads(threads).map_err(|e| anyhow!("{e}"))?;
        }
        let session = b
            .commit_from_file(onnx)
            .map_err(|e| anyhow!("{}: {e}", onnx.display()))?;
        Ok(OrtBackend { session, cfg })
    }
}

impl OrtBackend {
    /// Export checkpoint `<stem>` (architecture `cfg`) in memory and open a session on it.
    pub fn from_checkpoint(
        stem: &Path,
        cfg: ForecasterConfig,
        threads: usize,
    ) -> Result<OrtBackend> {
        use prost::Message;
        let model = crate::export::build_checkpoint(stem, &cfg)?.encode_to_vec();
        OrtBackend::from_bytes(&model, cfg, threads)
    }

    /// A session over an ONNX model held in memory (e.g. exported at start-up).
    pub fn from_bytes(model: &[u8], cfg: ForecasterConfig, threads: usize) -> Result<OrtBackend> {
        let env = environment()?;
        let mut b = Session::builder(env).map_err(|e| anyhow!("{e}"))?;
        if threads > 0 {
            b = b.with_intra_threads(threads).map_err(|e| anyhow!("{e}"))?;
        }
        let session = b.commit_from_memory(model).map_err(|e| anyhow!("{e}"))?;
        Ok(OrtBackend { session, cfg })
    }
}

impl OrtBackend {
    /// A model whose agents have different features: one tensor per agent in and out, each
    /// window's values regrouped from and back to the backend layout (A's frames, then B's).
    fn predict_per_agent(&mut self, b: usize, obs: &[f32], text: &[f32]) -> Result<Vec<f32>> {
        use crate::export::{AGENT_INPUTS, AGENT_OUTPUTS};
        let [fa, fb] = self.cfg.agent_features;
        let (n, pred) = (self.cfg.obs, self.cfg.pred);
        let per = n * (fa + fb);
        let (mut xa, mut xb) = (
            Vec::with_capacity(b * n * fa),
            Vec::with_capacity(b * n * fb),
        );
        for w in obs.chunks_exact(per) {
            xa.extend_from_slice(&w[..n * fa]);
            xb.extend_from_slice(&w[n * fa..]);
        }
        let xa = Tensor::from_array(([b, n, fa], xa))?;
        let xb = Tensor::from_array(([b, n, fb], xb))?;
        let outputs = if self.cfg.text_dim > 0 {
            let t = Tensor::from_array(([b, self.cfg.text_dim], text.to_vec()))?;
            self.session
                .run(ort::inputs![AGENT_INPUTS[0] => xa, AGENT_INPUTS[1] => xb, "text" => t])?
        } else {
            self.session
                .run(ort::inputs![AGENT_INPUTS[0] => xa, AGENT_INPUTS[1] => xb])?
        };
        let (_, ya) = outputs[AGENT_OUTPUTS[0]].try_extract_tensor::<f32>()?;
        let (_, yb) = outputs[AGENT_OUTPUTS[1]].try_extract_tensor::<f32>()?;
        anyhow::ensure!(
            ya.len() == b * pred * fa && yb.len() == b * pred * fb,
            "the session gave {} and {} values for a batch of {b}",
            ya.len(),
            yb.len()
        );
        let mut y = Vec::with_capacity(b * pred * (fa + fb));
        for (wa, wb) in ya.chunks_exact(pred * fa).zip(yb.chunks_exact(pred * fb)) {
            y.extend_from_slice(wa);
            y.extend_from_slice(wb);
        }
        Ok(y)
    }
}

impl Backend for OrtBackend {
    fn name(&self) -> String {
        "onnxruntime-cpu".into()
    }

    fn config(&self) -> &ForecasterConfig {
        &self.cfg
    }

    fn predict(&mut self, b: usize, obs: &[f32], text: &[f32]) -> Result<Vec<f32>> {
        check_sizes(&self.cfg, b, obs, text)?;
        if self.cfg.agent_features != [FEATURES, FEATURES] {
            return self.predict_per_agent(b, obs, text);
        }
        let x = Tensor::from_array(([b, 2, self.cfg.obs, FEATURES], obs.to_vec()))?;
        let outputs = if self.cfg.text_dim > 0 {
            let t = Tensor::from_array(([b, self.cfg.text_dim], text.to_vec()))?;
            self.session.run(ort::inputs!["obs" => x, "text" => t])?
        } else {
            self.session.run(ort::inputs!["obs" => x])?
        };
        let (_, data) = outputs["forecast"].try_extract_tensor::<f32>()?;
        Ok(data.to_vec())
    }
}
