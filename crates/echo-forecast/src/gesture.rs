//! Waving back with a visible wave.
//!
//! The HRI model learns *when* to answer a wave and with which arm — it raises the arm in time
//! with the partner — but a forecast regressed over many waves averages their phases out: the
//! raised hand barely moves from side to side (one joint swings 0.15–0.23 rad). [`WaveBack`]
//! keeps the learned plan and adds the oscillation: when the plan raises an arm (its grasping
//! frame above its shoulder at some point of the plan) — or the partner has a hand above their
//! shoulder, and then the arm the plan holds highest — that arm's joints at each plan point
//! are solved by the same inverse kinematics as [`crate::contact`] for the learned hand
//! position kept at least [`RAISE_RAMP_M`] above the shoulder and moved sideways (along the
//! robot's y axis, across the partner's view) by
//!
//! ```text
//! y(t) = A · sin(2π f t)
//! ```
//!
//! Every plan is made again from the partner's latest frames: when the learned model stops
//! raising the arm (the partner has stopped waving), the wave stops.
//!
//! with `t` the plan point's absolute time (successive plans continue one another's phase),
//! amplitude [`WAVE_AMPLITUDE_M`] and frequency [`WAVE_HZ`] (people wave at 1–2 Hz). The safety
//! service limits the motion like any other.

use echo_msgs::{Interaction, RobotPlan};
use nalgebra::Vector3;

use crate::contact::ContactReach;
use echo_robot::SHOULDER_LINKS as SHOULDER;

/// Side-to-side amplitude of the hand, m.
pub const WAVE_AMPLITUDE_M: f64 = 0.08;
/// Wave frequency, Hz.
pub const WAVE_HZ: f64 = 0.8;
/// While waving, the hand stays at least this far above the shoulder, m.
pub const RAISE_RAMP_M: f64 = 0.1;

/// What a wave refinement did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaveRefinement {
    /// The arm that waves (left = true).
    pub left_arm: bool,
    /// Highest point of the hand above the shoulder in the plan, m.
    pub raised_m: f64,
}

/// Adds a wave to the raised arm of a plan.
pub struct WaveBack<'a> {
    reach: &'a ContactReach,
}

