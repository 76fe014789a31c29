//! Checkpoints: the weights (safetensors) and what is stored next to them (JSON: architecture,
//! training settings, text encoder), saved and loaded by stem.

use std::path::Path;

use candle_core::{DType, Device};
use candle_nn::{VarBuilder, VarMap};
use echo_text::SentenceEncoder;
use serde::{Deserialize, Serialize};

use crate::model::{Forecaster, ForecasterConfig};
use crate::train_config::TrainConfig;

/// What is stored next to the weights.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CheckpointMeta {
    /// Architecture.
    pub model: ForecasterConfig,
    /// How it was trained.
    pub training: TrainConfig,
    /// The command that produced it.
    pub command: String,
    /// Text encoder id ("none": the model reads no text).
    pub text_encoder: String,
    /// Feature layout.
    pub features: String,
    /// Settings of a human–robot (HRI) training, when the model has a robot agent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hri_training: Option<serde_json::Value>,
}

impl CheckpointMeta {
    /// Read `<stem>.json` (`stem` resolved by [`echo_assets::resolve_model`]); the file is
    /// named in any error.
    pub fn load(stem: &Path) -> anyhow::Result<CheckpointMeta> {
        Self::read(&echo_assets::resolve_model(stem)?)
    }

    /// Read `<stem>.json` of an already resolved stem.
    fn read(stem: &Path) -> anyhow::Result<CheckpointMeta> {
        let jp = stem.with_extension("json");
        serde_json::from_slice(
            &std::fs::read(&jp).map_err(|e| anyhow::anyhow!("{}: {e}", jp.display()))?,
        )
        .map_err(|e| anyhow::anyhow!("{}: {e}", jp.display()))
    }
}

/// A loaded checkpoint.
pub struct Checkpoint {
    /// The model.
    pub model: Forecaster,
    /// Its metadata.
    pub meta: CheckpointMeta,
    /// The sentence encoder it was trained with (when it reads text).
    pub text: Option<SentenceEncoder>,
    dev: Device,
}

impl Checkpoint {
    /// Save weights and metadata as `<stem>.safetensors` and `<stem>.json`.
    pub fn save(varmap: &VarMap, meta: &CheckpointMeta, stem: &Path) -> anyhow::Result<()> {
        if let Some(d) = stem.parent() {
            std::fs::create_dir_all(d)?;
        }
        varmap.save(stem.with_extension("safetensors"))?;
        std::fs::write(
            stem.with_extension("json"),
            serde_json::to_vec_pretty(meta)?,
        )?;
        Ok(())
    }

    /// Load `<stem>.safetensors` and `<stem>.json`, and the sentence encoder the model was
    /// trained with when it reads text; a missing tensor or encoder is named.
    /// `stem` is resolved by [`echo_assets::resolve_model`] (`$ECHO_MODELS`, the installation,
    /// the working directory).
    pub fn load(stem: &Path, dev: &Device) -> anyhow::Result<Checkpoint> {
        let stem = &echo_assets::resolve_model(stem)?;
        let meta = CheckpointMeta::read(stem)?;
        let wp = stem.with_extension("safetensors");
        let bytes = std::fs::read(&wp).map_err(|e| anyhow::anyhow!("{}: {e}", wp.display()))?;
        let vb = VarBuilder::from_buffered_safetensors(bytes, DType::F32, dev)?;
        let model = Forecaster::new(meta.model.clone(), vb)
            .map_err(|e| anyhow::anyhow!("{}: {e}", wp.display()))?;
        let text = if meta.model.text_dim > 0 {
            let enc = SentenceEncoder::load_default(dev)?;
            anyhow::ensure!(
                enc.id() == meta.text_encoder && enc.dim() == meta.model.text_dim,
                "{}: trained with {} ({}-d), found {} ({}-d)",
                stem.with_extension("json").display(),
                meta.text_encoder,
                meta.model.text_dim,
                enc.id(),
                enc.dim()
            );
            Some(enc)
        } else {
            None
        };
        Ok(Checkpoint {
            model,
            meta,
            text,
            dev: dev.clone(),
        })
    }

    /// The device its tensors live on.
    pub fn device(&self) -> &Device {
        &self.dev
    }
}
