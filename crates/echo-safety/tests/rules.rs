//! One test per safety rule: timeout, recovery, e-stop, invalid plans, stale state,
//! measured-state faults and source lock, liveliness, separation, contact, self-collision.

use std::time::{Duration, Instant};

use echo_msgs::*;
use echo_robot::RobotModel;
use echo_safety::{SafetyConfig, Supervisor};

const DT: Duration = Duration::from_millis(20);

struct Rig {
    sup: Supervisor,
    joints: Vec<String>,
    now: Instant,
    stamp: u64,
}

impl Rig {
    /// A supervisor that has not heard from the robot yet.
    fn bare(cfg: SafetyConfig) -> Rig {
        let sup = Supervisor::new(cfg, RobotModel::tiago_dual()).unwrap();
        let joints = sup.filter().joints().to_vec();
        Rig {
            sup,
            joints,
            now: Instant::now(),
            stamp: 1,
        }
    }

    /// A supervisor whose robot stands in the home pose.
    fn new(cfg: SafetyConfig) -> Rig {
        let mut r = Rig::bare(cfg);
        let home = echo_robot::home_pose();
        let q: Vec<f64> = r
            .joints
            .iter()
            .map(|j| home.iter().find(|(n, _)| n == j).map_or(0.0, |(_, v)| *v))
            .collect();
        r.feed_state(&q);
        r
    }

    fn q(&self) -> Vec<f64> {
        self.sup.filter().state().iter().map(|s| s.q).collect()
    }

    fn idx(&self, j: &str) -> usize {
        self.joints.iter().position(|x| x == j).unwrap()
    }

    fn feed_state(&mut self, q: &[f64]) {
        let _ = self.feed_from("robot", q);
    }

    /// A joint state from sender `source`.
    fn feed_from(
        &mut self,
        source: &str,
        q: &[f64],
    ) -> Result<(), echo_safety::measured::StateFault> {
        let js = JointState {
            header: Header::new("tiago", source, ""),
            name: self.joints.clone(),
            position: q.to_vec(),
            velocity: vec![],
            base: None,
        };
        self.sup.on_joint_state(&js, self.now)
    }

    /// A plan moving `joint` by `delta` over `secs`, from where the robot is commanded to be.
    fn plan(&mut self, joint: &str, delta: f64, secs: f64) -> RobotPlan {
        let here = self.q();
        let mut there = here.clone();
        there[self.idx(joint)] += delta;
        let mut h = Header::new("tiago", "forecaster", "odom");
        h.stamp_ns = self.stamp;
        self.stamp += 1;
        RobotPlan {
            header: h,
            mode: ControlMode::Forecast,
            joint_names: self.joints.clone(),
            points: vec![
                PlanPoint {
                    t: 0.0,
                    positions: here,
                    base: None,
                },
                PlanPoint {
                    t: secs,
                    positions: there,
                    base: None,
                },
            ],
        }
    }

    /// A plan from where the robot is commanded to be to absolute `targets` in `secs`.
    fn plan_to(&mut self, targets: &[(&str, f64)], secs: f64) -> RobotPlan {
        let mut p = self.plan(targets[0].0, 0.0, secs);
        for (j, v) in targets {
            let i = self.idx(j);
            p.points[1].positions[i] = *v;
        }
        p
    }

    /// `n` cycles while a forecaster sends a fresh plan toward `targets` every third cycle
    /// (15 Hz), arriving `secs` after the start.
    fn follow(&mut self, targets: &[(&str, f64)], secs: f64, n: usize) -> Vec<echo_safety::Tick> {
        let mut out = vec![];
        for k in 0..n {
            if k % 3 == 0 {
                let left = (secs - k as f64 * DT.as_secs_f64()).max(0.1);
                let p = self.plan_to(targets, left);
                let _ = self.sup.on_plan(&p, self.now);
            }
            out.push(self.tick());
        }
        out
    }

    /// Advance one cycle with a perfect robot (measured = commanded).
    fn tick(&mut self) -> echo_safety::Tick {
        self.now += DT;
        let q = self.q();
        self.feed_state(&q);
        self.sup.tick(self.now)
    }
}

fn speed(r: &Rig) -> f64 {
    r.sup
        .filter()
        .state()
        .iter()
        .map(|s| s.v.abs())
        .fold(0.0, f64::max)
}