impl<'a> WaveBack<'a> {
    /// Using the arm model and inverse kinematics of `reach`.
    pub fn new(reach: &'a ContactReach) -> WaveBack<'a> {
        WaveBack { reach }
    }

    /// Refine `plan` (stamped `stamp_s`, seconds on the sender's clock) for `interaction`;
    /// `partner_waving`: the partner has a hand above the shoulder now ([`hand_raised`]) — the
    /// arm the plan holds highest then waves even if the plan does not raise it.
    /// `None`: not a wave, no arm raised in the plan nor the partner's, or unknown joints.
    pub fn refine(
        &self,
        plan: &mut RobotPlan,
        stamp_s: f64,
        interaction: Interaction,
        partner_waving: bool,
    ) -> Option<WaveRefinement> {
        if interaction != Interaction::Wave || plan.points.len() < 2 {
            return None;
        }
        let model = self.reach.model();
        let index: Vec<usize> = plan
            .joint_names
            .iter()
            .map(|n| model.joint_index(n))
            .collect::<Option<_>>()?;
        let values = |p: &[f64]| {
            let mut q = model.zero();
            for (i, v) in index.iter().zip(p) {
                q.0[*i] = *v;
            }
            q
        };
        let height = |q: &echo_robot::JointValues, arm: usize| -> Option<f64> {
            let s = model.fk(q, SHOULDER[arm]).ok()?.translation.vector;
            Some(self.reach.grasp(q, arm).z - s.z)
        };
        // The arm the plan raises highest.
        let mut best = (f64::NEG_INFINITY, 0usize);
        for p in &plan.points {
            let q = values(&p.positions);
            for arm in 0..2 {
                let h = height(&q, arm)?;
                if h > best.0 {
                    best = (h, arm);
                }
            }
        }
        let (raised, arm) = best;
        if raised.is_nan() || (raised <= 0.0 && !partner_waving) {
            return None;
        }
        let mut q_prev = values(&plan.points[0].positions);
        for k in 1..plan.points.len() {
            let learned = values(&plan.points[k].positions);
            let h = height(&learned, arm)?;
            // Once the plan raises the arm, the hand stays at least RAISE_RAMP_M above the
            // shoulder over the plan's horizon, so the wave is not cut short.
            let lift = (RAISE_RAMP_M - h).max(0.0);
            let t = stamp_s + plan.points[k].t;
            let y = WAVE_AMPLITUDE_M * (2.0 * std::f64::consts::PI * WAVE_HZ * t).sin();
            let target = self.reach.grasp(&learned, arm) + Vector3::new(0.0, y, lift);
            let solved = self.reach.solve(&q_prev, arm, &target);
            let mut q = learned;
            for &j in &self.reach.arms[arm] {
                q.0[j] = solved.0[j];
            }
            for (slot, i) in plan.points[k].positions.iter_mut().zip(&index) {
                *slot = q.0[*i];
            }
            q_prev = q;
        }
        Some(WaveRefinement {
            left_arm: arm == 0,
            raised_m: raised,
        })
    }
}

/// Whether a person (SMPL-22 joints) has a wrist above its shoulder.
pub fn hand_raised(joints: &[[f64; 3]]) -> bool {
    use echo_motion::skeleton::j;
    joints.len() >= echo_motion::skeleton::NUM_JOINTS
        && [(j::L_WRIST, j::L_SHOULDER), (j::R_WRIST, j::R_SHOULDER)]
            .iter()
            .any(|&(w, s)| joints[w][2] > joints[s][2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::ContactConfig;
    use echo_msgs::{ControlMode, Header, PlanPoint};
    use echo_robot::RobotModel;

    /// A still plan with the right hand `lift` metres above the shoulder (by inverse
    /// kinematics from the home pose).
    fn plan(reach: &ContactReach, lift: f64) -> RobotPlan {
        let model = reach.model();
        let mut q = model
            .values_from(
                echo_robot::home_pose()
                    .iter()
                    .map(|(n, v)| (n.as_str(), *v)),
            )
            .unwrap();
        let s = model.fk(&q, SHOULDER[1]).unwrap().translation.vector;
        let target = s + Vector3::new(0.35, -0.15, lift);
        for _ in 0..20 {
            q = reach.solve(&q, 1, &target);
        }
        let names = echo_hri::data::robot_joint_names();
        let positions: Vec<f64> = names
            .iter()
            .map(|n| q.0[model.joint_index(n).unwrap()])
            .collect();
        RobotPlan {
            header: Header::new("tiago", "forecaster", "odom"),
            mode: ControlMode::Forecast,
            joint_names: names,
            points: (0..=30)
                .map(|k| PlanPoint {
                    t: k as f64 / 15.0,
                    positions: positions.clone(),
                    base: None,
                })
                .collect(),
        }
    }

    fn hand_y(reach: &ContactReach, plan: &RobotPlan, k: usize, arm: usize) -> (f64, f64) {
        let q = reach
            .model()
            .values_from(
                plan.joint_names
                    .iter()
                    .map(|n| n.as_str())
                    .zip(plan.points[k].positions.iter().copied()),
            )
            .unwrap();
        let g = reach.grasp(&q, arm);
        (g.y, g.z)
    }

    #[test]
    fn a_raised_arm_waves_side_to_side_and_a_lowered_one_does_not() {
        let reach = ContactReach::new(RobotModel::tiago_dual(), ContactConfig::default()).unwrap();
        let raised = plan(&reach, 0.3);
        let mut p = raised.clone();
        let done = WaveBack::new(&reach)
            .refine(&mut p, 100.0, Interaction::Wave, false)
            .expect("waves");
        assert!(!done.left_arm && done.raised_m > 0.15, "{done:?}");
        let ys: Vec<f64> = (1..p.points.len())
            .map(|k| hand_y(&reach, &p, k, 1).0)
            .collect();
        let (lo, hi) = ys
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
                (a.min(*y), b.max(*y))
            });
        assert!(
            hi - lo > 1.5 * WAVE_AMPLITUDE_M,
            "side to side {:.3} m",
            hi - lo
        );
        // Other interactions leave the plan alone, and so does a plan with the arms down.
        let mut same = raised.clone();
        assert!(WaveBack::new(&reach)
            .refine(&mut same, 100.0, Interaction::Handshake, true)
            .is_none());
        assert_eq!(same, raised);
        let mut down = plan(&reach, -0.4);
        let before = down.clone();
        assert!(WaveBack::new(&reach)
            .refine(&mut down, 100.0, Interaction::Wave, false)
            .is_none());
        assert_eq!(down, before);
        // The partner waving: the arm held highest is raised and waves.
        let done = WaveBack::new(&reach)
            .refine(&mut down, 100.0, Interaction::Wave, true)
            .expect("answers the partner's wave");
        let arm = usize::from(!done.left_arm);
        let (_, z) = hand_y(&reach, &down, 20, arm);
        let q = reach
            .model()
            .values_from(
                down.joint_names
                    .iter()
                    .map(|n| n.as_str())
                    .zip(down.points[20].positions.iter().copied()),
            )
            .unwrap();
        let s = reach
            .model()
            .fk(&q, SHOULDER[arm])
            .unwrap()
            .translation
            .vector;
        assert!(
            z > s.z,
            "the hand rises above the shoulder: {z:.2} vs {:.2}",
            s.z
        );
    }
}
