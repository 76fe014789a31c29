//! The safety service's loop driven by scripted inputs, no network: no command before the robot's
//! state is known; hostile joint states (out of range, from a second publisher, ROS 2 garbage) are
//! refused, counted, named in the status, and no command leaves the hard limits; a latched
//! e-stop shows in the status; plans that stop coming, or a required service that disappears,
//! hold the robot and say why; the status goes out every fifth cycle and on every change.

use std::time::{Duration, Instant};

use anyhow::Result;
use echo_bus::{Received, Stats};
use echo_msgs::{
    ControlMode, EStop, EStopAction, Header, Interaction, InteractionIntent, JointState, PlanPoint,
    RobotCommand, RobotPlan, SafetyState, SafetyStatus,
};
use echo_robot::RobotModel;
use echo_safety::{SafetyConfig, Supervisor};
use futures::stream;
use safety::{run, Input, Loop, Output};

#[derive(Default)]
struct Collect {
    commands: Vec<RobotCommand>,
    statuses: Vec<SafetyStatus>,
    /// Commands sent before each status (= its cycle, once the state is known).
    status_after: Vec<usize>,
}

impl Output for Collect {
    async fn command(&mut self, cmd: RobotCommand) -> Result<()> {
        self.commands.push(cmd);
        Ok(())
    }

    async fn status(&mut self, st: SafetyStatus) -> Result<()> {
        self.statuses.push(st);
        self.status_after.push(self.commands.len());
        Ok(())
    }
}

fn rx<M>(msg: M, at: Instant) -> Received<M> {
    Received { msg, at }
}

fn home() -> (Vec<String>, Vec<f64>) {
    let sup = Supervisor::new(SafetyConfig::default(), RobotModel::tiago_dual()).unwrap();
    let names = sup.filter().joints().to_vec();
    let home = echo_robot::home_pose();
    let q = names
        .iter()
        .map(|j| home.iter().find(|(n, _)| n == j).map_or(0.0, |(_, v)| *v))
        .collect();
    (names, q)
}

fn state(names: &[String], q: &[f64]) -> JointState {
    JointState {
        header: Header::new("tiago", "robot", ""),
        name: names.to_vec(),
        position: q.to_vec(),
        velocity: vec![],
        base: None,
    }
}

#[tokio::test]
async fn hostile_joint_states_are_refused_and_never_reach_a_command() {
    let (names, q) = home();
    let t0 = Instant::now();
    let dt = Duration::from_millis(20);
    let mut inputs = vec![Input::Tick(t0)];
    let i = names.iter().position(|n| n == "arm_right_1_joint").unwrap();
    let mut forged = q.clone();
    forged[i] = 2.5;
    let garbage_cdr = vec![0u8, 1, 0, 0, 9, 9];
    for k in 1..=100u32 {
        let now = t0 + dt * k;
        inputs.push(Input::State(rx(state(&names, &q), now)));
        if (20..70).contains(&k) {
            // A second publisher under the robot's name, and ROS 2 garbage.
            inputs.push(Input::State(rx(state(&names, &forged), now)));
            inputs.push(Input::Ros2State(garbage_cdr.clone(), now));
        }
        if k == 80 {
            inputs.push(Input::EStop(rx(
                EStop {
                    header: Header::new("tiago", "operator", ""),
                    action: EStopAction::Engage,
                    reason: "test".into(),
                },
                now,
            )));
        }
        inputs.push(Input::Tick(now));
    }
    let stats = Stats::new("safety");
    let sup = Supervisor::new(SafetyConfig::default(), RobotModel::tiago_dual()).unwrap();
    let hard = sup.filter().hard_limits().to_vec();
    let mut lp = Loop::new(sup, "tiago");
    let mut out = Collect::default();
    run(stream::iter(inputs), &mut out, &mut lp, &stats)
        .await
        .unwrap();

    // No command before the state; one per tick after it.
    assert_eq!(out.commands.len(), 100);
    assert!(out.statuses[0].reasons[0].contains("waiting"));
    // Every point inside the hard limits.
    for c in &out.commands {
        for tr in &c.trajectories {
            for p in &tr.points {
                for (n, x) in tr.joint_names.iter().zip(&p.positions) {
                    let j = names.iter().position(|m| m == n).unwrap();
                    assert!(x >= &hard[j].0 && x <= &hard[j].1, "{n} commanded {x}");
                }
            }
        }
    }
    // Named, counted, and over: the fault clears after the forged stream stops.
    let named = out.statuses.iter().any(|s| {
        s.reasons
            .iter()
            .any(|r| r.contains("sensor fault") && r.contains("arm_right_1_joint"))
    });
    assert!(named);
    assert!(stats.rejected_count("robot_state", "out_of_limits") > 0);
    assert!(stats.rejected_count("ros2_joint_states", "invalid") > 0);
    let counters = &out.statuses.last().unwrap().counters;
    assert_eq!(
        counters.get("state/fault_cleared"),
        Some(&1),
        "{counters:?}"
    );
    // The e-stop shows.
    assert_eq!(out.statuses.last().unwrap().state, SafetyState::EStopped);
    assert_eq!(lp.state(), Some(SafetyState::EStopped));
}

