//! Waving back with a visible wave.
//!
//! The HRI model learns *when* to answer a wave and with which arm — it raises the arm in time
//! with the partner — but a forecast regressed over many waves averages their phases out: the
//! raised hand barely moves from side to side (one joint swings 0.15–0.23 rad). [`WaveBack`]
//! keeps the learned plan and adds the oscillation: when the plan raises an arm (its grasping
//! frame above its shoulder at some point of the plan) — or the partner has a hand above their
//! shoulder, and then the arm the plan holds highest — that arm's joints at each plan point
//! are solved by the same inverse kinematics as [`crate::contact`] for a hand raised beside
//! the head ([`WAVE_FORWARD_M`] forward, [`WAVE_OUT_M`] out and [`WAVE_UP_M`] up from its
//! shoulder: clear of the head, the arm's joints away from their limits) and moved sideways
//! (along the robot's y axis, across the partner's view) by
//!
//! ```text
//! y(t) = A · sin(2π f t)
//! ```
//!
//! Every plan is made again from the partner's latest frames: when the learned model stops
//! raising the arm — but once a wave has started, the forecaster service keeps it going with
//! the same arm while the interaction is a wave (`keep_arm`): the regressed plan dips now and
//! then, and a wave cut short at each dip is not recognisable.
//!
//! with `t` the plan point's absolute time (successive plans continue one another's phase),
//! amplitude [`WAVE_AMPLITUDE_M`] and frequency [`WAVE_HZ`] (people wave at 1–2 Hz; the arm's
//! acceleration and jerk limits allow about half that). The safety service limits the motion
//! like any other.

use echo_msgs::{Interaction, RobotPlan};
use echo_robot::JointValues;
use nalgebra::Vector3;

use crate::contact::ContactReach;
use echo_robot::SHOULDER_LINKS as SHOULDER;

/// Side-to-side amplitude of the hand, m.
pub const WAVE_AMPLITUDE_M: f64 = 0.06;
/// Wave frequency, Hz: slower than people wave (1–2 Hz), because the arm's shoulder joints
/// accelerate at most 1.5 rad/s² with a jerk of 7.5 rad/s³ (`echo_robot::limits`): at 0.6 Hz
/// the hand's ±6 cm (0.85 m/s² at the hand, shared by the arm's seven joints) stay within
/// them; at 0.8 Hz and ±8 cm they did not, and the safety filter cut the wave to a drift.
pub const WAVE_HZ: f64 = 0.6;
/// The waving hand's centre relative to its shoulder: forward, m. Of a grid of centres 0–0.4 m
/// forward, out and up, this one keeps TIAGo++'s arm joints furthest from their limits over a
/// whole wave (0.36 rad; the elbow reaches its limit at most others, and the safety filter
/// brakes an arm that runs towards a limit).
pub const WAVE_FORWARD_M: f64 = 0.4;
/// … outwards (away from the body), m.
pub const WAVE_OUT_M: f64 = 0.3;
/// … up, m.
pub const WAVE_UP_M: f64 = 0.3;

/// What a wave refinement did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaveRefinement {
    /// The arm that waves (left = true).
    pub left_arm: bool,
    /// Highest point of the hand above the shoulder in the plan, m.
    pub raised_m: f64,
}

/// Adds a wave to the raised arm of a plan.
pub struct WaveBack {
    /// Per arm (left, right): the wave posture — the arm's joints with the hand at the wave
    /// centre, solved once from the home pose — and how far the hand stays from the centre, m.
    postures: [Option<(JointValues, f64)>; 2],
}

/// The wave centre of `arm`'s hand at joints `q`: [`WAVE_FORWARD_M`] forward, [`WAVE_OUT_M`]
/// out (a raised hand in front of the face would swing into the head) and [`WAVE_UP_M`] up
/// from its shoulder.
fn centre(model: &echo_robot::RobotModel, q: &JointValues, arm: usize) -> Option<Vector3<f64>> {
    let side = if arm == 0 { 1.0 } else { -1.0 };
    let shoulder = model.fk(q, SHOULDER[arm]).ok()?.translation.vector;
    Some(shoulder + Vector3::new(WAVE_FORWARD_M, side * WAVE_OUT_M, WAVE_UP_M))
}

