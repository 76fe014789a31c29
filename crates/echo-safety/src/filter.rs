//! Group-coordinated, jerk-limited tracking with a feasible stop always available.
//!
//! Per control step and joint group:
//! 1. desired velocity `v* = v_ref + (q_ref − q)/τ`;
//! 2. velocity: if any joint exceeds `s·V` (s = separation speed scale), all joints of the group
//!    are scaled by the same factor (the path is kept);
//! 3. acceleration: the change `a → a_req = (v* − v)/dt` is taken by one common fraction `f` for
//!    the whole group, the largest that keeps every joint within its jerk, acceleration and
//!    velocity-peak bounds (`v + a|a|/2J ≤ V`: braking the acceleration away never overshoots V);
//! 4. the candidate state is accepted only if the braking law from it comes to rest inside the
//!    position limits for every joint of the group; otherwise the whole group takes a braking
//!    step instead. By induction (the braking law is a state feedback) a stop inside the limits
//!    exists from every state the filter ever commands.

use echo_robot::limits::JointKinematicLimits;

use crate::joint::{brake_sim, brake_step, integrate, velocity_peak_bounds, JointState1};

/// A joint group as the filter sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// Group name (arm_left, …).
    pub name: String,
    /// Controller name.
    pub controller: String,
    /// Indices into the filter's joint list.
    pub joints: Vec<usize>,
}

/// Per-joint reference for the next step: target position and velocity; `None` holds still.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// Target positions.
    pub q: Vec<Option<f64>>,
    /// Target velocities (feed-forward).
    pub v: Vec<f64>,
}

impl Reference {
    /// Hold every joint.
    pub fn hold(n: usize) -> Self {
        Reference {
            q: vec![None; n],
            v: vec![0.0; n],
        }
    }
}

/// What happened to a group in one step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GroupStep {
    /// Tracked the reference unchanged.
    Tracked,
    /// Tracked with velocity or acceleration scaled down.
    Limited,
    /// Braked (asked to, or because tracking would lose the feasible stop).
    Braked,
}

/// The filter.
#[derive(Debug, Clone)]
pub struct Filter {
    joints: Vec<String>,
    limits: Vec<JointKinematicLimits>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    groups: Vec<Group>,
    dt: f64,
    tau: f64,
    state: Vec<JointState1>,
    hard: Vec<(f64, f64)>,
    recovery_scale: f64,
}

impl Filter {
    /// A filter over `joints` (with `limits`) in `groups`, at rest at the lower… set with [`Self::reset_to`].
    pub fn new(
        joints: Vec<String>,
        limits: Vec<JointKinematicLimits>,
        groups: Vec<Group>,
        dt: f64,
        tau: f64,
    ) -> Filter {
        let n = joints.len();
        let lo = limits.iter().map(|l| l.lower).collect();
        let hi = limits.iter().map(|l| l.upper).collect();
        let state = limits
            .iter()
            .map(|l| JointState1::rest(0.0f64.clamp(l.lower, l.upper)))
            .collect();
        debug_assert_eq!(n, limits.len());
        let hard = limits.iter().map(|l| (l.lower, l.upper)).collect();
        Filter {
            joints,
            limits,
            lo,
            hi,
            groups,
            dt,
            tau,
            state,
            hard,
            recovery_scale: 1.0,
        }
    }

    /// The hard position limits (the operating limits are inside them) and the speed scale of
    /// a group while one of its joints is outside its operating range, recovering inward.
    /// Without this call the operating limits are the hard limits.
    pub fn with_hard_limits(mut self, hard: Vec<(f64, f64)>, recovery_scale: f64) -> Filter {
        debug_assert_eq!(hard.len(), self.limits.len());
        self.hard = hard
            .iter()
            .zip(&self.limits)
            .map(|(&(lo, hi), l)| (lo.min(l.lower), hi.max(l.upper)))
            .collect();
        self.recovery_scale = recovery_scale.clamp(0.0, 1.0);
        self
    }

    /// Hard position limits per joint.
    pub fn hard_limits(&self) -> &[(f64, f64)] {
        &self.hard
    }

