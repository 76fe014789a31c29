//! Scripted human–robot missions: the partner the robot meets in the demo and the system tests.
//!
//! A mission is data: a scenario file (`deploy/scenarios/<name>.json`, [`MissionSpec`]; an
//! unknown field is an error) lists the interactions the partner performs, each a generated clip
//! of the held-out test split (`echo_motion::synth`, standing or walking family) in which the
//! robot plays person B: the clip's person A is placed in the robot's frame with the robot
//! standing where B stood when the two were closest
//! ([`crate::perception::clip_partner_for_robot`]). Between two interactions the partner moves
//! from the last pose of one to the first of the next over `transition_s` (joint positions
//! blended with a smoothstep). Each interaction is a [`Segment`] with its description and type,
//! which the demo announces on `prompt` while it plays and scores afterwards.
//!
//! Per interaction the file says how it is staged:
//! - `standoff_m`: the partner stands this much further from the robot than they stood from
//!   person B (moved along the line from the robot to where they were at the closest moment):
//!   the robot's base, torso and shoulder mounts are deeper than a person's chest, and where B
//!   stood, the partner's torso would already be inside the robot's body clearance
//!   ([`STANDOFF_M`]; [`WAVE_STANDOFF_M`] for a wave across a distance);
//! - `hold_s`: in a handshake, a high five or a handover the partner holds the hand out at its
//!   furthest from their body for this long (the clip's pose at that moment is held): a person
//!   offering a robot their hand waits for it, and the robot's arm, slowed near people by the
//!   safety service's contact speed, needs longer than person B did ([`HOLD_S`]).
//!
//! A real capture replayed as the partner ([`Mission::from_clip`]) is staged with the same
//! defaults for its interaction type.

use echo_motion::skeleton::NUM_JOINTS;
use echo_motion::synth::{self, Clip, Split, FPS, KINDS, WALKING_KINDS};
use std::path::{Path, PathBuf};

use echo_msgs::Interaction;
use nalgebra::Vector3;
use serde::Deserialize;

use crate::perception::{clip_partner_for_robot, Actor, Recorded};

/// How long the partner holds out a hand for a handshake, a high five or a handover, waiting
/// for the robot, s.
pub const HOLD_S: f64 = 3.0;

/// How much further from the robot the partner stands than from person B, m.
pub const STANDOFF_M: f64 = 0.2;

/// A waving partner stands this much further away than person B did, m: waving is a greeting
/// across a distance, and a robot arm moving at waving speed keeps full speed only beyond the
/// safety service's protective distance plus its slow zone (about 2.2 m).
pub const WAVE_STANDOFF_M: f64 = 0.8;

/// Time the partner takes between two interactions, s.
pub const TRANSITION_S: f64 = 1.5;

/// One interaction of a mission.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// Its type.
    pub interaction: Interaction,
    /// Its description (the prompt the forecaster is given).
    pub text: String,
    /// Start, s of mission time.
    pub start_s: f64,
    /// End, s of mission time.
    pub end_s: f64,
    /// The clip it comes from (`test:<i>`, `test-walk:<i>` or a capture's files).
    pub source: String,
}

/// A scripted partner and the interactions it performs.
#[derive(Debug, Clone)]
pub struct Mission {
    /// Its name.
    pub name: String,
    /// The interactions in order.
    pub segments: Vec<Segment>,
    partner: Recorded,
}

/// A clip with how it is staged in front of the robot.
struct Staged {
    clip: Clip,
    source: String,
    standoff_m: f64,
    hold_s: f64,
}

