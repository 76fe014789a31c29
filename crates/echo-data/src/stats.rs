//! Motion statistics of a set of captures, to set synthetic data beside real data.
//!
//! Per person and frame at 30 Hz (velocities by central differences over 1/15 s, so that the
//! numbers match the forecaster's rate): root (pelvis) speed on the floor plane and its
//! acceleration, mean joint speed relative to the root, arm swing (peak-to-peak of each wrist
//! along the person's facing direction, relative to the pelvis, per second window, averaged),
//! inter-person distance (pelvis to pelvis), and the contact rate (share of frames where a
//! wrist of one person is within 0.15 m of any joint of the other).

use echo_motion::skeleton::{heading, NUM_JOINTS};
use echo_motion::synth::{Clip, FPS};
use nalgebra::Vector3;

use crate::source::Capture;

/// Distribution summary.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Mean.
    pub mean: f64,
    /// Median.
    pub median: f64,
    /// 90th percentile.
    pub p90: f64,
    /// Maximum.
    pub max: f64,
}

impl Summary {
    fn of(mut v: Vec<f64>) -> Summary {
        v.retain(|x| x.is_finite());
        if v.is_empty() {
            return Summary {
                mean: f64::NAN,
                median: f64::NAN,
                p90: f64::NAN,
                max: f64::NAN,
            };
        }
        v.sort_by(|a, b| a.total_cmp(b));
        let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
        Summary {
            mean: v.iter().sum::<f64>() / v.len() as f64,
            median: q(0.5),
            p90: q(0.9),
            max: v[v.len() - 1],
        }
    }
}

/// Statistics of a set of captures.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MotionStats {
    /// Captures.
    pub captures: usize,
    /// Total duration, s.
    pub seconds: f64,
    /// Root speed on the floor, m/s.
    pub root_speed: Summary,
    /// Share of person-frames with the root faster than 0.3 m/s (walking or more).
    pub moving_share: f64,
    /// Root acceleration on the floor, m/s².
    pub root_acc: Summary,
    /// Mean joint speed relative to the root, m/s.
    pub joint_speed: Summary,
    /// Wrist swing along the facing direction, peak-to-peak per 1 s, m.
    pub arm_swing: Summary,
    /// Pelvis-to-pelvis distance, m.
    pub distance: Summary,
    /// Share of frames with a wrist within 0.15 m of the other person.
    pub contact_rate: f64,
}

fn joints(c: &Clip, f: usize, p: usize) -> [Vector3<f64>; NUM_JOINTS] {
    c.joints(f, p)
}

/// Statistics of `captures`.
pub fn motion_stats(captures: &[Capture]) -> MotionStats {
    let (mut speed, mut acc, mut jspeed, mut swing, mut dist) =
        (vec![], vec![], vec![], vec![], vec![]);
    let (mut contact, mut frames_total, mut seconds) = (0usize, 0usize, 0.0);
    let k = (FPS / 15.0).round() as usize; // 2 frames at 30 Hz
    let dt = k as f64 / FPS;
    for cap in captures {
        let c = &cap.clip;
        let n = c.frames.len();
        seconds += n as f64 / FPS;
        for f in 0..n {
            let a = joints(c, f, 0);
            let b = joints(c, f, 1);
            frames_total += 1;
            dist.push((a[0] - b[0]).xy().norm());
            let touch = |x: &[Vector3<f64>; NUM_JOINTS], y: &[Vector3<f64>; NUM_JOINTS]| {
                [20, 21]
                    .iter()
                    .any(|&w| y.iter().any(|j| (x[w] - j).norm() < 0.15))
            };
            if touch(&a, &b) || touch(&b, &a) {
                contact += 1;
            }
        }
        for p in 0..2 {
            let root: Vec<Vector3<f64>> = (0..n).map(|f| joints(c, f, p)[0]).collect();
            let vel: Vec<Vector3<f64>> = (k..n.saturating_sub(k))
                .map(|f| (root[f + k] - root[f - k]) / (2.0 * dt))
                .collect();
            speed.extend(vel.iter().map(|v| v.xy().norm()));
            acc.extend(
                (k..vel.len().saturating_sub(k))
                    .map(|i| ((vel[i + k] - vel[i - k]) / (2.0 * dt)).xy().norm()),
            );
            for f in k..n.saturating_sub(k) {
                let (j0, j1) = (joints(c, f - k, p), joints(c, f + k, p));
                let m = (0..NUM_JOINTS)
                    .map(|j| ((j1[j] - j1[0]) - (j0[j] - j0[0])).norm() / (2.0 * dt))
                    .sum::<f64>()
                    / NUM_JOINTS as f64;
                jspeed.push(m);
            }
            // Wrist swing: per 1 s window, peak-to-peak of the wrist along the facing direction.
            let win = FPS as usize;
            let mut s = 0;
            while s + win <= n {
                for w in [20, 21] {
                    let along: Vec<f64> = (s..s + win)
                        .map(|f| {
                            let j = joints(c, f, p);
                            let fwd = heading(&j) * Vector3::x();
                            (j[w] - j[0]).dot(&fwd)
                        })
                        .collect();
                    let hi = along.iter().cloned().fold(f64::MIN, f64::max);
                    let lo = along.iter().cloned().fold(f64::MAX, f64::min);
                    swing.push(hi - lo);
                }
                s += win;
            }
        }
    }
    let moving = speed.iter().filter(|v| **v > 0.3).count() as f64 / speed.len().max(1) as f64;
    MotionStats {
        captures: captures.len(),
        seconds,
        root_speed: Summary::of(speed),
        moving_share: moving,
        root_acc: Summary::of(acc),
        joint_speed: Summary::of(jspeed),
        arm_swing: Summary::of(swing),
        distance: Summary::of(dist),
        contact_rate: contact as f64 / frames_total.max(1) as f64,
    }
}