#[test]
fn no_plan_means_no_motion() {
    let mut r = Rig::new(SafetyConfig::default());
    let t = r.tick();
    assert_eq!(t.state, SafetyState::Holding);
    assert!(t.reasons.iter().any(|x| x.contains("no valid plan")));
    assert_eq!(speed(&r), 0.0);
}

#[test]
fn plan_timeout_stops_within_the_bound_and_recovery_has_no_jump() {
    let cfg = SafetyConfig::default();
    let mut r = Rig::new(cfg.clone());
    let target = r.q()[r.idx("arm_right_1_joint")] + 1.2;
    for t in r.follow(&[("arm_right_1_joint", target)], 2.0, 30) {
        assert_ne!(t.state, SafetyState::Stopping);
    }
    assert!(speed(&r) > 0.1, "moving");
    // The plan stream stops.
    let last_plan = r.now - 2 * DT;
    let stop_time = r.sup.filter().stop_time();
    let mut stopped_at = None;
    for _ in 0..200 {
        let t = r.tick();
        if t.state == SafetyState::Holding {
            stopped_at = Some(r.now);
            break;
        }
    }
    let stopped_at = stopped_at.expect("robot stops");
    let took = (stopped_at - last_plan).as_secs_f64();
    let bound = cfg.plan_deadline_ms / 1e3 + stop_time + 2.0 * DT.as_secs_f64();
    assert!(
        took <= bound,
        "stopped {took:.3} s after the last plan (bound {bound:.3} s)"
    );
    assert_eq!(speed(&r), 0.0);
    // Plans return: motion resumes from where the robot is, continuously.
    let mut prev = r.q();
    let back = prev[r.idx("arm_right_1_joint")] - 0.5;
    for _ in 0..7 {
        r.follow(&[("arm_right_1_joint", back)], 1.0, 3);
        let q = r.q();
        for (j, (a, b)) in q.iter().zip(&prev).enumerate() {
            let vmax = r.sup.filter().limits()[j].velocity;
            assert!(
                (a - b).abs() <= 3.0 * vmax * DT.as_secs_f64() + 1e-9,
                "jump on {}",
                r.joints[j]
            );
        }
        prev = q;
    }
    assert!(speed(&r) > 0.05, "motion resumed");
}

#[test]
fn estop_latches_until_reset() {
    let mut r = Rig::new(SafetyConfig::default());
    let p = r.plan("head_1_joint", 0.8, 1.0);
    r.sup.on_plan(&p, r.now).unwrap();
    for _ in 0..10 {
        r.tick();
    }
    r.sup.on_estop(&EStop {
        header: Header::new("tiago", "op", ""),
        action: EStopAction::Engage,
        reason: "button".into(),
    });
    for _ in 0..100 {
        // Fresh plans keep arriving: they must not move the robot.
        let p = r.plan("head_1_joint", 0.3, 1.0);
        let _ = r.sup.on_plan(&p, r.now);
        let t = r.tick();
        assert_eq!(t.state, SafetyState::EStopped);
    }
    assert_eq!(speed(&r), 0.0, "stopped under e-stop");
    r.sup.on_estop(&EStop {
        header: Header::new("tiago", "op", ""),
        action: EStopAction::Reset,
        reason: "clear".into(),
    });
    let t = r.tick();
    assert_ne!(t.state, SafetyState::EStopped);
    assert_eq!(speed(&r), 0.0, "a reset alone does not move the robot");
    let p = r.plan("head_1_joint", -0.3, 1.0);
    r.sup.on_plan(&p, r.now).unwrap();
    for _ in 0..10 {
        r.tick();
    }
    assert!(speed(&r) > 0.0, "a new plan after the reset moves it");
}

