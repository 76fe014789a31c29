//! Scripted human–robot missions: the partner the robot meets in the demo and the system tests.
//!
//! A mission is a sequence of generated interactions (the test split of `echo_motion::synth`)
//! in which the robot plays person B: each clip's person A is placed in the robot's frame with
//! the robot standing where B stood when the two were closest
//! ([`crate::perception::clip_partner_for_robot`]). Between two interactions the partner moves
//! from the last pose of one to the first of the next over [`TRANSITION_S`] (joint positions
//! blended with a smoothstep). Each interaction is a [`Segment`] with its description and type,
//! which the demo announces on `prompt` while it plays and scores afterwards.
//!
//! The partner stands [`STANDOFF_M`] further from the robot than they stood from person B (moved
//! along the line from the robot to where they were at the closest moment): the robot's base,
//! torso and shoulder mounts are deeper than a person's chest, and where B stood, the
//! partner's torso would already be inside the robot's body clearance.
//!
//! In a handshake, a high five or a handover the partner holds the hand out for [`HOLD_S`] at
//! its furthest from their body (the clip's pose at that moment is held): a person offering a
//! robot their hand waits for it, and the robot's arm, slowed near people by the safety
//! service's contact speed, needs longer than person B did.
//!
//! | name | interactions |
//! |---|---|
//! | `mission` | walk up and shake hands (a walking clip), hand an object over, wave goodbye |
//! | `wave`, `handshake`, `handover`, `high-five` | that one interaction (a standing clip) |
//! | `walk-up` | walk up and shake hands |

use echo_motion::skeleton::NUM_JOINTS;
use echo_motion::synth::{self, Clip, Split, FPS, KINDS, WALKING_KINDS};
use echo_msgs::Interaction;
use nalgebra::Vector3;

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

/// Every mission name [`Mission::named`] knows.
pub const MISSIONS: [&str; 6] = [
    "mission",
    "wave",
    "handshake",
    "handover",
    "high-five",
    "walk-up",
];

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
    /// The clip it comes from (`test:<i>` or `test-walk:<i>`).
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

/// Which clip of the test split.
#[derive(Debug, Clone, Copy)]
enum Source {
    Standing(Interaction),
    Walking(Interaction),
}

impl Source {
    fn clip(self) -> (Clip, String) {
        let find = |kinds: &[Interaction], k: Interaction| {
            kinds.iter().position(|x| *x == k).unwrap_or(0) as u64
        };
        match self {
            Source::Standing(k) => {
                let i = find(&KINDS, k);
                (synth::generate(&Split::Test.clip(i)), format!("test:{i}"))
            }
            Source::Walking(k) => {
                let i = find(&WALKING_KINDS, k);
                (
                    synth::generate(&Split::Test.walking_clip(i)),
                    format!("test-walk:{i}"),
                )
            }
        }
    }
}

impl Mission {
    /// A mission by name ([`MISSIONS`]).
    pub fn named(name: &str) -> Result<Mission, String> {
        use Interaction::*;
        let sources = match name {
            "mission" => vec![
                Source::Walking(Handshake),
                Source::Standing(Handover),
                Source::Standing(Wave),
            ],
            "wave" => vec![Source::Standing(Wave)],
            "handshake" => vec![Source::Standing(Handshake)],
            "handover" => vec![Source::Standing(Handover)],
            "high-five" => vec![Source::Standing(HighFive)],
            "walk-up" => vec![Source::Walking(Handshake)],
            other => {
                return Err(format!(
                    "unknown scenario '{other}' (one of: {})",
                    MISSIONS.join(", ")
                ))
            }
        };
        let clips: Vec<(Clip, String)> = sources.into_iter().map(Source::clip).collect();
        Ok(Mission::from_clips(name, &clips))
    }

    /// A mission of these clips (and their sources' names), in order.
    pub fn from_clips(name: &str, clips: &[(Clip, String)]) -> Mission {
        let mut frames: Vec<[Vector3<f64>; NUM_JOINTS]> = vec![];
        let mut segments = vec![];
        for (clip, source) in clips {
            let Some(Actor::Recorded(person)) = clip_partner_for_robot(clip).into_iter().next()
            else {
                continue;
            };
            let away = match clip.params.kind {
                Interaction::Wave => WAVE_STANDOFF_M,
                _ => STANDOFF_M,
            };
            let mut next = standoff(person.frames(), clip, away);
            if matches!(
                clip.params.kind,
                Interaction::Handshake | Interaction::HighFive | Interaction::Handover
            ) {
                hold_offer(&mut next, HOLD_S);
            }
            let next = next.as_slice();
            if let (Some(last), Some(first)) = (frames.last().copied(), next.first()) {
                let n = (TRANSITION_S * FPS).round() as usize;
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

    #[test]
    fn every_named_mission_builds_with_segments_in_order() {
        for name in MISSIONS {
            let m = Mission::named(name).unwrap();
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
        assert!(Mission::named("dance").is_err());
        let m = Mission::named("mission").unwrap();
        let kinds: Vec<_> = m.segments.iter().map(|s| s.interaction).collect();
        assert_eq!(
            kinds,
            [
                Interaction::Handshake,
                Interaction::Handover,
                Interaction::Wave
            ]
        );
        // Transitions leave a gap of TRANSITION_S between segments.
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
    fn the_partner_moves_continuously_across_transitions() {
        let m = Mission::named("mission").unwrap();
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
