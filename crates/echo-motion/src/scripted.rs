//! Scripted single-person motions: a person who stands, walks, waves or offers a handshake,
//! built from arm directions and gait phases through the skeleton's forward kinematics.
//! The mock perception publisher replays these; tests use them as ground truth.

use std::f64::consts::PI;

use nalgebra::Vector3;

use crate::posing::{pose, Intent};
use crate::skeleton::{forward, j, Body, Pose, NUM_JOINTS};

/// What a person does during one segment of a script.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Action {
    /// Stand with arms down.
    Stand,
    /// Walk along the facing direction at `speed` m/s.
    Walk {
        /// Speed, m/s.
        speed: f64,
    },
    /// Wave with the right (or left) hand at 1.5 Hz.
    Wave {
        /// True for the right hand.
        right: bool,
    },
    /// Hold the right (or left) hand out for a handshake.
    OfferHand {
        /// True for the right hand.
        right: bool,
    },
}

/// One timed segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// Duration, seconds.
    pub duration: f64,
    /// What happens.
    pub action: Action,
}

/// A person following a script from a start position and heading.
#[derive(Debug, Clone)]
pub struct ScriptedPerson {
    /// Body proportions.
    pub body: Body,
    /// Start pelvis position on the floor plane (z is set from the body).
    pub start: Vector3<f64>,
    /// Facing direction (yaw about z).
    pub yaw: f64,
    /// Segments played in order; the last one holds.
    pub segments: Vec<Segment>,
}

/// Seconds over which arm targets blend from one action to the next.
const BLEND_S: f64 = 0.5;

impl ScriptedPerson {
    /// Total script length.
    pub fn duration(&self) -> f64 {
        self.segments.iter().map(|s| s.duration).sum()
    }

    /// Segment index and time within it at `t` (clamped into the last segment).
    fn segment_at(&self, t: f64) -> (usize, f64) {
        let mut t0 = 0.0;
        for (i, s) in self.segments.iter().enumerate() {
            if t < t0 + s.duration || i + 1 == self.segments.len() {
                return (i, t - t0);
            }
            t0 += s.duration;
        }
        (0, t)
    }

    /// Distance walked by time `t`.
    fn walked(&self, t: f64) -> f64 {
        let mut t0 = 0.0;
        let mut d = 0.0;
        for s in &self.segments {
            let dt = (t - t0).clamp(0.0, s.duration);
            if let Action::Walk { speed } = s.action {
                d += speed * dt;
            }
            t0 += s.duration;
        }
        d
    }

    /// The pose at time `t` (seconds from the start of the script).
    pub fn pose_at(&self, t: f64) -> Pose {
        let (i, ts) = self.segment_at(t.max(0.0));
        let action = self
            .segments
            .get(i)
            .map(|s| s.action)
            .unwrap_or(Action::Stand);
        let prev = if i > 0 {
            self.segments[i - 1].action
        } else {
            Action::Stand
        };
        let w = smoothstep((ts / BLEND_S).clamp(0.0, 1.0));

        let walked = self.walked(t);
        let fwd = Vector3::new(self.yaw.cos(), self.yaw.sin(), 0.0);
        let root = self.start + fwd * walked;
        let mut it = Intent::standing(root.x, root.y, self.yaw);
        // Arms: blend the directions of the previous and the current action, as hand targets.
        for right in [false, true] {
            let (u0, f0) = arm_dirs(prev, right, t);
            let (u1, f1) = arm_dirs(action, right, t);
            let (l1, l2) = arm_segments(&self.body, right);
            let target = u0.lerp(&u1, w).normalize() * l1 + f0.lerp(&f1, w).normalize() * l2;
            if right {
                it.right_hand = Some(target);
            } else {
                it.left_hand = Some(target);
            }
        }
        // Legs: the gait of the shared posing, phase driven by the distance walked.
        let walking = |a: Action| matches!(a, Action::Walk { .. });
        let gait =
            if walking(action) { w } else { 0.0 } + if walking(prev) { 1.0 - w } else { 0.0 };
        it.gait = (PI * walked / crate::synth::STEP_M, gait);
        // A little idle sway so a standing person is never perfectly still.
        it.spine_pitch = 0.02 * (0.7 * t).sin();
        pose(&self.body, &it)
    }