#[test]
fn invalid_plans_are_rejected_and_the_last_valid_plan_continues() {
    let mut r = Rig::new(SafetyConfig::default());
    let mut twin = Rig::new(SafetyConfig::default());
    twin.now = r.now;
    let good = r.plan("head_1_joint", 0.6, 1.0);
    r.sup.on_plan(&good, r.now).unwrap();
    twin.sup.on_plan(&good, twin.now).unwrap();
    r.tick();
    twin.tick();

    let mut unknown = r.plan("head_1_joint", 0.1, 1.0);
    unknown.joint_names[0] = "arm_left_8_joint".into();
    assert_eq!(
        r.sup.on_plan(&unknown, r.now).unwrap_err().reason(),
        "unknown_joint"
    );

    let mut far = r.plan("head_1_joint", 0.1, 1.0);
    let i = r.idx("arm_left_2_joint");
    far.points[0].positions[i] += 1.0;
    assert_eq!(
        r.sup.on_plan(&far, r.now).unwrap_err().reason(),
        "far_from_state"
    );

    let mut old = r.plan("head_1_joint", 0.1, 1.0);
    old.header.stamp_ns = good.header.stamp_ns;
    assert_eq!(
        r.sup.on_plan(&old, r.now).unwrap_err().reason(),
        "out_of_order"
    );

    let mut imitation = r.plan("head_1_joint", 0.1, 1.0);
    imitation.mode = ControlMode::Imitation;
    assert_eq!(
        r.sup.on_plan(&imitation, r.now).unwrap_err().reason(),
        "wrong_mode"
    );

    for k in [
        "plan/unknown_joint",
        "plan/far_from_state",
        "plan/out_of_order",
        "plan/wrong_mode",
    ] {
        assert_eq!(r.sup.counters().get(k), Some(&1), "{k}");
    }
    // Still following the good plan exactly as a twin that never saw the bad ones.
    for _ in 0..8 {
        r.tick();
        twin.tick();
        assert_eq!(r.q(), twin.q());
    }
    assert!(
        r.q()[r.idx("head_1_joint")] > 0.005,
        "moving toward the good plan"
    );
}

#[test]
fn stale_joint_state_stops_the_robot() {
    let mut r = Rig::new(SafetyConfig::default());
    let p = r.plan("head_1_joint", 0.8, 2.0);
    r.sup.on_plan(&p, r.now).unwrap();
    for _ in 0..10 {
        r.tick();
    }
    // The robot interface goes quiet (plans keep coming).
    let mut reasons = vec![];
    for _ in 0..100 {
        r.now += DT;
        let p = r.plan("head_1_joint", 0.1, 2.0);
        let _ = r.sup.on_plan(&p, r.now);
        let t = r.sup.tick(r.now);
        reasons = t.reasons;
    }
    assert!(
        reasons.iter().any(|x| x.contains("joint state")),
        "{reasons:?}"
    );
    assert_eq!(speed(&r), 0.0);
}

#[test]
fn lost_liveliness_of_a_required_service_stops_the_robot() {
    let cfg = SafetyConfig {
        required_alive: vec!["forecaster".into()],
        ..Default::default()
    };
    let mut r = Rig::new(cfg);
    let p = r.plan("head_1_joint", 0.8, 2.0);
    r.sup.on_plan(&p, r.now).unwrap();
    r.tick();
    r.sup.on_alive("forecaster", false);
    let t = r.tick();
    assert!(t
        .reasons
        .iter()
        .any(|x| x.contains("forecaster liveliness lost")));
    for _ in 0..100 {
        r.tick();
    }
    assert_eq!(speed(&r), 0.0);
}

fn person(x: f64, y: f64) -> HumanSkeletons {
    echo_safety::bench_support::partner_skeletons(echo_motion_free_person(x, y))
}

/// A standing person facing the robot at (x, y), right hand held out toward the robot.
fn echo_motion_free_person(x: f64, y: f64) -> Vec<[f64; 3]> {
    let mut j = vec![[x, y, 0.95]; 22];
    let set = |j: &mut Vec<[f64; 3]>, i: usize, p: [f64; 3]| j[i] = [x + p[0], y + p[1], p[2]];
    for (i, p) in [
        (1, [0.0, -0.09, 0.86]),
        (2, [0.0, 0.09, 0.86]),
        (3, [0.0, 0.0, 1.06]),
        (4, [0.0, -0.1, 0.46]),
        (5, [0.0, 0.1, 0.46]),
        (6, [0.0, 0.0, 1.2]),
        (7, [0.0, -0.1, 0.06]),
        (8, [0.0, 0.1, 0.06]),
        (9, [0.0, 0.0, 1.28]),
        (10, [-0.12, -0.1, 0.0]),
        (11, [-0.12, 0.1, 0.0]),
        (12, [0.0, 0.0, 1.52]),
        (13, [0.0, -0.07, 1.41]),
        (14, [0.0, 0.07, 1.41]),
        (15, [0.0, 0.0, 1.63]),
        (16, [0.0, -0.18, 1.43]),
        (17, [0.0, 0.18, 1.43]),
        (18, [0.0, -0.2, 1.15]),
        (19, [-0.25, 0.2, 1.2]),
        (20, [0.0, -0.2, 0.9]),
        (21, [-0.5, 0.15, 1.05]),
    ] {
        set(&mut j, i, p);
    }
    j
}

