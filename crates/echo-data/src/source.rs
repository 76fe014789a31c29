//! Loading each kind of source as captures (two people, 22 joints, z up, metres, 30 Hz), per split.
//!
//! Splits:
//! * synthetic: the generator's own seed ranges per split;
//! * InterGen layout: `split/<train|val|test>.txt` (held-out asks for test);
//! * Echo's format: the split recorded per clip (none recorded: train);
//! * a CMU directory: `splits.json` in the directory when present
//!   (`{"val": ["20_03"], "test": ["22_05"]}`, the rest train), else a stable hash of the capture
//!   name (FNV-1a: % 5 == 0 test, == 1 val, else train), so adding a capture never moves another;
//! * one BVH pair (`bvh:`): the whole capture, whatever split is asked — the user named it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use echo_motion::capture::{load_bvh_pair, CleanReport, PairOptions};
use echo_motion::synth::{generate_clips, generate_split, Clip, Split};

use crate::spec::{Family, Source};
use crate::DataError;

/// A two-person capture from some source.
#[derive(Debug, Clone)]
pub struct Capture {
    /// Unique within its source (file stem, clip id, seed).
    pub name: String,
    /// Source label (`synthetic`, `cmu`, `bvh`, `intergen`, `echo`).
    pub source: &'static str,
    /// Whether it was recorded from real people (augmentations that change roles, sides or
    /// timing apply only to those: synthetic descriptions name roles and hands).
    pub real: bool,
    /// The motion.
    pub clip: Clip,
    /// What cleaning a real file needed.
    pub report: Option<CleanReport>,
}

/// Default description of a real capture without one.
pub const GENERIC_TEXT: &str = "Two people interact with each other.";

/// Per-capture descriptions in a CMU directory (`captures.json`).
#[derive(Debug, Clone, Default, serde::Deserialize)]
struct CaptureInfo {
    #[serde(default)]
    text: Option<String>,
}

#[derive(Debug, Clone, Default, serde::Deserialize)]
struct Splits {
    #[serde(default)]
    val: Vec<String>,
    #[serde(default)]
    test: Vec<String>,
}

/// FNV-1a of `s`.
fn fnv(s: &str) -> u64 {
    s.bytes().fold(0xcbf29ce484222325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x100000001b3)
    })
}

/// The split of a real capture named `name` by the hash rule.
pub fn hash_split(name: &str) -> Split {
    match fnv(name) % 5 {
        0 => Split::Test,
        1 => Split::Val,
        _ => Split::Train,
    }
}

fn same(a: Split, b: Split) -> bool {
    // Held-out is the real sources' test.
    a == b || (a == Split::HeldOut && b == Split::Test)
}

/// The CMU pairs in `dir`: (name, A file, B file), by the rule `<s>_<t>.bvh` + `<s+1>_<t>.bvh`.
pub fn cmu_pairs(dir: &Path) -> Result<Vec<(String, PathBuf, PathBuf)>, DataError> {
    let rd = std::fs::read_dir(dir).map_err(|e| DataError::Io(dir.to_path_buf(), e))?;
    let mut files: BTreeMap<(u32, String), PathBuf> = BTreeMap::new();
    for e in rd.flatten() {
        let p = e.path();
        if p.extension().and_then(|x| x.to_str()) != Some("bvh") {
            continue;
        }
        let stem = p
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("")
            .to_string();
        if let Some((s, t)) = stem.split_once('_') {
            if let Ok(s) = s.parse::<u32>() {
                files.insert((s, t.to_string()), p.clone());
            }
        }
    }
    let mut out = vec![];
    for ((s, t), a) in &files {
        if let Some(b) = files.get(&(s + 1, t.clone())) {
            out.push((format!("{s:02}_{t}"), a.clone(), b.clone()));
        }
    }
    if out.is_empty() {
        return Err(DataError::Empty(format!(
            "{}: no pair of files <s>_<t>.bvh + <s+1>_<t>.bvh",
            dir.display()
        )));
    }
    Ok(out)
}

fn bvh_capture(
    name: String,
    source: &'static str,
    a: &Path,
    b: &Path,
    text: Option<String>,
) -> Result<Capture, DataError> {
    let text = text.unwrap_or_else(|| GENERIC_TEXT.to_string());
    let kind = echo_motion::intergen::kind_from_text(std::slice::from_ref(&text));
    let (clip, report) = load_bvh_pair(a, b, &PairOptions::default(), vec![text], kind)
        .map_err(|e| DataError::Bvh(e.to_string()))?;
    Ok(Capture {
        name,
        source,
        real: true,
        clip,
        report: Some(report),
    })
}

