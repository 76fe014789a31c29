//! The safety service's loop driven by scripted inputs, no network: no command before the robot's
//! state is known; hostile joint states (out of range, from a second publisher, ROS 2 garbage) are
//! refused, counted, named in the status, and no command leaves the hard limits; a latched
//! e-stop shows in the status.

use std::time::{Duration, Instant};

use anyhow::Result;
use echo_bus::{Received, Stats};
use echo_msgs::{EStop, EStopAction, Header, JointState, RobotCommand, SafetyState, SafetyStatus};
use echo_robot::RobotModel;
use echo_safety::{SafetyConfig, Supervisor};
use futures::stream;
use safety::{run, Input, Loop, Output};

#[derive(Default)]
struct Collect {
    commands: Vec<RobotCommand>,
    statuses: Vec<SafetyStatus>,
}

impl Output for Collect {
    async fn command(&mut self, cmd: RobotCommand) -> Result<()> {
        self.commands.push(cmd);
        Ok(())
    }

    async fn status(&mut self, st: SafetyStatus) -> Result<()> {
        self.statuses.push(st);
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