#[test]
fn an_approaching_person_slows_then_stops_the_robot() {
    let mut r = Rig::new(SafetyConfig::default());
    let mut scales = vec![];
    let target = r.q()[r.idx("arm_right_1_joint")] + 0.3;
    for x in [3.0, 2.0, 1.6, 1.3, 1.1, 0.9, 0.7] {
        r.sup.on_humans(&person(x, 0.0), r.now);
        let t = r
            .follow(&[("arm_right_1_joint", target)], 1.0, 1)
            .pop()
            .unwrap();
        scales.push((x, t.speed_scale, t.min_separation_m));
    }
    assert_eq!(scales[0].1, 1.0, "{scales:?}");
    assert!(
        scales.windows(2).all(|w| w[1].1 <= w[0].1 + 1e-9),
        "scale falls as the person nears: {scales:?}"
    );
    assert_eq!(scales.last().unwrap().1, 0.0, "{scales:?}");
    for _ in 0..100 {
        r.sup.on_humans(&person(0.7, 0.0), r.now);
        r.follow(&[("arm_right_1_joint", target)], 1.0, 1);
    }
    assert_eq!(speed(&r), 0.0, "separation halt");
}

#[test]
fn handshake_intent_lets_the_hand_approach_slowly() {
    let mut r = Rig::new(SafetyConfig::default());
    let intent = |i: Interaction| InteractionIntent {
        header: Header::new("tiago", "op", ""),
        text: String::new(),
        interaction: i,
        mode: ControlMode::Forecast,
    };
    // The person's right hand is held out 0.6 m in front of the robot's right gripper region.
    let scene = person(1.05, -0.1);
    r.sup.on_humans(&scene, r.now);
    r.sup.on_intent(&intent(Interaction::Wave));
    let p = r.plan("arm_right_1_joint", 0.2, 1.0);
    r.sup.on_plan(&p, r.now).unwrap();
    let no_contact = r.tick();
    r.sup.on_intent(&intent(Interaction::Handshake));
    let p = r.plan("arm_right_1_joint", 0.2, 1.0);
    r.sup.on_plan(&p, r.now).unwrap();
    let contact = r.tick();
    assert!(
        contact.speed_scale >= no_contact.speed_scale,
        "handshake {} vs wave {}",
        contact.speed_scale,
        no_contact.speed_scale
    );
}

#[test]
fn arms_never_drive_into_each_other() {
    let mut r = Rig::new(SafetyConfig::default());
    // Swing both arms across the body.
    let targets = [("arm_left_1_joint", 1.45), ("arm_right_1_joint", 1.45)];
    let model = RobotModel::tiago_dual();
    let body = echo_robot::collision::RobotBody::tiago(&model).unwrap();
    let mut braked = false;
    for _ in 0..150 {
        let t = r.follow(&targets, 1.5, 1).pop().unwrap();
        braked |= t.reasons.iter().any(|x| x.contains("self-collision"));
        let q = model
            .values_from(
                r.joints
                    .iter()
                    .map(String::as_str)
                    .zip(r.q())
                    .chain([("torso_lift_joint", 0.15)]),
            )
            .unwrap();
        let d = echo_robot::collision::min_self_distance(&body.at(&model, &q));
        assert!(d > -0.02, "arms interpenetrate: {d}");
    }
    assert!(braked, "the self-collision rule engaged");
}

/// Hard limits of the filter's joints, from the URDF.
fn hard_limits(r: &Rig) -> Vec<(f64, f64)> {
    r.sup.filter().hard_limits().to_vec()
}

/// Every point of `cmd` inside the hard limits; returns the first point's positions by joint.
fn check_inside_hard(r: &Rig, cmd: &RobotCommand) -> Vec<f64> {
    let hard = hard_limits(r);
    let mut first = vec![f64::NAN; r.joints.len()];
    for tr in &cmd.trajectories {
        for p in &tr.points {
            for (n, q) in tr.joint_names.iter().zip(&p.positions) {
                let i = r.idx(n);
                assert!(
                    *q >= hard[i].0 - 1e-9 && *q <= hard[i].1 + 1e-9,
                    "{n} commanded {q} outside its hard limits {:?}",
                    hard[i]
                );
            }
        }
        for (n, q) in tr.joint_names.iter().zip(&tr.points[0].positions) {
            first[r.idx(n)] = *q;
        }
    }
    first
}

