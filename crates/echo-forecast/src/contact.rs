//! Closing the last centimetres of a contact interaction.
//!
//! The HRI model plans the robot's gross motion — it turns, raises the arm, brings the gripper
//! towards the partner's hand — but a forecast regressed over many people stops a few
//! centimetres short of any one hand. A handshake or a handover needs the gripper *at* the hand.
//! [`ContactReach`] refines a learned plan the way a visual servo closes a reach: when the
//! interaction is a contact one and the partner offers a hand within [`ContactConfig::reach_m`]
//! of the nearer of the robot's shoulders, that arm's joints at each plan point are pulled towards an inverse-kinematics solution that puts the grasping frame
//! [`ContactConfig::grasp_depth_m`] inside that hand's sphere, with a first-order approach
//! (time constant [`ContactConfig::tau_s`]) from the measured joints:
//!
//! ```text
//! q'_k = q_k + (1 − exp(−t_k / τ)) · (IK(hand_k | q'_{k−1}) − q_k)
//! ```
//!
//! Only an *offered* hand is reached for: one whose sphere keeps [`ContactConfig::offered_m`]
//! from the partner's own torso and thighs. A hand the forecast says will be offered is reached
//! for ahead of time: until the first forecast frame in which it is offered, the gripper heads
//! for where it will be then (the safety service's contact speed is low: a reach that waited for
//! the hand would arrive after the handshake). A hand drawn back to the body (the handshake is
//! over, the object is handed) is let go: from the first point where it is no longer offered,
//! the refinement's offset decays with the same time constant and the learned plan takes over
//! — the gripper does not follow a hand to the partner's hip, where the safety service's body
//! clearance would stop the robot.
//!
//! IK is damped least squares on the chosen arm's seven joints (numerical Jacobian of the
//! URDF forward kinematics, damping λ, joint limits enforced). Everything else — speed near the
//! partner, clearances to head and body, the limits — stays the safety service's job: the
//! refined plan is only a request.

use echo_motion::sensors::{body_capsules, BodyPart};
use echo_motion::skeleton::NUM_JOINTS;
use echo_msgs::{Interaction, RobotPlan};
use echo_robot::collision::{Part, RobotBody};
use echo_robot::{JointValues, RobotModel};
use nalgebra::{Matrix3, SMatrix, Vector3};

/// Settings of the contact refinement.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactConfig {
    /// The plan is refined when an offered hand is within this distance of the arm's shoulder
    /// (the arm's reach), m.
    pub reach_m: f64,
    /// The grasping frame is aimed this far past the hand sphere's near surface, towards its
    /// centre, m (0: at the surface; the gripper's own radius then overlaps the hand, and the
    /// gripper stays on the robot's side of it, away from the partner's body).
    pub grasp_depth_m: f64,
    /// Time constant of the approach (and of letting go), s.
    pub tau_s: f64,
    /// A hand is offered while its sphere keeps this far from the partner's torso and thighs, m.
    pub offered_m: f64,
    /// Damping of the least-squares steps, m.
    pub damping: f64,
    /// Newton steps per plan point.
    pub iterations: usize,
    /// Largest change of one joint per step, rad.
    pub max_step_rad: f64,
}

impl Default for ContactConfig {
    fn default() -> Self {
        ContactConfig {
            reach_m: 0.9,
            grasp_depth_m: 0.0,
            tau_s: 0.2,
            offered_m: 0.1,
            damping: 0.05,
            iterations: 6,
            max_step_rad: 0.3,
        }
    }
}

/// What a refinement did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactRefinement {
    /// The arm used (left = true).
    pub left_arm: bool,
    /// The partner's hand aimed at (left = true).
    pub left_hand: bool,
    /// Surface distance of the learned plan's closest point to that hand, m.
    pub planned_surface_m: f64,
    /// Surface distance at the refined plan's last point, m (≤ 0: touching).
    pub refined_surface_m: f64,
}

/// The refinement, for one robot model.
#[derive(Debug, Clone)]
pub struct ContactReach {
    model: RobotModel,
    body: RobotBody,
    cfg: ContactConfig,
    /// Model indices of each arm's seven joints (left, right).
    pub(crate) arms: [[usize; 7]; 2],
}