/// A mission that cannot be built from its description.
#[derive(Debug, thiserror::Error)]
pub enum MissionError {
    /// The file is not readable.
    #[error("reading scenario {path}: {source}")]
    Read {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The file is not a scenario (an unknown field is an error too).
    #[error("parsing scenario {path}: {source}")]
    Parse {
        /// File.
        path: PathBuf,
        /// Cause.
        source: serde_json::Error,
    },
    /// A value the mission cannot be played with.
    #[error("scenario {name}: {reason}")]
    Invalid {
        /// Scenario.
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// No scenario of that name.
    #[error("unknown scenario '{name}' (one of: {known})")]
    Unknown {
        /// Name asked for.
        name: String,
        /// Names found under the scenarios directory.
        known: String,
    },
}

/// Which family of generated clips an interaction is taken from (the held-out test split).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClipFamily {
    /// Two people standing about 1 m apart ([`KINDS`]).
    Standing,
    /// Performed while walking up to the other ([`WALKING_KINDS`]).
    Walking,
}

/// One interaction of a scenario file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StepSpec {
    /// Its type (`handshake`, `wave`, …: the prompt's interaction names).
    pub interaction: Interaction,
    /// Standing or walking clip.
    pub clip: ClipFamily,
    /// Which clip of that type and family: 0 is the first of the test split.
    #[serde(default)]
    pub take: u64,
    /// How much further from the robot the partner stands than from person B, m.
    #[serde(default = "default_standoff")]
    pub standoff_m: f64,
    /// How long the partner holds the hand out at its furthest, waiting for the robot, s (0: no
    /// hold).
    #[serde(default)]
    pub hold_s: f64,
}

fn default_standoff() -> f64 {
    STANDOFF_M
}

fn default_transition() -> f64 {
    TRANSITION_S
}

/// A scenario file (`deploy/scenarios/<name>.json`): the interactions the scripted partner
/// performs, in order.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MissionSpec {
    /// What happens, in a sentence.
    pub description: String,
    /// Time the partner takes between two interactions, s.
    #[serde(default = "default_transition")]
    pub transition_s: f64,
    /// The interactions in order.
    pub interactions: Vec<StepSpec>,
}

impl MissionSpec {
    /// Check every value against what the mission builder can play.
    pub fn validate(&self, name: &str) -> Result<(), MissionError> {
        let bad = |reason: String| MissionError::Invalid {
            name: name.to_string(),
            reason,
        };
        if self.interactions.is_empty() {
            return Err(bad("no interactions".into()));
        }
        if !(0.1..=10.0).contains(&self.transition_s) {
            return Err(bad(format!(
                "transition_s {} outside 0.1–10 s",
                self.transition_s
            )));
        }
        for (i, s) in self.interactions.iter().enumerate() {
            let kinds: &[Interaction] = match s.clip {
                ClipFamily::Standing => &KINDS,
                ClipFamily::Walking => &WALKING_KINDS,
            };
            if !kinds.contains(&s.interaction) {
                return Err(bad(format!(
                    "interaction {i}: no {:?} clip of {:?}",
                    s.clip, s.interaction
                )));
            }
            if !(0.0..=3.0).contains(&s.standoff_m) {
                return Err(bad(format!(
                    "interaction {i}: standoff_m {} outside 0–3 m",
                    s.standoff_m
                )));
            }
            if !(0.0..=30.0).contains(&s.hold_s) {
                return Err(bad(format!(
                    "interaction {i}: hold_s {} outside 0–30 s",
                    s.hold_s
                )));
            }
            if s.take > 1000 {
                return Err(bad(format!("interaction {i}: take {} above 1000", s.take)));
            }
        }
        Ok(())
    }
}

impl StepSpec {
    /// The generated clip it names, and that clip's source name (`test:<i>`, `test-walk:<i>`).
    fn clip(&self) -> (Clip, String) {
        let (kinds, family): (&[Interaction], _) = match self.clip {
            ClipFamily::Standing => (&KINDS, "test"),
            ClipFamily::Walking => (&WALKING_KINDS, "test-walk"),
        };
        let pos = kinds
            .iter()
            .position(|x| *x == self.interaction)
            .unwrap_or(0) as u64;
        let i = pos + self.take * kinds.len() as u64;
        let params = match self.clip {
            ClipFamily::Standing => Split::Test.clip(i),
            ClipFamily::Walking => Split::Test.walking_clip(i),
        };
        (synth::generate(&params), format!("{family}:{i}"))
    }
}