#[test]
fn out_of_limit_joint_states_never_reach_the_command() {
    // A second stream interleaved with the real robot reports joints far outside their hard
    // limits for 3 s at 100 Hz; then it stops on its own.
    for (joint, bad) in [
        ("arm_right_1_joint", 2.5),
        ("arm_right_1_joint", 1e9),
        ("torso_lift_joint", 50.0),
        ("arm_left_4_joint", -7.0),
    ] {
        let mut r = Rig::new(SafetyConfig::default());
        let p = r.plan("head_1_joint", 0.3, 1.0);
        r.sup.on_plan(&p, r.now).unwrap();
        for _ in 0..10 {
            r.tick();
        }
        let v = r.sup.filter().limits()[r.idx(joint)].velocity;
        let cmd = r.sup.tick(r.now).command.unwrap();
        let mut prev = check_inside_hard(&r, &cmd);
        let mut faulted = false;
        for k in 0..150 {
            r.now += DT;
            let real = r.q();
            let mut forged = real.clone();
            forged[r.idx(joint)] = bad;
            // Twice per cycle from the robot's own source name (as a second publisher would),
            // once real, once forged.
            let _ = r.feed_from("robot", &real);
            assert!(r.feed_from("robot", &forged).is_err(), "cycle {k}");
            let t = r.sup.tick(r.now);
            faulted |= t.reasons.iter().any(|x| x.contains("sensor fault"));
            assert_ne!(
                t.state,
                SafetyState::Following,
                "cycle {k}: {:?}",
                t.reasons
            );
            let first = check_inside_hard(&r, &t.command.unwrap());
            for (i, (a, b)) in first.iter().zip(&prev).enumerate() {
                let vmax = r.sup.filter().limits()[i].velocity;
                assert!(
                    (a - b).abs() <= vmax * DT.as_secs_f64() * (1.0 + 1e-6) + 1e-9,
                    "{}: {b} → {a} between commands",
                    r.joints[i]
                );
            }
            prev = first;
        }
        assert!(faulted, "{joint} = {bad} must be named as a sensor fault");
        assert!(r.sup.counters()["state/out_of_limits"] > 0);
        let q_cmd = r.q()[r.idx(joint)];
        assert!(
            (q_cmd - bad).abs() > 0.5 && v > 0.0,
            "{joint} commanded {q_cmd}"
        );
        // The forged stream stops: after fault_clear_ms of plausible samples the fault clears.
        let mut cleared = false;
        for _ in 0..40 {
            let t = r.tick();
            cleared = !t.reasons.iter().any(|x| x.contains("sensor fault"));
        }
        assert!(
            cleared,
            "the fault clears once the samples are plausible again"
        );
        assert_eq!(r.sup.counters()["state/fault_cleared"], 1);
    }
}

#[test]
fn a_consistent_but_wrong_measured_state_never_moves_the_command() {
    // The measured state drifts away from the command at a speed the joint could move, and
    // stays there: the robot stops and holds where it was commanded, with no jump in the
    // command, until the measured state agrees again or the operator resets.
    let mut r = Rig::new(SafetyConfig::default());
    let i = r.idx("arm_right_2_joint");
    let start = r.q();
    let cmd = r.sup.tick(r.now).command.unwrap();
    let mut prev = check_inside_hard(&r, &cmd);
    let mut offset = 0.0;
    let mut stopped = false;
    for _ in 0..200 {
        r.now += DT;
        offset = (offset - 0.01f64).max(-0.6);
        let mut m = r.q();
        m[i] = start[i] + offset;
        r.feed_from("robot", &m).unwrap();
        let t = r.sup.tick(r.now);
        stopped |= t.reasons.iter().any(|x| x.contains("from its command"));
        let first = check_inside_hard(&r, &t.command.unwrap());
        assert!(
            (first[i] - prev[i]).abs() <= 1e-9,
            "no plan: the command holds still whatever the measured state says"
        );
        prev = first;
    }
    assert!(stopped);
    assert!((r.q()[i] - start[i]).abs() < 1e-12);
    assert_eq!(r.sup.counters().get("resync"), None);
    // The operator's reset at rest re-anchors at the (plausible) measured position.
    r.sup.on_estop(&EStop {
        header: Header::new("tiago", "operator", ""),
        action: EStopAction::Reset,
        reason: "arm moved by hand".into(),
    });
    assert!((r.q()[i] - (start[i] - 0.6)).abs() < 1e-9);
    assert_eq!(r.sup.counters()["resync"], 1);
}