/// The arm used last time is kept unless the other shoulder is this much nearer the hand, m.
pub const ARM_SWITCH_M: f64 = 0.1;

use echo_robot::SHOULDER_LINKS as SHOULDER;

use echo_robot::GRASPING_FRAMES as GRASP;

impl ContactReach {
    /// For `model` (TIAGo++ joint and frame names).
    pub fn new(model: RobotModel, cfg: ContactConfig) -> anyhow::Result<ContactReach> {
        let body = RobotBody::tiago(&model)?;
        let mut arms = [[0usize; 7]; 2];
        for (a, side) in ["left", "right"].iter().enumerate() {
            for (k, slot) in arms[a].iter_mut().enumerate() {
                let name = format!("arm_{side}_{}_joint", k + 1);
                *slot = model
                    .joint_index(&name)
                    .ok_or_else(|| anyhow::anyhow!("the robot model has no joint {name}"))?;
            }
        }
        for g in GRASP.iter().chain(&SHOULDER) {
            anyhow::ensure!(model.has_frame(g), "the robot model has no frame {g}");
        }
        Ok(ContactReach {
            model,
            body,
            cfg,
            arms,
        })
    }

    /// Settings.
    pub fn config(&self) -> &ContactConfig {
        &self.cfg
    }

    /// Refine `plan` (joint positions over time, base fixed) towards the partner's forecast
    /// hands `human` (one SMPL-22 frame per plan point after the first, robot base frame) for
    /// `interaction`. `prefer_left`: the arm used last time, kept unless the other shoulder is
    /// [`ARM_SWITCH_M`] nearer the hand (a hand held in the middle must not make the robot
    /// alternate arms). Returns what was done, or `None` when the plan was left as it is (not a
    /// contact interaction, no hand offered within reach, unknown joints, or too short a
    /// forecast).
    pub fn refine(
        &self,
        plan: &mut RobotPlan,
        human: &[Vec<[f64; 3]>],
        interaction: Interaction,
        prefer_left: Option<bool>,
    ) -> Option<ContactRefinement> {
        if !matches!(
            interaction,
            Interaction::Handshake | Interaction::Handover | Interaction::HighFive
        ) || plan.points.len() < 2
            || human.len() + 1 < plan.points.len()
        {
            return None;
        }
        let index: Vec<usize> = plan
            .joint_names
            .iter()
            .map(|n| self.model.joint_index(n))
            .collect::<Option<_>>()?;
        let values = |p: &[f64]| {
            let mut q = self.model.zero();
            for (i, v) in index.iter().zip(p) {
                q.0[*i] = *v;
            }
            q
        };
        let hands: Vec<[(Vector3<f64>, f64, bool); 2]> = human
            .iter()
            .map(|f| hand_spheres(f, self.cfg.offered_m))
            .collect::<Option<_>>()?;
        // The hand: the offered one (the nearer to the robot if both are), in the first
        // forecast frame that offers one. The arm: the one whose shoulder is nearer to it (an
        // arm reaching across the robot's front would meet the other arm).
        let (first, hand) = hands.iter().enumerate().find_map(|(k, h)| {
            let offered: Vec<usize> = (0..2).filter(|&i| h[i].2).collect();
            let pick = offered
                .into_iter()
                .min_by(|&a, &b| h[a].0.xy().norm().total_cmp(&h[b].0.xy().norm()))?;
            Some((k, pick))
        })?;
        let q0 = values(&plan.points[0].positions);
        let shoulders: Vec<Vector3<f64>> = SHOULDER
            .iter()
            .map(|f| self.model.fk(&q0, f).map(|p| p.translation.vector))
            .collect::<Result<_, _>>()
            .ok()?;
        let c = hands[first][hand].0;
        let (dl, dr) = ((c - shoulders[0]).norm(), (c - shoulders[1]).norm());
        let arm = match prefer_left {
            Some(true) if dr + ARM_SWITCH_M > dl => 0,
            Some(false) if dl + ARM_SWITCH_M > dr => 1,
            _ => usize::from(dr < dl),
        };
        let planned = plan
            .points
            .iter()
            .skip(1)
            .zip(&hands)
            .map(|(p, h)| {
                let (c, r, _) = h[hand];
                self.gripper_capsules(&values(&p.positions))[arm]
                    .distance(&echo_robot::collision::Capsule::sphere(c, r))
            })
            .fold(f64::INFINITY, f64::min);
        let mut q_prev = values(&plan.points[0].positions);
        let shoulder = self
            .model
            .fk(&q_prev, SHOULDER[arm])
            .ok()?
            .translation
            .vector;
        // Until the hand is offered the gripper heads for where it will be then; a hand out of
        // the arm's reach is left alone.
        if (hands[first][hand].0 - shoulder).norm() > self.cfg.reach_m {
            return None;
        }
        let start = self.grasp(&q_prev, arm);
        let mut last = f64::INFINITY;
        // Once the hand is withdrawn: the offset from the learned plan at that moment, and when.
        let mut released: Option<(Vec<f64>, f64)> = None;
        for k in 1..plan.points.len() {
            let t = plan.points[k].t;
            let learned = values(&plan.points[k].positions);
            let (c, r, offered) = hands[(k - 1).max(first)][hand];
            if !offered && released.is_none() {
                let offset = self.arms[arm]
                    .iter()
                    .map(|&j| q_prev.0[j] - learned.0[j])
                    .collect();
                released = Some((offset, plan.points[k - 1].t));
            }
            let mut q = learned.clone();
            match &released {
                Some((offset, t_rel)) => {
                    let keep = (-(t - t_rel).max(0.0) / self.cfg.tau_s).exp();
                    for (&j, o) in self.arms[arm].iter().zip(offset) {
                        q.0[j] = learned.0[j] + keep * o;
                    }
                }
                None => {
                    let aim = self.aim(&q_prev, arm, c, r);
                    let w = 1.0 - (-t.max(0.0) / self.cfg.tau_s).exp();
                    let solved = self.solve(&q_prev, arm, &(start + w * (aim - start)));
                    for &j in &self.arms[arm] {
                        q.0[j] = solved.0[j];
                    }
                }
            }
            for (slot, i) in plan.points[k].positions.iter_mut().zip(&index) {
                *slot = q.0[*i];
            }
            last = self.gripper_capsules(&q)[arm]
                .distance(&echo_robot::collision::Capsule::sphere(c, r));
            q_prev = q;
        }
        Some(ContactRefinement {
            left_arm: arm == 0,
            left_hand: hand == 0,
            planned_surface_m: planned,
            refined_surface_m: last,
        })
    }

