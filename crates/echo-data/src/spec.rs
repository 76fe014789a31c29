//! The data spec: which sources, with which weights.
//!
//! ```text
//! spec   := item ("," item)*
//! item   := source ["*" weight]
//! source := "synthetic" [":" clips]            the generator (clips for the train split)
//!         | "synthetic-walk" [":" clips]       the generator's walking clips (approaches from
//!                                              2.4–5 m at 0.6–1.5 m/s, smooth starts and stops)
//!         | "synthetic-greet" [":" clips]      walking handshakes, high fives and handovers
//!                                              held 0.1–0.8 s, then a step back
//!         | "intergen:" root                   InterGen / InterHuman layout
//!         | "bvh:" a.bvh "+" b.bvh ["@" text]  one two-person capture (two files, one clock)
//!         | "cmu:" dir                         every CMU pair in dir: <s>_<t>.bvh + <s+1>_<t>.bvh
//!         | "echo:" dir                        Echo's own dataset format (echoctl data export)
//! ```
//!
//! Examples: `synthetic`, `cmu:data/cmu`, `cmu:data/cmu*0.5,synthetic:1300*0.5`,
//! `bvh:../shared/data/cmu/18_01.bvh+../shared/data/cmu/19_01.bvh@Two people shake hands.`.

use std::path::PathBuf;

/// One source of two-person interactions.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// Echo's generator; `clips` for the train split (validation and test get a twentieth).
    Synthetic {
        /// Training clips (None: the caller's default).
        clips: Option<u64>,
        /// Which of the generator's families.
        family: Family,
    },
    /// The InterGen / InterHuman layout (`motions_processed/person{1,2}/*.npy`, `annots/`,
    /// `split/{train,val,test}.txt`).
    InterGen {
        /// Dataset root.
        root: PathBuf,
    },
    /// One two-person BVH capture.
    BvhPair {
        /// Person A's file.
        a: PathBuf,
        /// Person B's file.
        b: PathBuf,
        /// Description (default: a generic one).
        text: Option<String>,
    },
    /// A directory of CMU two-person captures.
    CmuDir {
        /// Directory.
        dir: PathBuf,
    },
    /// Echo's dataset format.
    Echo {
        /// Directory (meta.json + positions.npy).
        dir: PathBuf,
    },
}

/// The generator's clip families.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// `synthetic`: the original choreography (every type, short approaches).
    Standing,
    /// `synthetic-walk`: walking clips ([`echo_motion::synth::Split::walking_clip`]).
    Walking,
    /// `synthetic-greet`: brief exchanges on the way ([`echo_motion::synth::Split::greeting_clip`]).
    Greeting,
}

/// A source with its sampling weight in a mix.
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    /// The source.
    pub source: Source,
    /// Relative weight of its windows in training (None: as many as it has).
    pub weight: Option<f64>,
}

/// A parsed spec.
#[derive(Debug, Clone, PartialEq)]
pub struct Spec {
    /// Sources in order.
    pub items: Vec<Item>,
}

/// Why a spec does not parse.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("data spec '{spec}': {what} (forms: synthetic[:clips], synthetic-walk[:clips], synthetic-greet[:clips], intergen:ROOT, bvh:A.bvh+B.bvh[@TEXT], cmu:DIR, echo:DIR; each optionally *WEIGHT, comma-separated)")]
pub struct SpecError {
    /// The spec.
    pub spec: String,
    /// What is wrong.
    pub what: String,
}

