//! safety + simulated robot as separate processes over Zenoh; the test plays the forecaster.
//! The plan stream stops → the robot is stopped within the documented bound with no limit
//! exceeded; plans resume → motion resumes without a jump.

use std::time::{Duration, Instant};

use echo_bus::testkit::within;
use echo_bus::topics;
use echo_msgs::{now_ns, ControlMode, Forecast, Header, JointState, PlanPoint, RobotPlan};
use echo_robot::groups::motion_groups;
use echo_robot::RobotModel;
use echo_system_tests::Harness;

/// Stop bound: plan deadline 0.2 s + the longest jerk-limited stop at this motion's speed
/// (≤ 0.8 s) + the simulated controllers settling below 0.01 rad/s (≤ 0.3 s) + transport.
const STOP_BOUND_S: f64 = 1.5;

fn plan_from(js: &JointState, joints: &[String], t0: f64, seq: u64) -> RobotPlan {
    let robot = js.header.robot_id.clone();
    let here: Vec<f64> = joints
        .iter()
        .map(|j| js.position_of(j).unwrap_or(0.0))
        .collect();
    let i = joints
        .iter()
        .position(|j| j == "arm_right_1_joint")
        .unwrap();
    let wave = |t: f64| -1.1 + 0.4 * (2.0 * std::f64::consts::PI * t / 3.0).sin();
    let mut h = Header::new(&robot, "test-forecaster", "odom");
    h.stamp_ns = now_ns() + seq;
    RobotPlan {
        header: h,
        mode: ControlMode::Forecast,
        joint_names: joints.to_vec(),
        points: (0..16)
            .map(|k| {
                let t = k as f64 / 15.0;
                let mut q = here.clone();
                q[i] = if k == 0 { here[i] } else { wave(t0 + t) };
                PlanPoint {
                    t,
                    positions: q,
                    base: None,
                }
            })
            .collect(),
    }
}

struct Driver {
    start: Instant,
    latest: Option<JointState>,
    samples: Vec<(f64, JointState)>,
    seq: u64,
    phase_t: f64,
    joints: Vec<String>,
}

impl Driver {
    /// For `secs`: record robot states; when `send`, publish a forecast with a plan at 15 Hz.
    async fn run(
        &mut self,
        secs: f64,
        send: bool,
        states: &echo_bus::Inbox<JointState>,
        forecasts: &echo_bus::Publisher<Forecast>,
    ) {
        let until = Instant::now() + Duration::from_secs_f64(secs);
        let mut tick = tokio::time::interval(Duration::from_millis(66));
        while Instant::now() < until {
            tick.tick().await;
            for s in states.drain() {
                self.samples
                    .push((self.start.elapsed().as_secs_f64(), s.msg.clone()));
                self.latest = Some(s.msg);
            }
            if !send {
                continue;
            }
            let Some(js) = self.latest.as_ref() else {
                continue;
            };
            self.seq += 1;
            let plan = plan_from(js, &self.joints, self.phase_t, self.seq);
            self.phase_t += 1.0 / 15.0;
            let f = Forecast {
                header: Header::new(&js.header.robot_id, "test-forecaster", "base_footprint"),
                model: "scripted".into(),
                rate_hz: 15.0,
                partner_id: 0,
                human: vec![],
                robot: Some(plan),
                inference_ms: 0.0,
            };
            forecasts.put(f).await.unwrap();
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn plan_loss_stops_the_robot_and_resumption_has_no_jump() -> anyhow::Result<()> {
    let mut h = Harness::new("sys-safety", 2)?;
    h.spawn_services("single", &["mock-robot", "safety"])?;
    let bus = h.bus("test-forecaster").await?;
    let robot = bus.robot().clone();
    let states = bus.subscribe(&topics::robot_state(&robot)).await?;
    let commands = bus.subscribe(&topics::command(&robot)).await?;
    let forecasts = bus.publisher(&topics::forecast(&robot)).await?;
    h.wait_alive(&bus, &["mock-robot", "safety"], Duration::from_secs(30))
        .await?;
    within(10.0, "robot state", states.recv()).await;

    let model = RobotModel::tiago_dual();
    let joints: Vec<String> = motion_groups()
        .iter()
        .flat_map(|g| g.joints.clone())
        .collect();
    let mut d = Driver {
        start: Instant::now(),
        latest: None,
        samples: vec![],
        seq: 0,
        phase_t: 0.0,
        joints: joints.clone(),
    };
    let (states, forecasts) = (&states, &forecasts);
    d.run(3.0, true, states, forecasts).await;
    let v_arm = |js: &JointState| {
        let i = js
            .name
            .iter()
            .position(|n| n == "arm_right_1_joint")
            .unwrap();
        js.velocity[i].abs()
    };
    let max_v_moving = d.samples.iter().map(|(_, s)| v_arm(s)).fold(0.0, f64::max);
    assert!(
        max_v_moving > 0.1,
        "the arm waved: peak {max_v_moving} rad/s\n{}",
        h.log_tail("safety")
    );

    // The plan stream stops.
    let t_stop = d.start.elapsed().as_secs_f64();
    d.run(2.5, false, states, forecasts).await;
    let max_speed = |s: &JointState| s.velocity.iter().map(|v| v.abs()).fold(0.0, f64::max);
    // Stopped = every later sample below 0.01 rad/s (a wave passes through zero speed too).
    let after_stop: Vec<&(f64, JointState)> =
        d.samples.iter().filter(|(t, _)| *t > t_stop).collect();
    let last_moving = after_stop.iter().rposition(|(_, s)| max_speed(s) >= 0.01);
    let stopped_at = match last_moving {
        Some(i) => after_stop
            .get(i + 1)
            .map(|(t, _)| *t)
            .expect("the robot stops"),
        None => t_stop,
    };
    let took = stopped_at - t_stop;
    eprintln!("stopped {took:.3} s after the last plan (bound {STOP_BOUND_S} s)");
    assert!(took <= STOP_BOUND_S, "stopped after {took:.3} s");

    // Plans resume: no jump in the measured motion, and it moves again.
    let t_resume = d.start.elapsed().as_secs_f64();
    d.run(2.5, true, states, forecasts).await;
    let after: Vec<&(f64, JointState)> = d
        .samples
        .iter()
        .filter(|(t, _)| *t > t_resume - 0.2)
        .collect();
    for w in after.windows(2) {
        let (ta, a) = &w[0];
        let (tb, b) = &w[1];
        let dt = (tb - ta).max(0.01);
        for (k, n) in a.name.iter().enumerate() {
            if let Some(l) = model.limits(n) {
                let dq = (b.position[k] - a.position[k]).abs();
                assert!(
                    dq <= l.velocity * dt * 1.5 + 1e-6,
                    "jump on {n}: {dq} in {dt} s"
                );
            }
        }
    }
    assert!(after.iter().any(|(_, s)| v_arm(s) > 0.05), "motion resumed");

    // Every command point stayed inside the soft limits.
    let mut n_cmd = 0;
    for c in commands.drain() {
        n_cmd += 1;
        for tr in &c.msg.trajectories {
            for p in &tr.points {
                for (k, n) in tr.joint_names.iter().enumerate() {
                    let l = model.limits(n).unwrap();
                    assert!(
                        p.positions[k] >= l.soft_lower - 1e-9
                            && p.positions[k] <= l.soft_upper + 1e-9,
                        "{n} at {}",
                        p.positions[k]
                    );
                    assert!(p.velocities[k].abs() <= l.velocity + 1e-9);
                }
            }
        }
    }
    assert!(n_cmd > 0, "commands were observed");
    Ok(())
}