    /// Joint names.
    pub fn joints(&self) -> &[String] {
        &self.joints
    }

    /// Groups.
    pub fn groups(&self) -> &[Group] {
        &self.groups
    }

    /// Limits per joint.
    pub fn limits(&self) -> &[JointKinematicLimits] {
        &self.limits
    }

    /// Current commanded state per joint.
    pub fn state(&self) -> &[JointState1] {
        &self.state
    }

    /// Control period.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Restart at rest at `q`, clamped into the hard limits (a non-finite value keeps the
    /// current position). A position between the operating and the hard limits widens that
    /// joint's allowed range to include it; the range tightens back as the joint moves inside
    /// (it may only move in, at the recovery speed scale). Never beyond the hard limits.
    pub fn reset_to(&mut self, q: &[f64]) {
        for (i, x) in q.iter().enumerate().take(self.state.len()) {
            let (hlo, hhi) = self.hard[i];
            let x = if x.is_finite() {
                x.clamp(hlo, hhi)
            } else {
                self.state[i].q
            };
            self.state[i] = JointState1::rest(x);
            self.lo[i] = self.limits[i].lower.min(x);
            self.hi[i] = self.limits[i].upper.max(x);
        }
    }

    /// Whether joint `i`'s commanded position is outside its operating range (recovering).
    pub fn outside_operating_range(&self, i: usize) -> bool {
        let q = self.state[i].q;
        q < self.limits[i].lower || q > self.limits[i].upper
    }

    /// Every joint at rest.
    pub fn all_rest(&self) -> bool {
        self.state.iter().all(JointState1::is_rest)
    }

    /// Longest braking time over all joints from the current state, s.
    pub fn stop_time(&self) -> f64 {
        self.state
            .iter()
            .zip(&self.limits)
            .map(|(s, l)| {
                brake_sim(*s, l, f64::NEG_INFINITY, f64::INFINITY, self.dt)
                    .map(|(_, k)| k as f64 * self.dt)
                    .unwrap_or(f64::INFINITY)
                    .max(if s.is_rest() { 0.0 } else { self.dt })
            })
            .fold(0.0, f64::max)
    }

    /// One control step. `scale[g]` ∈ [0, 1] caps group g's speed; `brake[g]` forces a braking step.
    pub fn step(&mut self, r: &Reference, scale: &[f64], brake: &[bool]) -> Vec<GroupStep> {
        let groups = self.groups.clone();
        let mut out = Vec::with_capacity(groups.len());
        for (g, group) in groups.iter().enumerate() {
            let forced = brake.get(g).copied().unwrap_or(true);
            // A scale that is not a number brakes (NaN.clamp would stay NaN).
            let mut s = scale
                .get(g)
                .copied()
                .filter(|s| !s.is_nan())
                .unwrap_or(0.0)
                .clamp(0.0, 1.0);
            if group
                .joints
                .iter()
                .any(|&j| self.outside_operating_range(j))
            {
                s = s.min(self.recovery_scale);
            }
            let result = if forced {
                None
            } else {
                self.track_group(group, r, s)
            };
            match result {
                Some((candidate, limited)) => {
                    for (k, &j) in group.joints.iter().enumerate() {
                        self.state[j] = candidate[k];
                    }
                    out.push(if limited {
                        GroupStep::Limited
                    } else {
                        GroupStep::Tracked
                    });
                }
                None => {
                    for &j in &group.joints {
                        self.state[j] = brake_step(self.state[j], &self.limits[j], self.dt);
                    }
                    out.push(GroupStep::Braked);
                }
            }
            for &j in &group.joints {
                let q = self.state[j].q;
                self.lo[j] = self.lo[j].max(self.limits[j].lower.min(q));
                self.hi[j] = self.hi[j].min(self.limits[j].upper.max(q));
            }
        }
        out
    }

