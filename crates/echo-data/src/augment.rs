//! Augmentations of a capture for training: role swap, mirror, speed, proportions.
//!
//! * role swap: person B becomes A — the model must not depend on who is called A;
//! * mirror: reflect across the x–z plane and exchange left and right joints;
//! * speed: resample time by a factor (0.8 = slower, 1.25 = faster), linear in position;
//! * proportions: scale each person about the floor point under their pelvis.
//!
//! Role swap, mirror and speed change what a description says (who starts, which hand, how
//! fast) for the generator's role-naming descriptions, so they are applied to real captures
//! only; proportions apply to every capture.

use echo_motion::skeleton::MIRROR;
use echo_motion::synth::Clip;

/// Which augmented copies to make.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Augment {
    /// Add the role-swapped copy.
    pub swap: bool,
    /// Add the mirrored copy (of the original and the swapped one).
    pub mirror: bool,
    /// Time factors, each adding resampled copies (empty: none).
    pub speeds: &'static [f64],
    /// Proportion factors, each adding a scaled copy.
    pub scales: &'static [f64],
}

impl Augment {
    /// Every augmentation (the training default).
    pub const ALL: Augment = Augment {
        swap: true,
        mirror: true,
        speeds: &[0.8, 1.25],
        scales: &[0.93, 1.07],
    };
    /// None.
    pub const NONE: Augment = Augment {
        swap: false,
        mirror: false,
        speeds: &[],
        scales: &[],
    };
}

/// A and B exchanged.
pub fn swap(c: &Clip) -> Clip {
    let mut o = c.clone();
    for f in &mut o.frames {
        f.swap(0, 1);
    }
    o.bodies.swap(0, 1);
    o.params.heights.swap(0, 1);
    o
}

/// Mirrored across the x–z plane, left and right exchanged.
pub fn mirror(c: &Clip) -> Clip {
    let mut o = c.clone();
    for f in &mut o.frames {
        for p in f.iter_mut() {
            let src = *p;
            for (j, m) in MIRROR.iter().enumerate() {
                p[j] = [src[*m][0], -src[*m][1], src[*m][2]];
            }
        }
    }
    o
}

/// Resampled so that motion runs `factor` times as fast.
pub fn speed(c: &Clip, factor: f64) -> Clip {
    let mut o = c.clone();
    let n = c.frames.len();
    if n < 2 || factor <= 0.0 {
        return o;
    }
    let m = (((n - 1) as f64) / factor).floor() as usize + 1;
    o.frames = (0..m)
        .map(|i| {
            let t = i as f64 * factor;
            let a = (t.floor() as usize).min(n - 1);
            let b = (a + 1).min(n - 1);
            let w = (t - a as f64) as f32;
            let mut f = c.frames[a];
            for (p, fp) in f.iter_mut().enumerate() {
                for (j, x) in fp.iter_mut().enumerate() {
                    let (xa, xb) = (c.frames[a][p][j], c.frames[b][p][j]);
                    for (k, v) in x.iter_mut().enumerate() {
                        *v += w * (xb[k] - xa[k]);
                    }
                }
            }
            f
        })
        .collect();
    o
}

/// Each person scaled by `factor` about the floor point under their pelvis.
pub fn proportions(c: &Clip, factor: f64) -> Clip {
    let mut o = c.clone();
    let s = factor as f32;
    for f in &mut o.frames {
        for p in f.iter_mut() {
            let (x0, y0) = (p[0][0], p[0][1]);
            for x in p.iter_mut() {
                x[0] = x0 + (x[0] - x0) * s;
                x[1] = y0 + (x[1] - y0) * s;
                x[2] *= s;
            }
        }
    }
    o.params.heights = o.params.heights.map(|h| h * factor);
    o
}

/// The capture and its augmented copies under `a` (`real`: whether role, side and timing
/// augmentations apply).
pub fn expand(c: &Clip, real: bool, a: &Augment) -> Vec<Clip> {
    let mut out = vec![c.clone()];
    if real {
        if a.swap {
            out.push(swap(c));
        }
        if a.mirror {
            let m: Vec<Clip> = out.iter().map(mirror).collect();
            out.extend(m);
        }
        let base = out.clone();
        for &f in a.speeds {
            out.extend(base.iter().map(|x| speed(x, f)));
        }
    }
    let base = out.clone();
    for &f in a.scales {
        out.extend(base.iter().take(2).map(|x| proportions(x, f)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use echo_motion::skeleton::NUM_JOINTS;
    use echo_motion::synth::{generate, Split};

    #[test]
    fn swap_and_mirror_are_involutions_and_mirror_keeps_distances() {
        let c = generate(&Split::Test.clip(2));
        assert_eq!(swap(&swap(&c)).frames, c.frames);
        assert_eq!(mirror(&mirror(&c)).frames, c.frames);
        let m = mirror(&c);
        let d = |f: &[[f32; 3]; NUM_JOINTS], a: usize, b: usize| {
            (0..3)
                .map(|k| (f[a][k] - f[b][k]).powi(2))
                .sum::<f32>()
                .sqrt()
        };
        // The left wrist of the mirror is where the right wrist was, reflected.
        let (f0, m0) = (&c.frames[10][0], &m.frames[10][0]);
        assert!((m0[20][1] + f0[21][1]).abs() < 1e-6);
        assert!((d(f0, 20, 21) - d(m0, 20, 21)).abs() < 1e-5);
    }

    #[test]
    fn speed_changes_duration_and_keeps_the_path() {
        let c = generate(&Split::Test.clip(1));
        let fast = speed(&c, 1.25);
        let slow = speed(&c, 0.8);
        assert!(fast.frames.len() < c.frames.len() && slow.frames.len() > c.frames.len());
        assert_eq!(fast.frames[0], c.frames[0]);
        // Frame 4 of the fast copy is frame 5 of the original.
        assert!((fast.frames[4][1][0][0] - c.frames[5][1][0][0]).abs() < 1e-5);
    }

    #[test]
    fn real_captures_get_every_copy_synthetic_only_proportions() {
        let c = generate(&Split::Test.clip(0));
        assert_eq!(expand(&c, true, &Augment::ALL).len(), 4 + 8 + 4);
        assert_eq!(expand(&c, false, &Augment::ALL).len(), 1 + 2);
        assert_eq!(expand(&c, true, &Augment::NONE).len(), 1);
    }
}