    /// Gripper capsules (left, right) at `q`.
    fn gripper_capsules(&self, q: &JointValues) -> [echo_robot::collision::Capsule; 2] {
        let mut out = [echo_robot::collision::Capsule::sphere(Vector3::zeros(), 0.0); 2];
        for (part, c) in self.body.at(&self.model, q) {
            if let Part::Gripper(left) = part {
                out[usize::from(!left)] = c;
            }
        }
        out
    }

    /// Where the grasping frame should go for a hand sphere (`c`, `r`): `grasp_depth_m` inside
    /// its surface, on the side the gripper comes from.
    fn aim(&self, q: &JointValues, arm: usize, c: Vector3<f64>, r: f64) -> Vector3<f64> {
        let g = self.grasp(q, arm);
        let dir = (g - c).try_normalize(1e-9).unwrap_or_else(Vector3::x);
        c + dir * (r - self.cfg.grasp_depth_m).max(0.0)
    }

    /// The robot model.
    pub(crate) fn model(&self) -> &RobotModel {
        &self.model
    }

    /// A grasping frame's position (left = 0, right = 1) at `q`.
    pub(crate) fn grasp(&self, q: &JointValues, arm: usize) -> Vector3<f64> {
        self.model
            .fk(q, GRASP[arm])
            .map(|p| p.translation.vector)
            .unwrap_or_else(|_| Vector3::repeat(f64::NAN))
    }