    /// The tracking candidate for a group, or `None` if it would lose the feasible stop.
    fn track_group(
        &self,
        group: &Group,
        r: &Reference,
        s: f64,
    ) -> Option<(Vec<JointState1>, bool)> {
        let dt = self.dt;
        let mut limited = false;
        // 1. desired velocities
        let mut vdes: Vec<f64> = group
            .joints
            .iter()
            .map(|&j| {
                let st = self.state[j];
                match r.q.get(j).copied().flatten().filter(|q| q.is_finite()) {
                    // A target beyond the limits becomes the limit.
                    Some(q_ref) => {
                        let q_ref = q_ref.clamp(self.lo[j], self.hi[j]);
                        let v_ff = if q_ref == self.lo[j] || q_ref == self.hi[j] {
                            0.0
                        } else {
                            r.v.get(j).copied().filter(|v| v.is_finite()).unwrap_or(0.0)
                        };
                        v_ff + (q_ref - st.q) / self.tau
                    }
                    None => 0.0,
                }
            })
            .collect();
        // 2. common velocity scaling
        let mut fv: f64 = 1.0;
        for (k, &j) in group.joints.iter().enumerate() {
            let l = &self.limits[j];
            let q = self.state[j].q;
            // Braking envelope: no faster toward a limit than a stop before it allows.
            let room = if vdes[k] > 0.0 {
                self.hi[j] - q
            } else {
                q - self.lo[j]
            };
            // …and no faster toward the target than a stop at the target allows.
            let to_target =
                r.q.get(j)
                    .copied()
                    .flatten()
                    .filter(|t| t.is_finite())
                    .map_or(0.0, |t| (t.clamp(self.lo[j], self.hi[j]) - q).abs());
            let v_ff = r.v.get(j).copied().filter(|v| v.is_finite()).unwrap_or(0.0);
            let cap = (s * l.velocity)
                .min(envelope_speed(room.max(0.0), l, dt))
                .min(envelope_speed(to_target, l, dt).max(v_ff.abs()));
            if vdes[k].abs() > cap {
                fv = fv.min(cap / vdes[k].abs());
            }
        }
        if fv < 1.0 {
            limited = true;
            for v in &mut vdes {
                *v *= fv;
            }
        }
        // 3. one common fraction of the acceleration change
        let mut lo_f: f64 = 0.0;
        let mut hi_f: f64 = 1.0;
        let mut bounds = Vec::with_capacity(group.joints.len());
        for (k, &j) in group.joints.iter().enumerate() {
            let st = self.state[j];
            let l = &self.limits[j];
            let a_req = (vdes[k] - st.v) / self.velocity_time_constant(l);
            let d = a_req - st.a;
            // Hard set: jerk, acceleration and the velocity peak under V (never empty from a
            // state the filter produced). Soft set: the peak under the scaled speed s·V; when a
            // scale drop makes it unreachable this cycle, take the hard point nearest to it.
            let (hard_lo, hard_hi) = velocity_peak_bounds(st, l, l.velocity, dt);
            let (soft_lo, soft_hi) = velocity_peak_bounds(st, l, s * l.velocity, dt);
            let lo_h = (st.a - l.jerk * dt).max(-l.acceleration).max(hard_lo);
            let hi_h = (st.a + l.jerk * dt).min(l.acceleration).min(hard_hi);
            if lo_h > hi_h {
                return None;
            }
            let (mut lo_a, mut hi_a) = (lo_h.max(soft_lo), hi_h.min(soft_hi));
            if lo_a > hi_a {
                let x = if soft_hi < lo_h { lo_h } else { hi_h };
                lo_a = x;
                hi_a = x;
                limited = true;
            }
            bounds.push((a_req, lo_a, hi_a));
            // a(f) = a + f·d ∈ [lo_a, hi_a]
            if d.abs() < 1e-15 {
                if st.a < lo_a - 1e-12 || st.a > hi_a + 1e-12 {
                    lo_f = 2.0; // infeasible as a group
                }
                continue;
            }
            let (f1, f2) = ((lo_a - st.a) / d, (hi_a - st.a) / d);
            lo_f = lo_f.max(f1.min(f2));
            hi_f = hi_f.min(f1.max(f2));
        }
        let coordinated = lo_f <= hi_f;
        if !coordinated || hi_f < 1.0 {
            limited = true;
        }
        let mut candidate = Vec::with_capacity(group.joints.len());
        for (k, &j) in group.joints.iter().enumerate() {
            let st = self.state[j];
            let (a_req, lo_a, hi_a) = bounds[k];
            let a_next = if coordinated {
                (st.a + hi_f * (a_req - st.a)).clamp(lo_a, hi_a)
            } else {
                a_req.clamp(lo_a, hi_a)
            };
            candidate.push(integrate(st, a_next, dt));
        }
        // 4. the feasible stop must survive
        for (k, &j) in group.joints.iter().enumerate() {
            brake_sim(candidate[k], &self.limits[j], self.lo[j], self.hi[j], dt)?;
        }
        Some((candidate, limited))
    }

