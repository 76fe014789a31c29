//! Property tests over adversarial references, plans, commanded and measured states. Cases per property: 10 000
//! (PROPTEST_CASES raises it, e.g. PROPTEST_CASES=200000 for a nightly run).

use std::time::{Duration, Instant};

use echo_msgs::{ControlMode, Header, JointState, PlanPoint, RobotPlan};
use echo_robot::limits::JointKinematicLimits;
use echo_robot::RobotModel;
use echo_safety::filter::{Filter, Group, Reference};
use echo_safety::joint::brake_sim;
use echo_safety::{SafetyConfig, Supervisor};
use proptest::prelude::*;

fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10_000)
}

const EPS: f64 = 1e-9;

fn limits_strategy() -> impl Strategy<Value = JointKinematicLimits> {
    (
        -3.0..0.0f64,
        0.05..3.0f64,
        0.05..3.0f64,
        0.1..5.0f64,
        0.5..30.0f64,
    )
        .prop_map(|(lo, span, v, a, j)| JointKinematicLimits {
            lower: lo,
            upper: lo + span,
            velocity: v,
            acceleration: a,
            jerk: j,
        })
}

#[derive(Debug, Clone)]
struct Step {
    targets: Vec<Option<f64>>,
    vff: Vec<f64>,
    scale: f64,
    brake: bool,
}