    /// Damped least squares on the arm's joints from `start` towards `target`.
    pub(crate) fn solve(
        &self,
        start: &JointValues,
        arm: usize,
        target: &Vector3<f64>,
    ) -> JointValues {
        let mut q = start.clone();
        let names = self.model.actuated_joints();
        for _ in 0..self.cfg.iterations {
            let g = self.grasp(&q, arm);
            let e = target - g;
            if !e.iter().all(|x| x.is_finite()) || e.norm() < 1e-4 {
                break;
            }
            let mut jac = SMatrix::<f64, 3, 7>::zeros();
            let h = 1e-5;
            for (c, &j) in self.arms[arm].iter().enumerate() {
                let mut qh = q.clone();
                qh.0[j] += h;
                jac.set_column(c, &((self.grasp(&qh, arm) - g) / h));
            }
            let lambda2 = self.cfg.damping * self.cfg.damping;
            let Some(inv) = (jac * jac.transpose() + Matrix3::identity() * lambda2).try_inverse()
            else {
                break;
            };
            let dq = jac.transpose() * inv * e;
            for (c, &j) in self.arms[arm].iter().enumerate() {
                let step = dq[c].clamp(-self.cfg.max_step_rad, self.cfg.max_step_rad);
                let mut v = q.0[j] + step;
                if let Some(l) = self.model.limits(&names[j]) {
                    v = v.clamp(l.lower, l.upper);
                }
                q.0[j] = v;
            }
        }
        q
    }
}

