//! Echo's own dataset format: a directory with `meta.json` (one entry per clip: id, type,
//! seed, split, heights, descriptions, frame offset and count) and `motions.safetensors` (one
//! tensor `positions`, f32, shape [total frames, 2, 22, 3], z-up metres at `fps`).

use std::path::{Path, PathBuf};

use echo_msgs::Interaction;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use serde::{Deserialize, Serialize};

use crate::skeleton::{Body, NUM_JOINTS};
use crate::synth::{Clip, ClipParams, Split, FPS};

/// Format version written into `meta.json`.
pub const FORMAT_VERSION: u32 = 1;

/// One clip's entry in `meta.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClipMeta {
    /// Clip id (file-unique).
    pub id: String,
    /// Interaction type.
    pub kind: Interaction,
    /// Generator seed (None for recorded data).
    pub seed: Option<u64>,
    /// Split.
    pub split: Option<Split>,
    /// Heights of the two people, metres.
    pub heights: [f64; 2],
    /// Descriptions.
    pub texts: Vec<String>,
    /// First frame in the positions tensor.
    pub offset: usize,
    /// Number of frames.
    pub frames: usize,
}

/// `meta.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Meta {
    /// Format version.
    pub version: u32,
    /// Frame rate.
    pub fps: f64,
    /// Clips.
    pub clips: Vec<ClipMeta>,
}

/// A loaded dataset: metadata and positions.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// Metadata.
    pub meta: Meta,
    /// Positions, flattened [frame][person][joint][xyz].
    pub positions: Vec<f32>,
}

/// Errors naming the file and the problem.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// I/O.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Error.
        source: std::io::Error,
    },
    /// Content problem.
    #[error("{path}: {what}")]
    Invalid {
        /// File.
        path: PathBuf,
        /// What is wrong.
        what: String,
    },
}

fn invalid(path: &Path, what: impl Into<String>) -> DatasetError {
    DatasetError::Invalid {
        path: path.to_path_buf(),
        what: what.into(),
    }
}

const FRAME_LEN: usize = 2 * NUM_JOINTS * 3;

/// Write clips in Echo's format.
pub fn write(dir: &Path, clips: &[Clip]) -> Result<(), DatasetError> {
    std::fs::create_dir_all(dir).map_err(|source| DatasetError::Io {
        path: dir.into(),
        source,
    })?;
    let mut data: Vec<f32> =
        Vec::with_capacity(clips.iter().map(|c| c.frames.len()).sum::<usize>() * FRAME_LEN);
    let mut metas = Vec::with_capacity(clips.len());
    for (i, c) in clips.iter().enumerate() {
        let offset = data.len() / FRAME_LEN;
        for f in &c.frames {
            for p in f {
                for j in p {
                    data.extend_from_slice(j);
                }
            }
        }
        metas.push(ClipMeta {
            id: format!("{:06}", i),
            kind: c.params.kind,
            seed: Some(c.params.seed),
            split: None,
            heights: c.params.heights,
            texts: c.texts.clone(),
            offset,
            frames: c.frames.len(),
        });
    }
    let total = data.len() / FRAME_LEN;
    let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
    let view = TensorView::new(Dtype::F32, vec![total, 2, NUM_JOINTS, 3], &bytes)
        .map_err(|e| invalid(dir, e.to_string()))?;
    let path = dir.join("motions.safetensors");
    safetensors::serialize_to_file([("positions", view)], None, &path)
        .map_err(|e| invalid(&path, e.to_string()))?;
    let meta = Meta {
        version: FORMAT_VERSION,
        fps: FPS,
        clips: metas,
    };
    let mp = dir.join("meta.json");
    std::fs::write(&mp, serde_json::to_vec_pretty(&meta).unwrap_or_default())
        .map_err(|source| DatasetError::Io { path: mp, source })
}