impl Spec {
    /// Parse `text`.
    pub fn parse(text: &str) -> Result<Spec, SpecError> {
        let err = |what: String| SpecError {
            spec: text.to_string(),
            what,
        };
        let mut items = vec![];
        for raw in split_items(text) {
            let raw = raw.trim();
            if raw.is_empty() {
                return Err(err("an empty item".into()));
            }
            // A weight is a trailing "*number" (not inside a prompt: prompts come after '@').
            let (body, weight) = match raw.rsplit_once('*') {
                Some((b, w)) if !w.contains('@') && !w.contains('/') => {
                    let w: f64 = w
                        .trim()
                        .parse()
                        .map_err(|_| err(format!("weight '{w}' is not a number")))?;
                    if !(w.is_finite() && w > 0.0) {
                        return Err(err(format!("weight {w} must be positive")));
                    }
                    (b.trim(), Some(w))
                }
                _ => (raw, None),
            };
            let (kind, arg) = body.split_once(':').unwrap_or((body, ""));
            let need = |what: &str| -> Result<PathBuf, SpecError> {
                if arg.is_empty() {
                    Err(err(format!("{kind} needs {what}")))
                } else {
                    Ok(PathBuf::from(arg))
                }
            };
            let source = match kind {
                "synthetic" | "synthetic-walk" | "synthetic-greet" => Source::Synthetic {
                    family: match kind {
                        "synthetic-walk" => Family::Walking,
                        "synthetic-greet" => Family::Greeting,
                        _ => Family::Standing,
                    },
                    clips: if arg.is_empty() {
                        None
                    } else {
                        Some(arg.parse().map_err(|_| {
                            err(format!("synthetic clip count '{arg}' is not a number"))
                        })?)
                    },
                },
                "intergen" => Source::InterGen {
                    root: need("a dataset root")?,
                },
                "cmu" => Source::CmuDir {
                    dir: need("a directory")?,
                },
                "echo" => Source::Echo {
                    dir: need("a directory")?,
                },
                "bvh" => {
                    let (files, text) = match arg.split_once('@') {
                        Some((f, t)) => (f, Some(t.trim().to_string()).filter(|t| !t.is_empty())),
                        None => (arg, None),
                    };
                    let (a, b) = files
                        .split_once('+')
                        .ok_or_else(|| err("bvh needs two files joined by '+'".into()))?;
                    if a.is_empty() || b.is_empty() {
                        return Err(err("bvh needs two files joined by '+'".into()));
                    }
                    Source::BvhPair {
                        a: PathBuf::from(a),
                        b: PathBuf::from(b),
                        text,
                    }
                }
                other => return Err(err(format!("unknown source '{other}'"))),
            };
            items.push(Item { source, weight });
        }
        if items.is_empty() {
            return Err(err("no source".into()));
        }
        Ok(Spec { items })
    }
}

/// Split at commas that are not inside a prompt (a prompt runs from '@' to the end of its item,
/// so a comma there would be ambiguous: prompts may not contain commas followed by a source
/// name; a comma followed by a known source keyword always starts a new item).
fn split_items(text: &str) -> Vec<String> {
    // "synthetic" also starts "synthetic-walk" and "synthetic-greet".
    const KEYS: [&str; 5] = ["synthetic", "intergen:", "bvh:", "cmu:", "echo:"];
    let mut out = vec![String::new()];
    let mut rest = text;
    while let Some(i) = rest.find(',') {
        let (head, tail) = rest.split_at(i);
        let after = tail[1..].trim_start();
        out.last_mut().expect("non-empty").push_str(head);
        let in_prompt = out.last().is_some_and(|s| s.contains('@'));
        if !in_prompt || KEYS.iter().any(|k| after.starts_with(k)) {
            out.push(String::new());
        } else {
            out.last_mut().expect("non-empty").push(',');
        }
        rest = &tail[1..];
    }
    out.last_mut().expect("non-empty").push_str(rest);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_form_parses() {
        let s = Spec::parse(
            "synthetic:1300*0.5, cmu:data/cmu*2,intergen:/d/ig,echo:out/ds,bvh:a.bvh+b.bvh@Two people meet, then shake hands.",
        )
        .unwrap();
        assert_eq!(s.items.len(), 5);
        assert_eq!(
            s.items[0],
            Item {
                source: Source::Synthetic {
                    clips: Some(1300),
                    family: Family::Standing
                },
                weight: Some(0.5)
            }
        );
        assert_eq!(s.items[1].weight, Some(2.0));
        assert_eq!(
            s.items[4].source,
            Source::BvhPair {
                a: "a.bvh".into(),
                b: "b.bvh".into(),
                text: Some("Two people meet, then shake hands.".into())
            }
        );
        assert_eq!(
            Spec::parse("synthetic").unwrap().items[0].source,
            Source::Synthetic {
                clips: None,
                family: Family::Standing
            }
        );
        assert_eq!(
            Spec::parse("synthetic-walk:30").unwrap().items[0].source,
            Source::Synthetic {
                clips: Some(30),
                family: Family::Walking
            }
        );
        assert_eq!(
            Spec::parse("synthetic-greet:9*0.2").unwrap().items[0].source,
            Source::Synthetic {
                clips: Some(9),
                family: Family::Greeting
            }
        );
    }

    #[test]
    fn mistakes_are_named() {
        for (bad, what) in [
            ("", "empty"),
            ("mocap:x", "unknown source"),
            ("bvh:a.bvh", "two files"),
            ("cmu:", "needs a directory"),
            ("synthetic*-1", "positive"),
            ("synthetic:lots", "not a number"),
        ] {
            let e = Spec::parse(bad).unwrap_err().to_string();
            assert!(e.contains(what), "{bad}: {e}");
        }
    }
}