/// The partner's hand spheres (left, right) of a SMPL-22 frame, as the contact sensors model
/// them: centre, radius, and whether the hand is offered (its sphere at least `offered_m` from
/// the torso and both thighs).
fn hand_spheres(frame: &[[f64; 3]], offered_m: f64) -> Option<[(Vector3<f64>, f64, bool); 2]> {
    if frame.len() < NUM_JOINTS {
        return None;
    }
    let p: Vec<Vector3<f64>> = frame.iter().map(|x| Vector3::from(*x)).collect();
    let capsules = body_capsules(&p);
    let body: Vec<_> = capsules
        .iter()
        .filter(|(part, _)| matches!(part, BodyPart::Torso | BodyPart::Thigh(_)))
        .map(|(_, c)| *c)
        .collect();
    let mut out = [(Vector3::zeros(), 0.0, false); 2];
    let mut found = 0;
    for (part, c) in &capsules {
        if let BodyPart::Hand(left) = part {
            let offered = body.iter().all(|b| b.distance(c) >= offered_m);
            out[usize::from(!left)] = (c.a, c.radius, offered);
            found += 1;
        }
    }
    (found == 2 && out.iter().all(|(c, ..)| c.iter().all(|x| x.is_finite()))).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use echo_msgs::{Header, PlanPoint};

    fn plan_at(reach: &ContactReach, q: &JointValues, n: usize) -> RobotPlan {
        let names = echo_models::robot_agent::robot_joint_names();
        let positions: Vec<f64> = names
            .iter()
            .map(|n| q.0[reach.model.joint_index(n).unwrap()])
            .collect();
        RobotPlan {
            header: Header::new("tiago", "forecaster", "odom"),
            mode: echo_msgs::ControlMode::Forecast,
            joint_names: names,
            points: (0..=n)
                .map(|k| PlanPoint {
                    t: k as f64 / 15.0,
                    positions: positions.clone(),
                    base: None,
                })
                .collect(),
        }
    }

    /// A standing person facing the robot (−x) placed so that the right hand, held out, has
    /// its sphere centred at `hand` (robot base frame); with `offered` false the same person
    /// lets that arm hang.
    fn person(hand: Vector3<f64>, offered: bool) -> Vec<[f64; 3]> {
        use echo_motion::skeleton::{forward, j, Body, Pose};
        let rest = forward(
            &Body::with_height(1.75),
            &Pose::rest(Vector3::zeros(), std::f64::consts::PI),
        );
        let arm = |dir: Vector3<f64>| {
            let mut v = rest;
            v[j::R_ELBOW] = v[j::R_SHOULDER] + dir * 0.28;
            v[j::R_WRIST] = v[j::R_ELBOW] + dir * 0.25;
            v
        };
        let out = arm(Vector3::new(-0.8, 0.0, -0.6).normalize());
        let p: Vec<[f64; 3]> = out.iter().map(|x| [x.x, x.y, x.z]).collect();
        // Move the whole body so the held-out hand's sphere centre lands on `hand`.
        let shift = hand - hand_spheres(&p, 0.0).unwrap()[1].0;
        let v = if offered { out } else { arm(-Vector3::z()) };
        v.iter().map(|x| (x + shift).into()).collect()
    }

    fn reach() -> ContactReach {
        ContactReach::new(RobotModel::tiago_dual(), ContactConfig::default()).unwrap()
    }

    /// The right gripper's grasping frame at a reachable arm pose, and that pose.
    fn right_arm_pose(r: &ContactReach) -> (JointValues, Vector3<f64>) {
        let q = r
            .model
            .values_from(
                echo_robot::home_pose()
                    .iter()
                    .map(|(n, v)| (n.as_str(), *v))
                    .chain([("arm_right_1_joint", 0.6), ("arm_right_4_joint", 1.2)]),
            )
            .unwrap();
        let g = r.grasp(&q, 1);
        (q, g)
    }

    #[test]
    fn a_hand_within_reach_is_touched_by_the_end_of_the_plan() {
        let r = reach();
        let (q, g) = right_arm_pose(&r);
        // The hand 15 cm from the grasping frame, further out in front.
        let hand = g + Vector3::new(0.12, 0.0, 0.09);
        let offering = person(hand, true);
        let mut plan = plan_at(&r, &q, 23);
        let human = vec![offering; 23];
        let before = plan.clone();
        let done = r
            .refine(&mut plan, &human, Interaction::Handshake, None)
            .expect("engaged");
        let arm = usize::from(!done.left_arm);
        assert!(done.planned_surface_m > 0.0, "{done:?}");
        assert!(done.refined_surface_m <= 0.0, "{done:?}");
        // The first point (the measured joints) is kept; later points move progressively.
        assert_eq!(plan.points[0], before.points[0]);
        let dist = |plan: &RobotPlan, k: usize| {
            let q = plan.points[k].positions.clone();
            let names = &plan.joint_names;
            let qv = r
                .model
                .values_from(names.iter().map(|n| n.as_str()).zip(q))
                .unwrap();
            (r.grasp(&qv, arm) - hand).norm()
        };
        let d = |k| dist(&plan, k);
        assert!(d(1) > d(5) && d(5) > d(23), "{} {} {}", d(1), d(5), d(23));
        // The hand drawn back to the body from point 12 on: the gripper lets go.
        let mut plan = before.clone();
        let mut human = vec![person(hand, true); 23];
        for f in human.iter_mut().skip(11) {
            *f = person(hand, false);
        }
        r.refine(&mut plan, &human, Interaction::Handshake, None)
            .unwrap();
        let (mid, end) = (dist(&plan, 11), dist(&plan, 23));
        assert!(end > mid + 0.05, "let go: {mid} then {end}");
        // Joint limits hold at every point.
        for p in &plan.points {
            for (n, v) in plan.joint_names.iter().zip(&p.positions) {
                let l = r.model.limits(n).unwrap();
                assert!(*v >= l.lower - 1e-9 && *v <= l.upper + 1e-9, "{n} = {v}");
            }
        }
    }

    #[test]
    fn other_interactions_and_far_hands_leave_the_plan_alone() {
        let r = reach();
        let (q, g) = right_arm_pose(&r);
        let near = person(g + Vector3::new(0.12, 0.0, 0.0), true);
        let far = person(g + Vector3::new(1.3, 0.0, 0.0), true);
        let withdrawn = person(g + Vector3::new(0.12, 0.0, 0.0), false);
        for (human, kind) in [
            (&near, Interaction::Wave),
            (&near, Interaction::Bow),
            (&far, Interaction::Handshake),
            (&withdrawn, Interaction::Handshake),
        ] {
            let mut plan = plan_at(&r, &q, 23);
            let before = plan.clone();
            let done = r.refine(&mut plan, &vec![human.clone(); 23], kind, None);
            assert!(done.is_none(), "{kind:?}: {done:?}");
            assert_eq!(plan, before);
        }
        // Malformed forecasts (too short, too few joints, NaN) are refused, never a panic.
        let mut plan = plan_at(&r, &q, 23);
        assert!(r
            .refine(
                &mut plan,
                &vec![near.clone(); 5],
                Interaction::Handshake,
                None
            )
            .is_none());
        assert!(r
            .refine(
                &mut plan,
                &vec![near[..10].to_vec(); 23],
                Interaction::Handshake,
                None
            )
            .is_none());
        let mut nan = near.clone();
        nan[21] = [f64::NAN; 3];
        assert!(r
            .refine(&mut plan, &vec![nan; 23], Interaction::Handshake, None)
            .is_none());
    }
}