fn step_strategy(n: usize) -> impl Strategy<Value = Step> {
    (
        prop::collection::vec(prop::option::weighted(0.9, -10.0..10.0f64), n),
        prop::collection::vec(-5.0..5.0f64, n),
        prop_oneof![Just(1.0), Just(0.0), 0.0..1.0f64],
        prop::bool::weighted(0.1),
    )
        .prop_map(|(targets, vff, scale, brake)| Step {
            targets,
            vff,
            scale,
            brake,
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

    /// No state the filter commands ever leaves the position, velocity, acceleration or jerk
    /// limits, contains a non-finite number, or loses its feasible stop.
    #[test]
    fn filter_never_violates_a_limit(
        limits in prop::collection::vec(limits_strategy(), 3),
        start in prop::collection::vec(0.0..1.0f64, 3),
        steps in prop::collection::vec(step_strategy(3), 1..40),
        dt in prop_oneof![Just(0.01), Just(0.02), 0.005..0.05f64],
    ) {
        let joints: Vec<String> = (0..3).map(|i| format!("j{i}")).collect();
        let groups = vec![
            Group { name: "a".into(), controller: "a".into(), joints: vec![0, 1] },
            Group { name: "b".into(), controller: "b".into(), joints: vec![2] },
        ];
        let mut f = Filter::new(joints, limits.clone(), groups, dt, 0.15);
        let q0: Vec<f64> = limits.iter().zip(&start).map(|(l, s)| l.lower + s * (l.upper - l.lower)).collect();
        f.reset_to(&q0);
        for st in &steps {
            let prev = f.state().to_vec();
            let r = Reference { q: st.targets.clone(), v: st.vff.clone() };
            f.step(&r, &[st.scale, 1.0 - st.scale], &[st.brake, false]);
            for (j, (s, l)) in f.state().iter().zip(&limits).enumerate() {
                prop_assert!(s.q.is_finite() && s.v.is_finite() && s.a.is_finite());
                prop_assert!(s.q >= l.lower - EPS && s.q <= l.upper + EPS, "joint {j} position {s:?} outside {l:?}");
                prop_assert!(s.v.abs() <= l.velocity * (1.0 + 1e-6) + EPS, "joint {j} velocity {s:?} over {l:?}");
                prop_assert!(s.a.abs() <= l.acceleration + EPS, "joint {j} acceleration {s:?}");
                prop_assert!((s.a - prev[j].a).abs() <= l.jerk * dt * (1.0 + 1e-9) + EPS, "joint {j} jerk {:?} → {s:?}", prev[j]);
                prop_assert!(brake_sim(*s, l, l.lower, l.upper, dt).is_some(), "joint {j} lost its stop at {s:?}");
            }
        }
    }
}

fn supervisor_fixture() -> (Supervisor, Vec<String>, Vec<JointKinematicLimits>) {
    let model = RobotModel::tiago_dual();
    let cfg = SafetyConfig::default();
    let sup = Supervisor::new(cfg.clone(), model.clone()).unwrap();
    let joints = sup.filter().joints().to_vec();
    let limits = sup.filter().limits().to_vec();
    (sup, joints, limits)
}

fn state_msg(joints: &[String], q: &[f64]) -> JointState {
    JointState {
        header: Header::new("tiago", "robot", ""),
        name: joints.to_vec(),
        position: q.to_vec(),
        velocity: vec![],
        base: None,
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

    /// Adversarial plans (targets far beyond limits, jumps, any timing) through the whole
    /// supervisor: every command point is finite and inside the limits; consecutive points keep
    /// velocity, acceleration and jerk limits; every command ends at rest; and consecutive
    /// commands join without a jerk violation.
    #[test]
    fn every_command_respects_the_limits(
        start in prop::collection::vec(0.0..1.0f64, 17),
        plans in prop::collection::vec((prop::collection::vec(-8.0..8.0f64, 17), 0.02..1.0f64, 0u64..3), 1..6),
    ) {
        let (mut sup, joints, limits) = supervisor_fixture();
        let q0: Vec<f64> = limits.iter().zip(&start).map(|(l, s)| l.lower + s * (l.upper - l.lower)).collect();
        let t0 = Instant::now();
        let mut now = t0;
        sup.on_joint_state(&state_msg(&joints, &q0), now).unwrap();
        let mut prev_first: Option<Vec<(f64, f64)>> = None;
        for (stamp, (targets, duration, ticks)) in (1u64..).zip(plans.iter()) {
            // A plan that starts where the robot is commanded to be, then jumps to `targets`.
            let here: Vec<f64> = sup.filter().state().iter().map(|s| s.q).collect();
            let mut h = Header::new("tiago", "forecaster", "odom");
            h.stamp_ns = stamp;
            let plan = RobotPlan {
                header: h,
                mode: ControlMode::Forecast,
                joint_names: joints.clone(),
                points: vec![
                    PlanPoint { t: 0.0, positions: here.clone(), base: None },
                    PlanPoint { t: *duration, positions: targets.clone(), base: None },
                ],
            };
            let _ = sup.on_plan(&plan, now);
            for _ in 0..=*ticks {
                now += Duration::from_millis(20);
                let q: Vec<f64> = sup.filter().state().iter().map(|s| s.q).collect();
                sup.on_joint_state(&state_msg(&joints, &q), now).unwrap();
                let tick = sup.tick(now);
                let cmd = tick.command.expect("a command once the state is known");
                let mut first = vec![];
                for tr in &cmd.trajectories {
                    let idx: Vec<usize> = tr.joint_names.iter().map(|n| joints.iter().position(|j| j == n).unwrap()).collect();
                    let mut prev: Option<(f64, Vec<f64>)> = None;
                    for p in &tr.points {
                        for (k, &j) in idx.iter().enumerate() {
                            let l = &limits[j];
                            let (q, v, a) = (p.positions[k], p.velocities[k], p.accelerations[k]);
                            prop_assert!(q.is_finite() && v.is_finite() && a.is_finite());
                            prop_assert!(q >= l.lower - EPS && q <= l.upper + EPS, "{} at {q}", joints[j]);
                            prop_assert!(v.abs() <= l.velocity * (1.0 + 1e-6) + EPS, "{} velocity {v}", joints[j]);
                            prop_assert!(a.abs() <= l.acceleration + EPS, "{} acceleration {a}", joints[j]);
                            if let Some((t_prev, a_prev)) = &prev {
                                let dtp = p.time_from_start - t_prev;
                                prop_assert!(dtp > 0.0);
                                prop_assert!((a - a_prev[k]).abs() <= l.jerk * dtp * (1.0 + 1e-9) + EPS, "{} jerk", joints[j]);
                            }
                        }
                        prev = Some((p.time_from_start, p.accelerations.clone()));
                    }
                    let last = tr.points.last().unwrap();
                    prop_assert!(last.velocities.iter().all(|v| *v == 0.0) && last.accelerations.iter().all(|a| *a == 0.0), "command must end at rest");
                    for (k, &j) in idx.iter().enumerate() {
                        first.push((j as f64, tr.points[0].accelerations[k]));
                    }
                }
                if let Some(pf) = &prev_first {
                    for ((j, a1), (_, a0)) in first.iter().zip(pf) {
                        let l = &limits[*j as usize];
                        prop_assert!((a1 - a0).abs() <= l.jerk * 0.02 * (1.0 + 1e-9) + EPS, "jerk between commands");
                    }
                }
                prev_first = Some(first);
            }
        }
    }
}

/// What the robot's joint-state input says in one control cycle.
#[derive(Debug, Clone)]
enum Measured {
    /// The robot is where it was commanded.
    Faithful,
    /// Nothing arrives (stale).
    Silent,
    /// One joint off by a plausible amount, consistently.
    Offset(usize, f64),
    /// One joint anywhere, even far outside any limit.
    Anywhere(usize, f64),
    /// One joint not a number.
    NonFinite(usize, f64),
    /// A faithful sample and a second stream's sample with one joint anywhere.
    Interleaved(usize, f64),
    /// A sample from another sender.
    Foreign(usize, f64),
}

fn measured_strategy() -> impl Strategy<Value = Measured> {
    let joint = 0usize..17;
    let anywhere = prop_oneof![-1e9..1e9f64, -4.0..4.0f64, Just(2.5), Just(50.0)];
    prop_oneof![
        4 => Just(Measured::Faithful),
        1 => Just(Measured::Silent),
        1 => (joint.clone(), -0.6..0.6f64).prop_map(|(j, d)| Measured::Offset(j, d)),
        2 => (joint.clone(), anywhere.clone()).prop_map(|(j, x)| Measured::Anywhere(j, x)),
        1 => (joint.clone(), prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY)])
            .prop_map(|(j, x)| Measured::NonFinite(j, x)),
        2 => (joint.clone(), anywhere.clone()).prop_map(|(j, x)| Measured::Interleaved(j, x)),
        1 => (joint, anywhere).prop_map(|(j, x)| Measured::Foreign(j, x)),
    ]
}

fn sample(joints: &[String], q: &[f64], source: &str) -> JointState {
    JointState {
        header: Header::new("tiago", source, ""),
        ..state_msg(joints, q)
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

    /// Adversarial measured states (outside any limit, jumps, non-finite, interleaved and
    /// foreign sources, silence) alongside adversarial plans: every command point stays inside
    /// the hard limits (and inside the operating limits, the robot having started inside them),
    /// and consecutive commands keep the velocity, acceleration and jerk limits — whatever the
    /// measured state says.
    #[test]
    fn no_measured_state_moves_a_command_out_of_the_limits(
        start in prop::collection::vec(0.0..1.0f64, 17),
        cycles in prop::collection::vec((measured_strategy(), prop::option::weighted(0.3, prop::collection::vec(-8.0..8.0f64, 17))), 1..30),
    ) {
        let (mut sup, joints, limits) = supervisor_fixture();
        let hard = sup.filter().hard_limits().to_vec();
        let q0: Vec<f64> = limits.iter().zip(&start).map(|(l, s)| l.lower + s * (l.upper - l.lower)).collect();
        let mut now = Instant::now();
        sup.on_joint_state(&state_msg(&joints, &q0), now).unwrap();
        let dt = 0.02;
        let mut prev: Option<Vec<(f64, f64, f64)>> = None;
        for (stamp, (m, plan)) in (1u64..).zip(&cycles) {
            now += Duration::from_millis(20);
            let q: Vec<f64> = sup.filter().state().iter().map(|s| s.q).collect();
            let with = |j: usize, x: f64| { let mut v = q.clone(); v[j] = x; v };
            match m {
                Measured::Faithful => { let _ = sup.on_joint_state(&state_msg(&joints, &q), now); }
                Measured::Silent => {}
                Measured::Offset(j, d) => { let _ = sup.on_joint_state(&state_msg(&joints, &with(*j, q[*j] + d)), now); }
                Measured::Anywhere(j, x) => { let _ = sup.on_joint_state(&state_msg(&joints, &with(*j, *x)), now); }
                Measured::NonFinite(j, x) => { let _ = sup.on_joint_state(&state_msg(&joints, &with(*j, *x)), now); }
                Measured::Interleaved(j, x) => {
                    let _ = sup.on_joint_state(&state_msg(&joints, &q), now);
                    let _ = sup.on_joint_state(&state_msg(&joints, &with(*j, *x)), now);
                }
                Measured::Foreign(j, x) => {
                    prop_assert!(sup.on_joint_state(&sample(&joints, &with(*j, *x), "intruder"), now).is_err());
                }
            }
            if let Some(targets) = plan {
                let mut h = Header::new("tiago", "forecaster", "odom");
                h.stamp_ns = stamp;
                let p = RobotPlan {
                    header: h,
                    mode: ControlMode::Forecast,
                    joint_names: joints.clone(),
                    points: vec![
                        PlanPoint { t: 0.0, positions: q.clone(), base: None },
                        PlanPoint { t: 0.5, positions: targets.clone(), base: None },
                    ],
                };
                let _ = sup.on_plan(&p, now);
            }
            let tick = sup.tick(now);
            let cmd = tick.command.expect("a command once the state is known");
            let mut first = vec![(f64::NAN, f64::NAN, f64::NAN); joints.len()];
            for tr in &cmd.trajectories {
                for p in &tr.points {
                    for (k, n) in tr.joint_names.iter().enumerate() {
                        let j = joints.iter().position(|x| x == n).unwrap();
                        let (lo, hi) = hard[j];
                        let l = &limits[j];
                        let x = p.positions[k];
                        prop_assert!(x.is_finite() && x >= lo - EPS && x <= hi + EPS, "{n} at {x} outside hard [{lo}, {hi}]");
                        prop_assert!(x >= l.lower - EPS && x <= l.upper + EPS, "{n} at {x} outside operating limits");
                    }
                }
                for (k, n) in tr.joint_names.iter().enumerate() {
                    let j = joints.iter().position(|x| x == n).unwrap();
                    let p0 = &tr.points[0];
                    first[j] = (p0.positions[k], p0.velocities[k], p0.accelerations[k]);
                }
            }
            if let Some(pf) = &prev {
                for (j, ((q1, v1, a1), (q0, v0, a0))) in first.iter().zip(pf).enumerate() {
                    let l = &limits[j];
                    prop_assert!((q1 - q0).abs() <= l.velocity * dt * (1.0 + 1e-6) + EPS, "{}: position step {q0} → {q1}", joints[j]);
                    prop_assert!((v1 - v0).abs() <= l.acceleration * dt * (1.0 + 1e-6) + EPS, "{}: velocity step {v0} → {v1}", joints[j]);
                    prop_assert!((a1 - a0).abs() <= l.jerk * dt * (1.0 + 1e-9) + EPS, "{}: jerk {a0} → {a1}", joints[j]);
                }
            }
            prev = Some(first);
        }
    }
}