impl WaveBack {
    /// The wave postures of both arms, by the inverse kinematics of `reach`. Solved from the
    /// home pose, not from the measured joints, whose solutions jump between the redundant
    /// arm's branches while it moves and send it back and forth.
    pub fn new(reach: &ContactReach) -> WaveBack {
        let model = reach.model();
        let home = model
            .values_from(
                echo_robot::home_pose()
                    .iter()
                    .map(|(n, v)| (n.as_str(), *v)),
            )
            .ok();
        let postures = std::array::from_fn(|arm| {
            let home = home.as_ref()?;
            let c0 = centre(model, home, arm)?;
            let mut q = home.clone();
            for _ in 0..60 {
                q = reach.solve(&q, arm, &c0);
            }
            let err = (reach.grasp(&q, arm) - c0).norm();
            Some((q, err))
        });
        WaveBack { postures }
    }

    /// Refine `plan` (stamped `stamp_s`, seconds on the sender's clock) for `interaction`,
    /// with the arm model and inverse kinematics of `reach` (the one the postures came from);
    /// `partner_waving`: the partner has a hand above the shoulder now ([`hand_raised`]) — the
    /// arm the plan holds highest then waves even if the plan does not raise it. `keep_arm`
    /// (left = true): the arm of a wave already under way, which goes on waving (plans that
    /// raise both arms about as high would otherwise switch arms and cut every wave short).
    /// `None`: not a wave, no arm raised in the plan nor the partner's, or unknown joints.
    pub fn refine(
        &self,
        reach: &ContactReach,
        plan: &mut RobotPlan,
        stamp_s: f64,
        interaction: Interaction,
        partner_waving: bool,
        keep_arm: Option<bool>,
    ) -> Option<WaveRefinement> {
        if interaction != Interaction::Wave || plan.points.len() < 2 {
            return None;
        }
        let model = reach.model();
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
        // Each hand's highest point above its shoulder over the plan.
        let mut raised = [f64::NEG_INFINITY; 2];
        for p in &plan.points {
            let q = values(&p.positions);
            for (arm, r) in raised.iter_mut().enumerate() {
                let s = model.fk(&q, SHOULDER[arm]).ok()?.translation.vector;
                *r = r.max(reach.grasp(&q, arm).z - s.z);
            }
        }
        let highest = usize::from(raised[1] > raised[0]);
        if raised[highest].is_nan() || (raised[highest] <= 0.0 && !partner_waving) {
            return None;
        }
        // The arm under way, else the one the plan holds highest — unless it cannot reach
        // its wave posture (then the other one).
        let err = |arm: usize| self.postures[arm].as_ref().map_or(f64::INFINITY, |p| p.1);
        let arm = match keep_arm {
            Some(left) => usize::from(!left),
            None if err(highest) > 0.03 && err(1 - highest) < err(highest) => 1 - highest,
            None => highest,
        };
        let posture = &self.postures[arm].as_ref()?.0;
        let measured = values(&plan.points[0].positions);
        let arm_joints = &reach.arms[arm];
        let gap = arm_joints
            .iter()
            .map(|&j| (posture.0[j] - measured.0[j]).abs())
            .fold(0.0, f64::max);
        // Far from the wave, the arm gets there at TRANSITION_RAD_S (its largest joint move);
        // near it, the plan starts on the wave itself: a plan that starts at the measured
        // joints feeds the arm's lag back into its own reference.
        let transition_s = if gap < START_TOLERANCE_RAD {
            0.0
        } else {
            gap / TRANSITION_RAD_S
        };
        for point in &mut plan.points {
            let learned = values(&point.positions);
            let t = stamp_s + point.t;
            let y = WAVE_AMPLITUDE_M * (2.0 * std::f64::consts::PI * WAVE_HZ * t).sin();
            let target = centre(model, &learned, arm)? + Vector3::new(0.0, y, 0.0);
            // Every point starts from the posture, so the joints move by the least the hand's
            // sideways swing needs.
            let mut seed = learned.clone();
            for &j in arm_joints {
                seed.0[j] = posture.0[j];
            }
            let solved = reach.solve(&seed, arm, &target);
            // A constant pace (no ease-in): plans follow one another every frame and the
            // safety service samples each near its start, so a ramp that starts flat would
            // never get the arm moving.
            let w = if transition_s > 0.0 {
                (point.t / transition_s).clamp(0.0, 1.0)
            } else {
                1.0
            };
            let mut q = learned;
            for &j in arm_joints {
                q.0[j] = measured.0[j] + w * (solved.0[j] - measured.0[j]);
            }
            for (slot, i) in point.positions.iter_mut().zip(&index) {
                *slot = q.0[*i];
            }
        }
        Some(WaveRefinement {
            left_arm: arm == 0,
            raised_m: raised[arm],
        })
    }
}