/// Read a dataset in Echo's format, checking every shape and offset.
pub fn read(dir: &Path) -> Result<Dataset, DatasetError> {
    let mp = dir.join("meta.json");
    let text = std::fs::read(&mp).map_err(|source| DatasetError::Io {
        path: mp.clone(),
        source,
    })?;
    let meta: Meta = serde_json::from_slice(&text).map_err(|e| invalid(&mp, e.to_string()))?;
    if meta.version != FORMAT_VERSION {
        return Err(invalid(
            &mp,
            format!(
                "format version {} (this build reads {FORMAT_VERSION})",
                meta.version
            ),
        ));
    }
    if !(meta.fps.is_finite() && meta.fps > 0.0) {
        return Err(invalid(&mp, "fps must be positive"));
    }
    let tp = dir.join("motions.safetensors");
    let bytes = std::fs::read(&tp).map_err(|source| DatasetError::Io {
        path: tp.clone(),
        source,
    })?;
    let st = SafeTensors::deserialize(&bytes).map_err(|e| invalid(&tp, e.to_string()))?;
    let t = st.tensor("positions").map_err(|_| {
        invalid(
            &tp,
            format!("no tensor 'positions' (found: {})", st.names().join(", ")),
        )
    })?;
    if t.dtype() != Dtype::F32 {
        return Err(invalid(
            &tp,
            format!("positions must be F32, not {:?}", t.dtype()),
        ));
    }
    let shape = t.shape().to_vec();
    if shape.len() != 4 || shape[1..] != [2, NUM_JOINTS, 3] {
        return Err(invalid(
            &tp,
            format!("positions must have shape [frames, 2, 22, 3], not {shape:?}"),
        ));
    }
    let positions: Vec<f32> = t
        .data()
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    if positions.iter().any(|x| !x.is_finite()) {
        return Err(invalid(&tp, "positions contain NaN or infinity"));
    }
    for c in &meta.clips {
        if c.frames == 0 || c.offset + c.frames > shape[0] {
            return Err(invalid(
                &mp,
                format!(
                    "clip {} spans frames {}..{} of {}",
                    c.id,
                    c.offset,
                    c.offset + c.frames,
                    shape[0]
                ),
            ));
        }
    }
    Ok(Dataset { meta, positions })
}

impl Dataset {
    /// Clip `i` as a [`Clip`] (bodies from the stored heights).
    pub fn clip(&self, i: usize) -> Option<Clip> {
        let m = self.meta.clips.get(i)?;
        let mut frames = Vec::with_capacity(m.frames);
        for f in m.offset..m.offset + m.frames {
            let base = f * FRAME_LEN;
            let mut fr = [[[0f32; 3]; NUM_JOINTS]; 2];
            for (p, person) in fr.iter_mut().enumerate() {
                for (j, joint) in person.iter_mut().enumerate() {
                    let k = base + (p * NUM_JOINTS + j) * 3;
                    *joint = [
                        self.positions[k],
                        self.positions[k + 1],
                        self.positions[k + 2],
                    ];
                }
            }
            frames.push(fr);
        }
        let mut params = ClipParams::sample(
            m.kind,
            &crate::synth::ParamRanges::train(),
            m.seed.unwrap_or(0),
        );
        params.heights = m.heights;
        Some(Clip {
            params,
            texts: m.texts.clone(),
            bodies: [
                Body::with_height(m.heights[0]),
                Body::with_height(m.heights[1]),
            ],
            frames,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::generate;

    /// A fresh directory, removed when the returned guard drops.
    fn tmp(name: &str) -> (tempfile::TempDir, PathBuf) {
        let guard = tempfile::tempdir().unwrap();
        let d = guard.path().join(name);
        (guard, d)
    }

    #[test]
    fn round_trip() {
        let clips: Vec<Clip> = (0..3).map(|i| generate(&Split::Test.clip(i))).collect();
        let (_tmp, d) = tmp("rt");
        write(&d, &clips).unwrap();
        let ds = read(&d).unwrap();
        assert_eq!(ds.meta.clips.len(), 3);
        let back = ds.clip(1).unwrap();
        assert_eq!(back.frames, clips[1].frames);
        assert_eq!(back.texts, clips[1].texts);
    }

    #[test]
    fn bad_files_name_the_file_and_the_problem() {
        let (_tmp, d) = tmp("bad");
        write(&d, &[generate(&Split::Test.clip(0))]).unwrap();
        std::fs::write(d.join("meta.json"), b"{\"version\": 1, \"fps\": 30, \"clips\": [{\"id\": \"x\", \"kind\": \"wave\", \"seed\": 1, \"split\": null, \"heights\": [1.7, 1.7], \"texts\": [], \"offset\": 0, \"frames\": 99999}]}").unwrap();
        let e = read(&d).unwrap_err().to_string();
        assert!(e.contains("meta.json") && e.contains("spans frames"), "{e}");
        std::fs::write(d.join("motions.safetensors"), b"not a safetensors file").unwrap();
        let e = read(&d).unwrap_err().to_string();
        assert!(e.contains("motions.safetensors"), "{e}");
        let e = read(&tmp("missing").1).unwrap_err().to_string();
        assert!(e.contains("meta.json"), "{e}");
    }
}