/// Load `source`'s captures of `split`; `synthetic_clips`: the generator's train-split size
/// when the spec gives none.
pub fn load(
    source: &Source,
    split: Split,
    synthetic_clips: u64,
) -> Result<Vec<Capture>, DataError> {
    match source {
        Source::Synthetic { clips, family } => {
            let train = clips.unwrap_or(synthetic_clips).max(1);
            let n = match split {
                Split::Train => train,
                _ => (train / 20).max(26),
            };
            let clips = match family {
                Family::Walking => {
                    generate_clips((0..n).map(|i| split.walking_clip(i)).collect(), 2, &|| {})
                }
                Family::Greeting => {
                    generate_clips((0..n).map(|i| split.greeting_clip(i)).collect(), 2, &|| {})
                }
                Family::Standing => generate_split(split, 0..n, 2, &|| {}),
            };
            Ok(clips
                .into_iter()
                .map(|clip| Capture {
                    name: format!("{}", clip.params.seed),
                    source: "synthetic",
                    real: false,
                    clip,
                    report: None,
                })
                .collect())
        }
        Source::InterGen { root } => {
            let name = match split {
                Split::Train => "train",
                Split::Val => "val",
                Split::Test | Split::HeldOut => "test",
            };
            Ok(echo_motion::intergen::load(root, name)
                .map_err(|e| DataError::Dataset(e.to_string()))?
                .into_iter()
                .map(|(id, clip)| Capture {
                    name: id,
                    source: "intergen",
                    real: true,
                    clip,
                    report: None,
                })
                .collect())
        }
        Source::Echo { dir } => {
            let ds =
                echo_motion::dataset::read(dir).map_err(|e| DataError::Dataset(e.to_string()))?;
            let mut out = vec![];
            for (i, m) in ds.meta.clips.iter().enumerate() {
                if !same(split, m.split.unwrap_or(Split::Train)) {
                    continue;
                }
                if let Some(clip) = ds.clip(i) {
                    out.push(Capture {
                        name: m.id.clone(),
                        source: "echo",
                        real: m.seed.is_none(),
                        clip,
                        report: None,
                    });
                }
            }
            Ok(out)
        }
        Source::BvhPair { a, b, text } => {
            let name = format!(
                "{}+{}",
                a.file_stem().and_then(|s| s.to_str()).unwrap_or("a"),
                b.file_stem().and_then(|s| s.to_str()).unwrap_or("b")
            );
            Ok(vec![bvh_capture(name, "bvh", a, b, text.clone())?])
        }
        Source::CmuDir { dir } => {
            let splits: Option<Splits> = read_json(&dir.join("splits.json"))?;
            let info: BTreeMap<String, CaptureInfo> =
                read_json(&dir.join("captures.json"))?.unwrap_or_default();
            let mut out = vec![];
            for (name, a, b) in cmu_pairs(dir)? {
                let s = match &splits {
                    Some(sp) if sp.test.contains(&name) => Split::Test,
                    Some(sp) if sp.val.contains(&name) => Split::Val,
                    Some(_) => Split::Train,
                    None => hash_split(&name),
                };
                if !same(split, s) {
                    continue;
                }
                let text = info.get(&name).and_then(|i| i.text.clone());
                out.push(bvh_capture(name, "cmu", &a, &b, text)?);
            }
            Ok(out)
        }
    }
}

fn read_json<T: serde::de::DeserializeOwned>(p: &Path) -> Result<Option<T>, DataError> {
    match std::fs::read(p) {
        Ok(b) => serde_json::from_slice(&b)
            .map(Some)
            .map_err(|e| DataError::Dataset(format!("{}: {e}", p.display()))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(DataError::Io(p.to_path_buf(), e)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cmu_pairs_by_subject_and_trial() {
        let d = tempfile::tempdir().unwrap();
        for f in [
            "20_01.bvh",
            "21_01.bvh",
            "20_02.bvh",
            "22_03.bvh",
            "23_03.bvh",
            "x.bvh",
        ] {
            std::fs::write(d.path().join(f), "").unwrap();
        }
        let names: Vec<String> = cmu_pairs(d.path())
            .unwrap()
            .into_iter()
            .map(|p| p.0)
            .collect();
        assert_eq!(names, vec!["20_01", "22_03"]);
    }

    #[test]
    fn the_hash_split_is_stable_and_uses_every_split() {
        let names: Vec<String> = (1..40).map(|t| format!("20_{t:02}")).collect();
        let splits: Vec<Split> = names.iter().map(|n| hash_split(n)).collect();
        for s in [Split::Train, Split::Val, Split::Test] {
            assert!(splits.contains(&s));
        }
        assert_eq!(hash_split("20_01"), hash_split("20_01"));
    }
}