/// A wave plan starts on the wave itself, not at the measured joints, once the arm is this
/// close to the wave posture on every joint, rad (the swing is about 0.1 rad a joint; the
/// safety service accepts plans starting up to 0.35 rad from the measured joints).
pub const START_TOLERANCE_RAD: f64 = 0.25;
/// Further away, the plan moves the arm into the wave posture at this pace (its largest
/// joint move), rad/s: a plan that asks for it at once sends the arm, through the safety
/// filter's limits, on a wide detour.
pub const TRANSITION_RAD_S: f64 = 0.8;

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
        let names = echo_models::robot_agent::robot_joint_names();
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
            .refine(&reach, &mut p, 100.0, Interaction::Wave, false, None)
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
            .refine(&reach, &mut same, 100.0, Interaction::Handshake, true, None)
            .is_none());
        assert_eq!(same, raised);
        let mut down = plan(&reach, -0.4);
        let before = down.clone();
        assert!(WaveBack::new(&reach)
            .refine(&reach, &mut down, 100.0, Interaction::Wave, false, None)
            .is_none());
        assert_eq!(down, before);
        // The partner waving: the arm held highest is raised, at a pace the arm can follow,
        // and waves. Plans follow one another, each starting where the last one was 0.5 s in.
        let mut arm = 0;
        let mut current = down.clone();
        for round in 0..10 {
            let mut p = down.clone();
            let start = current.points[8].positions.clone();
            for pt in &mut p.points {
                pt.positions = start.clone();
            }
            let done = WaveBack::new(&reach)
                .refine(
                    &reach,
                    &mut p,
                    100.0 + 0.5 * round as f64,
                    Interaction::Wave,
                    true,
                    None,
                )
                .expect("answers the partner's wave");
            arm = usize::from(!done.left_arm);
            for w in p.points.windows(2) {
                let dt = w[1].t - w[0].t;
                for (a, b) in w[0].positions.iter().zip(&w[1].positions) {
                    assert!(
                        (b - a).abs() / dt <= TRANSITION_RAD_S + 0.6,
                        "a joint moves at {:.2} rad/s",
                        (b - a).abs() / dt
                    );
                }
            }
            current = p;
        }
        let (_, z) = hand_y(&reach, &current, 20, arm);
        let q = reach
            .model()
            .values_from(
                current
                    .joint_names
                    .iter()
                    .map(|n| n.as_str())
                    .zip(current.points[20].positions.iter().copied()),
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

    #[test]
    fn a_wave_under_way_keeps_its_arm() {
        let reach = ContactReach::new(RobotModel::tiago_dual(), ContactConfig::default()).unwrap();
        // The plan raises the right arm, but the left one is already waving: the left goes on.
        let mut p = plan(&reach, 0.3);
        let done = WaveBack::new(&reach)
            .refine(&reach, &mut p, 100.0, Interaction::Wave, true, Some(true))
            .expect("waves");
        assert!(done.left_arm, "{done:?}");
        let span = |arm: usize| {
            let ys: Vec<f64> = (1..p.points.len())
                .map(|k| hand_y(&reach, &p, k, arm).0)
                .collect();
            ys.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
                - ys.iter().cloned().fold(f64::INFINITY, f64::min)
        };
        assert!(span(0) > 1.5 * WAVE_AMPLITUDE_M, "left {:.3} m", span(0));
        assert!(span(1) < 0.01, "the right arm holds: {:.3} m", span(1));
    }
}