/// A plan holding the robot where it is for 1 s (imitation mode, as the retargeter sends it).
fn still_plan(names: &[String], q: &[f64], stamp_ns: u64) -> RobotPlan {
    let mut header = Header::new("tiago", "retargeter", "odom");
    header.stamp_ns = stamp_ns;
    RobotPlan {
        header,
        mode: ControlMode::Imitation,
        joint_names: names.to_vec(),
        points: [0.0, 1.0]
            .iter()
            .map(|t| PlanPoint {
                t: *t,
                positions: q.to_vec(),
                base: None,
            })
            .collect(),
    }
}

#[tokio::test]
async fn stale_plans_and_a_lost_required_service_hold_the_robot_and_the_status_says_why() {
    let (names, q) = home();
    let t0 = Instant::now();
    let dt = Duration::from_millis(20);
    let cfg = SafetyConfig {
        required_alive: vec!["mock-robot".into()],
        ..SafetyConfig::default()
    };
    let deadline_ms = cfg.plan_deadline_ms;
    let mut inputs = vec![
        Input::Prompt(rx(
            InteractionIntent {
                header: Header::new("tiago", "operator", ""),
                text: "copy me".into(),
                interaction: Interaction::Imitation,
                mode: ControlMode::Imitation,
            },
            t0,
        )),
        Input::Alive("mock-robot".into(), true),
    ];
    // 0–2 s: plans at 15 Hz (every third cycle); 2–3 s: none (stale); 3–4 s: plans again;
    // at 3.5 s the robot interface's liveliness is lost, at 3.8 s it is back.
    let mut stamp = 1_000;
    for k in 1..=200u32 {
        let now = t0 + dt * k;
        inputs.push(Input::State(rx(state(&names, &q), now)));
        let planning = k <= 100 || k > 150;
        if planning && k % 3 == 0 {
            stamp += 66_000_000;
            inputs.push(Input::Retarget(rx(still_plan(&names, &q, stamp), now)));
        }
        if k == 175 {
            inputs.push(Input::Alive("mock-robot".into(), false));
        }
        if k == 190 {
            inputs.push(Input::Alive("mock-robot".into(), true));
        }
        inputs.push(Input::Tick(now));
    }
    let stats = Stats::new("safety");
    let sup = Supervisor::new(cfg, RobotModel::tiago_dual()).unwrap();
    let mut lp = Loop::new(sup, "tiago");
    let mut out = Collect::default();
    run(stream::iter(inputs), &mut out, &mut lp, &stats)
        .await
        .unwrap();
    assert_eq!(
        out.commands.len(),
        200,
        "one command per cycle once the state is known"
    );

    // The status in force at a cycle: the last one sent at or before it.
    let at = |cycle: usize| -> &SafetyStatus {
        let i = out.status_after.partition_point(|c| *c <= cycle);
        &out.statuses[i.saturating_sub(1)]
    };
    let following =
        |s: &SafetyStatus| matches!(s.state, SafetyState::Following | SafetyState::Limiting);
    assert!(following(at(90)), "{:?}", at(90));
    // Stale: held after the deadline, the reason names the plan's age.
    let stale_cycle = 100 + (deadline_ms / 20.0).ceil() as usize + 10;
    let s = at(stale_cycle.min(149));
    assert!(!following(s), "{s:?}");
    assert!(
        s.reasons.iter().any(|r| r.contains("no valid plan for")),
        "{:?}",
        s.reasons
    );
    // Plans again: following.
    assert!(following(at(170)), "{:?}", at(170));
    // A required service lost: held, named; back: following.
    let s = at(180);
    assert!(!following(s), "{s:?}");
    assert!(
        s.reasons
            .iter()
            .any(|r| r.contains("mock-robot liveliness lost")),
        "{:?}",
        s.reasons
    );
    assert_eq!(
        out.statuses
            .last()
            .unwrap()
            .counters
            .get("liveliness_lost/mock-robot"),
        Some(&1)
    );
    assert!(following(out.statuses.last().unwrap()));

    // Cadence: a status every fifth cycle, plus one per state change, and no more.
    let changes = out
        .statuses
        .windows(2)
        .filter(|w| w[0].state != w[1].state)
        .count();
    let n = out.statuses.len();
    assert!(n >= 201 / 5, "{n} statuses");
    assert!(
        n <= 201 / 5 + 1 + changes,
        "{n} statuses, {changes} changes"
    );
}