/// The scenario names found in `<deploy>/scenarios/`, sorted.
pub fn scenario_names(deploy: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(deploy.join("scenarios"))
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let p = e.path();
            (p.extension()? == "json").then(|| p.file_stem()?.to_str().map(str::to_string))?
        })
        .collect();
    names.sort();
    names
}

/// The scenario file `name` names: a path (ends in `.json` or holds a `/`) as it is, or a name
/// under `<deploy>/scenarios/` (an error listing the known names when there is none).
pub fn scenario_path(name: &str, deploy: &Path) -> Result<PathBuf, MissionError> {
    if name.ends_with(".json") || name.contains('/') {
        return Ok(PathBuf::from(name));
    }
    let p = deploy.join("scenarios").join(format!("{name}.json"));
    if !p.is_file() {
        return Err(MissionError::Unknown {
            name: name.to_string(),
            known: scenario_names(deploy).join(", "),
        });
    }
    Ok(p)
}

impl Mission {
    /// A mission from its scenario file ([`scenario_path`]).
    pub fn load(name: &str, deploy: &Path) -> Result<Mission, MissionError> {
        let path = scenario_path(name, deploy)?;
        let text = std::fs::read(&path).map_err(|source| MissionError::Read {
            path: path.clone(),
            source,
        })?;
        let spec: MissionSpec =
            serde_json::from_slice(&text).map_err(|source| MissionError::Parse {
                path: path.clone(),
                source,
            })?;
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| name.to_string());
        Mission::from_spec(&stem, &spec)
    }

    /// A mission from a parsed scenario.
    pub fn from_spec(name: &str, spec: &MissionSpec) -> Result<Mission, MissionError> {
        spec.validate(name)?;
        let clips: Vec<Staged> = spec
            .interactions
            .iter()
            .map(|s| {
                let (clip, source) = s.clip();
                Staged {
                    clip,
                    source,
                    standoff_m: s.standoff_m,
                    hold_s: s.hold_s,
                }
            })
            .collect();
        Ok(Mission::build(name, &clips, spec.transition_s))
    }

    /// A mission of one recorded clip (a real capture) and its source's name, staged like a
    /// scenario's standing interaction of the same type.
    pub fn from_clip(name: &str, clip: Clip, source: String) -> Mission {
        let (standoff_m, hold_s) = match clip.params.kind {
            Interaction::Wave => (WAVE_STANDOFF_M, 0.0),
            Interaction::Handshake | Interaction::HighFive | Interaction::Handover => {
                (STANDOFF_M, HOLD_S)
            }
            _ => (STANDOFF_M, 0.0),
        };
        let staged = Staged {
            clip,
            source,
            standoff_m,
            hold_s,
        };
        Mission::build(name, &[staged], TRANSITION_S)
    }

    fn build(name: &str, clips: &[Staged], transition_s: f64) -> Mission {
        let mut frames: Vec<[Vector3<f64>; NUM_JOINTS]> = vec![];
        let mut segments = vec![];
        for Staged {
            clip,
            source,
            standoff_m,
            hold_s,
        } in clips
        {
            let Some(Actor::Recorded(person)) = clip_partner_for_robot(clip).into_iter().next()
            else {
                continue;
            };
            let mut next = standoff(person.frames(), clip, *standoff_m);
            if *hold_s > 0.0 {
                hold_offer(&mut next, *hold_s);
            }
            let next = next.as_slice();
            if let (Some(last), Some(first)) = (frames.last().copied(), next.first()) {
                let n = (transition_s * FPS).round() as usize;
                for k in 1..n {
                    let s = k as f64 / n as f64;
                    let w = s * s * (3.0 - 2.0 * s);
                    frames.push(std::array::from_fn(|j| last[j].lerp(&first[j], w)));
                }
            }
            let start = frames.len() as f64 / FPS;
            frames.extend_from_slice(next);
            segments.push(Segment {
                interaction: clip.params.kind,
                text: clip.texts.first().cloned().unwrap_or_default(),
                start_s: start,
                end_s: (frames.len().saturating_sub(1)) as f64 / FPS,
                source: source.clone(),
            });
        }
        Mission {
            name: name.to_string(),
            segments,
            partner: Recorded::new(FPS, frames),
        }
    }

    /// Length, s.
    pub fn duration(&self) -> f64 {
        self.partner.duration()
    }

    /// The interaction playing at mission time `t` (the previous one during a transition).
    pub fn segment_at(&self, t: f64) -> Option<&Segment> {
        self.segments
            .iter()
            .rev()
            .find(|s| s.start_s <= t)
            .or(self.segments.first())
    }

    /// The partner, for the mock estimator.
    pub fn actors(&self) -> Vec<Actor> {
        vec![Actor::Recorded(self.partner.clone())]
    }

    /// The partner's joints at mission time `t` (robot base frame).
    pub fn partner_at(&self, t: f64) -> [Vector3<f64>; NUM_JOINTS] {
        self.partner.joints_at(t)
    }
}