    /// Joint positions at time `t`.
    pub fn joints_at(&self, t: f64) -> [Vector3<f64>; NUM_JOINTS] {
        forward(&self.body, &self.pose_at(t))
    }
}

fn smoothstep(x: f64) -> f64 {
    x * x * (3.0 - 2.0 * x)
}

fn arm_segments(body: &Body, right: bool) -> (f64, f64) {
    let (e, w) = if right {
        (j::R_ELBOW, j::R_WRIST)
    } else {
        (j::L_ELBOW, j::L_WRIST)
    };
    (body.offsets[e].norm(), body.offsets[w].norm())
}

/// Upper-arm and forearm directions in the body frame (x forward, y left, z up).
fn arm_dirs(action: Action, right: bool, t: f64) -> (Vector3<f64>, Vector3<f64>) {
    let side = if right { -1.0 } else { 1.0 };
    let down = (
        Vector3::new(0.0, 0.12 * side, -1.0),
        Vector3::new(0.08, 0.08 * side, -1.0),
    );
    match action {
        Action::Wave { right: r } if r == right => {
            let swing = 0.45 * (2.0 * PI * 1.5 * t).sin();
            (
                Vector3::new(0.25, 0.9 * side, 0.15),
                Vector3::new(0.15, (0.15 + swing) * side, 1.0),
            )
        }
        Action::OfferHand { right: r } if r == right => (
            Vector3::new(0.55, 0.15 * side, -0.8),
            Vector3::new(1.0, -0.05 * side, 0.05),
        ),
        _ => down,
    }
}

/// The demo's partner: starts 3 m in front of the robot facing it, walks to 1.2 m, waves,
/// offers a handshake, lowers the arm and stands.
pub fn demo_partner(height_m: f64) -> ScriptedPerson {
    ScriptedPerson {
        body: Body::with_height(height_m),
        start: Vector3::new(3.0, 0.1, 0.0),
        yaw: PI,
        segments: vec![
            Segment {
                duration: 1.0,
                action: Action::Stand,
            },
            Segment {
                duration: 2.25,
                action: Action::Walk { speed: 0.8 },
            },
            Segment {
                duration: 0.75,
                action: Action::Stand,
            },
            Segment {
                duration: 3.0,
                action: Action::Wave { right: true },
            },
            Segment {
                duration: 1.0,
                action: Action::Stand,
            },
            Segment {
                duration: 3.0,
                action: Action::OfferHand { right: true },
            },
            Segment {
                duration: 2.0,
                action: Action::Stand,
            },
        ],
    }
}

/// A bystander who walks across the scene 2.5 m in front of the robot, never facing it.
pub fn bystander(height_m: f64) -> ScriptedPerson {
    ScriptedPerson {
        body: Body::with_height(height_m),
        start: Vector3::new(2.8, 2.5, 0.0),
        yaw: -PI / 2.0,
        segments: vec![Segment {
            duration: 60.0,
            action: Action::Walk { speed: 0.4 },
        }],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::PARENTS;

    #[test]
    fn partner_approaches_and_raises_the_hand_to_wave() {
        let p = demo_partner(1.75);
        let start = p.joints_at(0.0);
        let near = p.joints_at(4.0);
        assert!((start[0].x - 3.0).abs() < 1e-9);
        assert!((near[0].x - 1.2).abs() < 0.01, "{}", near[0].x);
        let waving = p.joints_at(5.5);
        assert!(
            waving[j::R_WRIST].z > waving[j::HEAD].z,
            "wrist above head while waving"
        );
        let offering = p.joints_at(9.5);
        // Hand held out toward the robot (the person faces -x), around waist height.
        assert!(offering[j::R_WRIST].x < offering[0].x - 0.3);
        assert!((offering[j::R_WRIST].z - 1.0).abs() < 0.25);
    }

    #[test]
    fn bone_lengths_stay_constant() {
        let p = demo_partner(1.6);
        let lengths = |q: &[Vector3<f64>; NUM_JOINTS]| {
            (1..NUM_JOINTS)
                .map(|k| (q[k] - q[PARENTS[k] as usize]).norm())
                .collect::<Vec<_>>()
        };
        let l0 = lengths(&p.joints_at(0.0));
        for i in 0..200 {
            let li = lengths(&p.joints_at(i as f64 * 0.07));
            for (a, b) in l0.iter().zip(&li) {
                assert!((a - b).abs() < 1e-9);
            }
        }
    }
}
