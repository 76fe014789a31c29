//! One joint's discrete jerk-limited motion.
//!
//! State (q, v, a) advances by `a' = a + j·dt`, `v' = v + a'·dt`, `q' = q + v'·dt` with
//! |j| ≤ J, |a| ≤ A, |v| ≤ V. The braking law drives (v, a) to rest along the switching curve
//! `a* = −sign(v)·min(A, √(2J|v|), |v|/2dt)`; it is a state feedback, so the braking trajectory from any
//! state on it is the tail of the braking trajectory before it — which makes "a stop inside the
//! limits exists" an invariant that one simulation per cycle can keep.

use echo_robot::limits::JointKinematicLimits;

/// Position, velocity, acceleration.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointState1 {
    /// Position.
    pub q: f64,
    /// Velocity.
    pub v: f64,
    /// Acceleration.
    pub a: f64,
}

impl JointState1 {
    /// At rest at `q`.
    pub fn rest(q: f64) -> Self {
        JointState1 { q, v: 0.0, a: 0.0 }
    }

    /// Whether at rest.
    pub fn is_rest(&self) -> bool {
        self.v == 0.0 && self.a == 0.0
    }
}

/// Advance with acceleration `a_next` (already limited).
pub fn integrate(s: JointState1, a_next: f64, dt: f64) -> JointState1 {
    let v = s.v + a_next * dt;
    JointState1 {
        q: s.q + v * dt,
        v,
        a: a_next,
    }
}

/// A braking joint snaps to rest when |v| ≤ 0.6·J·dt² and |a| ≤ 0.4·J·dt: the implied
/// acceleration |v|/dt and the change from `a` to it stay within one jerk step (J·dt), and the
/// discrete braking law's residual oscillation (±0.5·J·dt²) is caught.
fn snaps_to_rest(s: &JointState1, l: &JointKinematicLimits, dt: f64) -> bool {
    s.v.abs() <= 0.6 * l.jerk * dt * dt && s.a.abs() <= 0.4 * l.jerk * dt
}

/// One step of the braking law.
pub fn brake_step(s: JointState1, l: &JointKinematicLimits, dt: f64) -> JointState1 {
    if snaps_to_rest(&s, l, dt) {
        return JointState1::rest(s.q + s.v * dt * 0.5);
    }
    // Near rest the curve becomes linear (a* = −v/2dt: velocity halves each step), which the
    // discrete law follows without chattering across zero.
    let target = -s.v.signum()
        * l.acceleration
            .min((2.0 * l.jerk * s.v.abs()).sqrt())
            .min(s.v.abs() / (2.0 * dt));
    let step = (target - s.a).clamp(-l.jerk * dt, l.jerk * dt);
    let a = (s.a + step).clamp(-l.acceleration, l.acceleration);
    integrate(s, a, dt)
}

/// Longest braking simulation, in steps (10 s at 50 Hz: far beyond any real stop).
const MAX_BRAKE_STEPS: usize = 500;

/// Simulate braking from `s`; `Some((final position, steps))` if it comes to rest with every
/// position inside `[lo, hi]`, `None` otherwise.
pub fn brake_sim(
    s: JointState1,
    l: &JointKinematicLimits,
    lo: f64,
    hi: f64,
    dt: f64,
) -> Option<(f64, usize)> {
    let mut x = s;
    for k in 0..MAX_BRAKE_STEPS {
        if x.q < lo - 1e-12 || x.q > hi + 1e-12 {
            return None;
        }
        if x.is_rest() {
            return Some((x.q, k));
        }
        x = brake_step(x, l, dt);
    }
    None
}

/// Largest acceleration that keeps the velocity peak `v + a|a|/(2J)` (plus one step of
/// discretisation) within `vmax` — and its mirror for the lower bound.
pub fn velocity_peak_bounds(
    s: JointState1,
    l: &JointKinematicLimits,
    vmax: f64,
    dt: f64,
) -> (f64, f64) {
    let hi = peak_bound(s.v, l.jerk, vmax, dt);
    let lo = -peak_bound(-s.v, l.jerk, vmax, dt);
    (lo, hi)
}

/// Largest a with v + a·dt + a²/(2J) + a·dt ≤ vmax (for a ≥ 0); negative when v is already
/// beyond the bound (then the joint must decelerate).
fn peak_bound(v: f64, j: f64, vmax: f64, dt: f64) -> f64 {
    let room = vmax - v;
    if room <= 0.0 {
        return room / dt;
    }
    // a²/(2J) + 2·dt·a − room = 0
    let b = 2.0 * dt;
    j * (-b + (b * b + 2.0 * room / j).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    const L: JointKinematicLimits = JointKinematicLimits {
        lower: -1.0,
        upper: 1.0,
        velocity: 2.0,
        acceleration: 1.5,
        jerk: 7.5,
    };

    #[test]
    fn braking_comes_to_rest_within_limits() {
        let dt = 0.02;
        // States inside the invariant v + a|a|/2J ≤ V.
        for (v, a) in [(1.0, 0.0), (-1.9, 1.5), (0.3, 1.5), (1.7, 1.5), (0.0, -1.2)] {
            let mut s = JointState1 { q: 0.0, v, a };
            let mut steps = 0;
            while !s.is_rest() {
                let n = brake_step(s, &L, dt);
                assert!((n.a - s.a).abs() <= L.jerk * dt + 1e-9, "jerk at {s:?}");
                assert!(n.a.abs() <= L.acceleration + 1e-9);
                assert!(
                    n.v.abs() <= L.velocity + 1e-9,
                    "velocity {n:?} from {v},{a}"
                );
                s = n;
                steps += 1;
                assert!(steps < 300, "no stop from {v},{a}");
            }
        }
    }

    #[test]
    fn feasibility_detects_a_wall() {
        let dt = 0.02;
        let s = JointState1 {
            q: 0.9,
            v: 1.5,
            a: 0.0,
        };
        assert!(brake_sim(s, &L, -1.0, 1.0, dt).is_none());
        let s = JointState1 {
            q: 0.0,
            v: 1.5,
            a: 0.0,
        };
        let (q, _) = brake_sim(s, &L, -1.0, 1.0, dt).unwrap();
        assert!(q > 0.5 && q < 1.0, "{q}");
    }
}

#[cfg(test)]
mod convergence {
    use super::*;

    /// Every state on a grid around rest (where a discrete law is most likely to chatter)
    /// comes to rest.
    #[test]
    fn braking_reaches_rest_from_every_small_state() {
        let l = JointKinematicLimits {
            lower: -1.0,
            upper: 1.0,
            velocity: 1.0,
            acceleration: 2.0,
            jerk: 10.0,
        };
        let mut bad = 0;
        for i in 0..50 {
            for k in 0..50 {
                let s = JointState1 {
                    q: 0.0,
                    v: -0.1 + 0.004 * i as f64,
                    a: -0.5 + 0.02 * k as f64,
                };
                if brake_sim(s, &l, -10.0, 10.0, 0.02).is_none() {
                    eprintln!("no stop from {s:?}");
                    bad += 1;
                }
            }
        }
        assert_eq!(bad, 0);
    }
}