#[test]
fn joint_states_from_a_second_source_are_refused() {
    let mut r = Rig::new(SafetyConfig::default());
    let q = r.q();
    let mut other = q.clone();
    other[r.idx("head_2_joint")] += 0.05;
    let e = r.feed_from("intruder", &other).unwrap_err();
    assert_eq!(e.reason(), "foreign_source");
    assert_eq!(r.sup.counters()["state/foreign_source"], 1);
    let t = r.tick();
    assert!(
        !t.reasons.iter().any(|x| x.contains("sensor fault")),
        "a refused source is not a fault of the robot's sensors"
    );
    // A configured source: only it is accepted, even as the first one heard.
    let cfg = SafetyConfig {
        state_source: Some("ros2".into()),
        ..Default::default()
    };
    let mut r2 = Rig::bare(cfg);
    assert!(r2.feed_from("robot", &q).is_err());
    assert!(r2.sup.tick(r2.now).command.is_none());
    r2.feed_from("ros2", &q).unwrap();
    assert!(r2.sup.tick(r2.now).command.is_some());
}

#[test]
fn a_robot_starting_beyond_its_hard_limits_gets_no_command() {
    let mut r = Rig::bare(SafetyConfig::default());
    let mut q = vec![0.0; r.joints.len()];
    q[r.idx("torso_lift_joint")] = 0.2;
    let mut bad = q.clone();
    bad[r.idx("torso_lift_joint")] = 50.0;
    assert!(r.feed_from("robot", &bad).is_err());
    let t = r.sup.tick(r.now);
    assert!(t.command.is_none());
    assert!(t.reasons[0].contains("sensor fault"), "{:?}", t.reasons);
    // Plausible samples for fault_clear_ms: the robot starts where it is.
    r.now += Duration::from_millis(10);
    let _ = r.feed_from("robot", &q); // jump from 50 m: still a fault
    for _ in 0..30 {
        r.now += DT;
        let _ = r.feed_from("robot", &q);
        r.sup.tick(r.now);
    }
    let t = r.sup.tick(r.now);
    assert!(t.command.is_some(), "{:?}", t.reasons);
    assert!((r.q()[r.idx("torso_lift_joint")] - 0.2).abs() < 1e-12);
}

#[test]
fn a_robot_starting_between_its_soft_and_hard_limits_recovers_inward_slowly() {
    let mut r = Rig::bare(SafetyConfig::default());
    let i = r.idx("head_1_joint");
    let soft = r.sup.filter().limits()[i];
    let hard = hard_limits(&r)[i];
    assert!(hard.1 > soft.upper, "the URDF insets the soft limit");
    let home = echo_robot::home_pose();
    let mut q: Vec<f64> = r
        .joints
        .iter()
        .map(|j| home.iter().find(|(n, _)| n == j).map_or(0.0, |(_, v)| *v))
        .collect();
    // Beyond the hard limit by less than the tolerance: the command starts at the hard limit.
    q[i] = hard.1 + 0.005;
    r.feed_from("robot", &q).unwrap();
    assert!((r.q()[i] - hard.1).abs() < 1e-12);
    // A plan asks for a target further out, then for one inside: the joint only moves in,
    // at the recovery speed while outside its soft range.
    let p = r.plan_to(&[("head_1_joint", 3.0)], 1.0);
    r.sup.on_plan(&p, r.now).unwrap();
    for _ in 0..20 {
        r.tick();
        assert!(r.q()[i] <= hard.1 + 1e-12);
    }
    let mut max_v: f64 = 0.0;
    for _ in 0..200 {
        if r.q()[i] <= soft.upper {
            break;
        }
        let p = r.plan_to(&[("head_1_joint", 0.5)], 1.0);
        let _ = r.sup.on_plan(&p, r.now);
        let before = r.q()[i];
        r.tick();
        assert!(r.q()[i] <= before + 1e-12, "only inward");
        max_v = max_v.max(r.sup.filter().state()[i].v.abs());
    }
    assert!(r.q()[i] <= soft.upper, "back inside the soft range");
    assert!(
        max_v <= 0.2 * soft.velocity + 1e-9,
        "recovery speed {max_v} over 0.2·V"
    );
}