/// A markdown table of `sets` (name, stats) side by side.
pub fn markdown(sets: &[(String, MotionStats)]) -> String {
    let mut s = String::from("| statistic |");
    for (n, _) in sets {
        s.push_str(&format!(" {n} |"));
    }
    s.push_str("\n|---|");
    s.push_str(&"---|".repeat(sets.len()));
    s.push('\n');
    let sum = |x: &Summary| format!("{:.2} / {:.2} / {:.2}", x.median, x.p90, x.max);
    type Cell<'a> = Box<dyn Fn(&MotionStats) -> String + 'a>;
    let rows: Vec<(&str, Cell)> = vec![
        (
            "captures, seconds",
            Box::new(|m: &MotionStats| format!("{}, {:.0}", m.captures, m.seconds)),
        ),
        (
            "root speed m/s (median / p90 / max)",
            Box::new(move |m: &MotionStats| sum(&m.root_speed)),
        ),
        (
            "share of time walking (> 0.3 m/s)",
            Box::new(|m: &MotionStats| format!("{:.0} %", 100.0 * m.moving_share)),
        ),
        (
            "root acceleration m/s² (median / p90 / max)",
            Box::new(move |m: &MotionStats| sum(&m.root_acc)),
        ),
        (
            "joint speed rel. to root m/s (median / p90 / max)",
            Box::new(move |m: &MotionStats| sum(&m.joint_speed)),
        ),
        (
            "arm swing m per s (median / p90 / max)",
            Box::new(move |m: &MotionStats| sum(&m.arm_swing)),
        ),
        (
            "inter-person distance m (median / p90 / max)",
            Box::new(move |m: &MotionStats| sum(&m.distance)),
        ),
        (
            "contact rate (wrist within 0.15 m)",
            Box::new(|m: &MotionStats| format!("{:.1} %", 100.0 * m.contact_rate)),
        ),
    ];
    for (name, f) in rows {
        s.push_str(&format!("| {name} |"));
        for (_, m) in sets {
            s.push_str(&format!(" {} |", f(m)));
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use echo_motion::synth::{generate, Split};

    fn cap(clip: Clip) -> Capture {
        Capture {
            name: "t".into(),
            source: "synthetic",
            real: false,
            clip,
            report: None,
        }
    }

    #[test]
    fn a_walk_past_moves_and_a_standing_wave_does_not() {
        // Find one clip of each kind in the test split.
        let mut walk = None;
        let mut wave = None;
        for i in 0..40 {
            let p = Split::Test.clip(i);
            match p.kind {
                echo_msgs::Interaction::WalkPast if walk.is_none() => walk = Some(generate(&p)),
                echo_msgs::Interaction::Wave if wave.is_none() => wave = Some(generate(&p)),
                _ => {}
            }
        }
        let w = motion_stats(&[cap(walk.unwrap())]);
        let s = motion_stats(&[cap(wave.unwrap())]);
        assert!(w.root_speed.median > 0.5, "{w:?}");
        assert!(s.root_speed.median < w.root_speed.median);
        assert!(w.moving_share > s.moving_share);
        let t = markdown(&[("walk".into(), w), ("wave".into(), s)]);
        assert!(t.contains("| root speed m/s"));
    }
}