/// Hold the frame in which a hand is furthest from the pelvis–neck axis for `hold_s`.
fn hold_offer(frames: &mut Vec<[Vector3<f64>; NUM_JOINTS]>, hold_s: f64) {
    use echo_motion::skeleton::j;
    let reach = |f: &[Vector3<f64>; NUM_JOINTS]| {
        let axis = f[j::NECK] - f[j::PELVIS];
        [j::L_WRIST, j::R_WRIST]
            .iter()
            .map(|&w| {
                let v = f[w] - f[j::PELVIS];
                let along = axis.try_normalize(1e-9).map(|a| v.dot(&a)).unwrap_or(0.0);
                (v.norm_squared() - along * along).max(0.0).sqrt()
            })
            .fold(0.0, f64::max)
    };
    let Some(at) =
        (0..frames.len()).max_by(|a, b| reach(&frames[*a]).total_cmp(&reach(&frames[*b])))
    else {
        return;
    };
    let n = (hold_s * FPS).round() as usize;
    let held = frames[at];
    frames.splice(at..at, std::iter::repeat_n(held, n));
}

/// The partner's frames moved `d` metres away from the robot, along the horizontal direction
/// from the robot to their pelvis at the clip's closest moment.
fn standoff(
    frames: &[[Vector3<f64>; NUM_JOINTS]],
    clip: &Clip,
    d: f64,
) -> Vec<[Vector3<f64>; NUM_JOINTS]> {
    let at = crate::perception::closest_frame(clip).min(frames.len().saturating_sub(1));
    let dir = frames
        .get(at)
        .and_then(|f| Vector3::new(f[0].x, f[0].y, 0.0).try_normalize(1e-6))
        .unwrap_or_else(Vector3::x);
    frames.iter().map(|f| f.map(|p| p + dir * d)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn deploy() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../deploy")
    }

    #[test]
    fn every_shipped_scenario_builds_with_segments_in_order() {
        let names = scenario_names(&deploy());
        for want in [
            "mission",
            "wave",
            "handshake",
            "handover",
            "high-five",
            "walk-up",
        ] {
            assert!(names.iter().any(|n| n == want), "{want} in {names:?}");
        }
        for name in &names {
            let m = Mission::load(name, &deploy()).unwrap();
            assert_eq!(&m.name, name);
            assert!(!m.segments.is_empty(), "{name}");
            let mut end = 0.0;
            for s in &m.segments {
                assert!(
                    s.start_s >= end && s.end_s > s.start_s + 1.0,
                    "{name}: {s:?}"
                );
                assert!(!s.text.is_empty());
                end = s.end_s;
            }
            assert!((m.duration() - end).abs() < 1e-9, "{name}");
        }
        let m = Mission::load("mission", &deploy()).unwrap();
        let kinds: Vec<_> = m.segments.iter().map(|s| s.interaction).collect();
        assert_eq!(
            kinds,
            [
                Interaction::Handshake,
                Interaction::Handover,
                Interaction::Wave
            ]
        );
        assert_eq!(m.segments[0].source, "test-walk:0");
        // Transitions leave a gap of transition_s between segments.
        let gap = m.segments[1].start_s - m.segments[0].end_s;
        assert!((gap - TRANSITION_S).abs() < 0.05, "{gap}");
        assert_eq!(
            m.segment_at(m.segments[1].start_s + 0.1),
            Some(&m.segments[1])
        );
        assert_eq!(
            m.segment_at(m.segments[1].start_s - 0.1),
            Some(&m.segments[0])
        );
    }

    #[test]
    fn a_scenario_file_is_checked_before_it_is_played() {
        let err = Mission::load("dance", &deploy()).unwrap_err().to_string();
        assert!(
            err.contains("unknown scenario 'dance'") && err.contains("handshake"),
            "{err}"
        );
        let parse = |text: &str| -> Result<Mission, MissionError> {
            let spec: MissionSpec =
                serde_json::from_str(text).map_err(|source| MissionError::Parse {
                    path: "t.json".into(),
                    source,
                })?;
            Mission::from_spec("t", &spec)
        };
        let ok = r#"{"description": "d", "interactions": [{"interaction": "wave", "clip": "standing"}]}"#;
        assert!(parse(ok).is_ok());
        for (text, what) in [
            // A misspelt field is an error, not ignored.
            (
                r#"{"description": "d", "interactions": [{"interaction": "wave", "clip": "standing", "hold": 3}]}"#,
                "unknown field",
            ),
            (
                r#"{"description": "d", "interactions": [{"interaction": "dance", "clip": "standing"}]}"#,
                "unknown variant",
            ),
            (
                r#"{"description": "d", "interactions": []}"#,
                "no interactions",
            ),
            // No walking clip of a wave exists.
            (
                r#"{"description": "d", "interactions": [{"interaction": "wave", "clip": "walking"}]}"#,
                "no Walking clip",
            ),
            (
                r#"{"description": "d", "interactions": [{"interaction": "wave", "clip": "standing", "standoff_m": -1}]}"#,
                "standoff_m",
            ),
            (
                r#"{"description": "d", "interactions": [{"interaction": "wave", "clip": "standing", "hold_s": 1e9}]}"#,
                "hold_s",
            ),
            (
                r#"{"description": "d", "transition_s": 0, "interactions": [{"interaction": "wave", "clip": "standing"}]}"#,
                "transition_s",
            ),
        ] {
            let err = parse(text).unwrap_err().to_string();
            assert!(err.contains(what), "{text}: {err}");
        }
    }

    #[test]
    fn hold_and_take_change_the_partner_as_described() {
        let one = |extra: &str| {
            let text = format!(
                r#"{{"description": "d", "interactions": [{{"interaction": "handshake", "clip": "standing"{extra}}}]}}"#
            );
            Mission::from_spec("t", &serde_json::from_str(&text).unwrap()).unwrap()
        };
        let (plain, held) = (one(""), one(r#", "hold_s": 2.0"#));
        assert!((held.duration() - plain.duration() - 2.0).abs() < 0.1);
        let other = one(r#", "take": 1"#);
        assert_eq!(plain.segments[0].source, "test:0");
        assert_eq!(other.segments[0].source, format!("test:{}", KINDS.len()));
        assert_ne!(plain.partner_at(0.5)[0], other.partner_at(0.5)[0]);
    }

    #[test]
    fn the_partner_moves_continuously_across_transitions() {
        let m = Mission::load("mission", &deploy()).unwrap();
        let dt = 1.0 / FPS;
        let mut t = 0.0;
        let mut worst: f64 = 0.0;
        while t + dt <= m.duration() {
            let (a, b) = (m.partner_at(t), m.partner_at(t + dt));
            worst = worst.max((a[0] - b[0]).norm() / dt);
            t += dt;
        }
        // No jump of the pelvis faster than a brisk walk.
        assert!(worst < 2.5, "pelvis speed {worst} m/s");
    }
}