    /// Time constant of the velocity loop: the time the jerk limit needs to build up the
    /// acceleration limit (A/J), at least one cycle — faster would only chatter.
    fn velocity_time_constant(&self, l: &JointKinematicLimits) -> f64 {
        (l.acceleration / l.jerk).max(self.dt)
    }

    /// Brake every group for one step.
    pub fn brake_all(&mut self) {
        let n = self.groups.len();
        self.step(
            &Reference::hold(self.joints.len()),
            &vec![0.0; n],
            &vec![true; n],
        );
    }
}

/// Fastest speed from which a jerk-limited stop (from zero acceleration, at 80 % of the
/// acceleration limit, one cycle late) fits in `room`: the root of
/// `room = v²/(2A) + v·A/(2J) + v·dt`.
pub fn envelope_speed(room: f64, l: &JointKinematicLimits, dt: f64) -> f64 {
    let a = 0.8 * l.acceleration;
    let b = a / (2.0 * l.jerk) + dt;
    // v²/(2a) + b·v − room = 0
    a * (-b + (b * b + 2.0 * room / a).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lim() -> JointKinematicLimits {
        JointKinematicLimits {
            lower: -1.0,
            upper: 1.0,
            velocity: 1.0,
            acceleration: 2.0,
            jerk: 10.0,
        }
    }

    fn two_joint_filter() -> Filter {
        Filter::new(
            vec!["a".into(), "b".into()],
            vec![lim(), lim()],
            vec![Group {
                name: "g".into(),
                controller: "c".into(),
                joints: vec![0, 1],
            }],
            0.02,
            0.15,
        )
    }

    #[test]
    fn reaches_a_target_and_never_leaves_the_limits() {
        let mut f = two_joint_filter();
        f.reset_to(&[0.0, 0.0]);
        let r = Reference {
            q: vec![Some(5.0), Some(-0.5)],
            v: vec![0.0, 0.0],
        };
        for _ in 0..400 {
            f.step(&r, &[1.0], &[false]);
            let s = f.state();
            assert!(s[0].q <= 1.0 + 1e-9 && s[0].v.abs() <= 1.0 + 1e-9);
        }
        // Stops at the limit, not at the unreachable target.
        assert!((f.state()[0].q - 1.0).abs() < 0.05, "{:?}", f.state()[0]);
        assert!((f.state()[1].q + 0.5).abs() < 1e-3);
    }

    #[test]
    fn velocity_scaling_keeps_the_direction() {
        let mut f = two_joint_filter();
        f.reset_to(&[-0.9, -0.9]);
        let r = Reference {
            q: vec![Some(0.9), Some(0.0)],
            v: vec![0.0, 0.0],
        };
        let mut ratios = vec![];
        for _ in 0..30 {
            f.step(&r, &[0.5], &[false]);
            let s = f.state();
            assert!(s[0].v <= 0.5 + 1e-9);
            if s[0].v > 0.05 {
                ratios.push(s[1].v / s[0].v);
            }
        }
        // Both joints move in proportion to their remaining distances (1.8 : 0.9).
        for r in &ratios {
            assert!((r - 0.5).abs() < 0.06, "{ratios:?}");
        }
    }
}
