//! Simulated TIAGo++ controllers.

use std::collections::HashMap;

use echo_msgs::{BasePose, ControllerTrajectory, Header, JointState, RobotCommand};
use echo_robot::RobotModel;
use serde::{Deserialize, Serialize};

/// Simulated robot settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimRobotConfig {
    /// First-order tracking time constant, s.
    pub time_constant_s: f64,
    /// Joint-state rate, Hz.
    pub rate_hz: f64,
    /// Base command timeout (the real controller's cmd_vel_timeout), s.
    pub base_timeout_s: f64,
    /// Sweep the head pan while no head command is active: amplitude (rad), 0 = off.
    pub head_sweep_rad: f64,
    /// Head sweep period, s.
    pub head_sweep_period_s: f64,
    /// Initial joint positions by name (others start at 0, inside their limits).
    pub initial: HashMap<String, f64>,
}

impl Default for SimRobotConfig {
    fn default() -> Self {
        let initial: HashMap<String, f64> = echo_robot::home_pose().into_iter().collect();
        SimRobotConfig {
            time_constant_s: 0.08,
            rate_hz: 100.0,
            base_timeout_s: 0.25,
            head_sweep_rad: 0.0,
            head_sweep_period_s: 6.0,
            initial,
        }
    }
}

struct Active {
    traj: ControllerTrajectory,
    start_s: f64,
}

/// The simulated robot.
pub struct SimRobot {
    cfg: SimRobotConfig,
    model: RobotModel,
    names: Vec<String>,
    q: Vec<f64>,
    v: Vec<f64>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    vmax: Vec<f64>,
    active: HashMap<String, Active>,
    base: BasePose,
    twist: Option<(f64, f64, f64)>,
    t: f64,
}

impl SimRobot {
    /// A robot at its initial pose.
    pub fn new(cfg: SimRobotConfig, model: RobotModel) -> Self {
        let names: Vec<String> = model.actuated_joints().to_vec();
        let lim = |n: &String| model.limits(n);
        let lower: Vec<f64> = names
            .iter()
            .map(|n| lim(n).map_or(f64::NEG_INFINITY, |l| l.lower))
            .collect();
        let upper: Vec<f64> = names
            .iter()
            .map(|n| lim(n).map_or(f64::INFINITY, |l| l.upper))
            .collect();
        let vmax: Vec<f64> = names
            .iter()
            .map(|n| lim(n).map_or(1.0, |l| l.velocity))
            .collect();
        let q = names
            .iter()
            .enumerate()
            .map(|(i, n)| {
                cfg.initial
                    .get(n)
                    .copied()
                    .unwrap_or(0.0)
                    .clamp(lower[i], upper[i])
            })
            .collect();
        SimRobot {
            v: vec![0.0; names.len()],
            names,
            q,
            lower,
            upper,
            vmax,
            active: HashMap::new(),
            base: BasePose {
                x: 0.0,
                y: 0.0,
                yaw: 0.0,
            },
            twist: None,
            t: 0.0,
            cfg,
            model,
        }
    }

    /// The robot model.
    pub fn model(&self) -> &RobotModel {
        &self.model
    }

    /// Simulation time, s.
    pub fn time(&self) -> f64 {
        self.t
    }

    /// Accept a command: each trajectory replaces its controller's running one (as
    /// JointTrajectoryController does); trajectories naming unknown joints are ignored and
    /// reported.
    pub fn command(&mut self, cmd: &RobotCommand) -> Vec<String> {
        let mut ignored = vec![];
        for tr in &cmd.trajectories {
            if let Some(bad) = tr.joint_names.iter().find(|n| !self.names.contains(n)) {
                ignored.push(format!("{}: unknown joint {bad}", tr.controller));
                continue;
            }
            self.active.insert(
                tr.controller.clone(),
                Active {
                    traj: tr.clone(),
                    start_s: self.t,
                },
            );
        }
        if let Some(tw) = cmd.base_twist {
            self.twist = Some((tw.linear_x, tw.angular_z, self.t));
        }
        ignored
    }

    /// Advance by `dt` seconds.
    pub fn step(&mut self, dt: f64) {
        self.t += dt;
        let mut target: Vec<Option<f64>> = vec![None; self.names.len()];
        for a in self.active.values() {
            let ts = self.t - a.start_s;
            let pts = &a.traj.points;
            let k = pts.partition_point(|p| p.time_from_start < ts);
            for (ji, name) in a.traj.joint_names.iter().enumerate() {
                let Some(idx) = self.names.iter().position(|n| n == name) else {
                    continue;
                };
                let value = if k == 0 {
                    // Before the first point: move from where we are toward it.
                    let p0 = &pts[0];
                    let w = (ts / p0.time_from_start.max(1e-6)).clamp(0.0, 1.0);
                    self.q[idx] + w * (p0.positions[ji] - self.q[idx])
                } else if k >= pts.len() {
                    pts[pts.len() - 1].positions[ji]
                } else {
                    let (a, b) = (&pts[k - 1], &pts[k]);
                    let w = (ts - a.time_from_start) / (b.time_from_start - a.time_from_start);
                    a.positions[ji] + w * (b.positions[ji] - a.positions[ji])
                };
                target[idx] = Some(value);
            }
        }
        if self.cfg.head_sweep_rad > 0.0 && !self.active.contains_key("head_controller") {
            if let Some(i) = self.names.iter().position(|n| n == "head_1_joint") {
                let w = 2.0 * std::f64::consts::PI / self.cfg.head_sweep_period_s;
                target[i] = Some(self.cfg.head_sweep_rad * (w * self.t).sin());
            }
        }
        for (i, tgt) in target.iter().enumerate() {
            let v = match *tgt {
                Some(x) => {
                    ((x - self.q[i]) / self.cfg.time_constant_s).clamp(-self.vmax[i], self.vmax[i])
                }
                None => 0.0,
            };
            self.q[i] = (self.q[i] + v * dt).clamp(self.lower[i], self.upper[i]);
            self.v[i] = v;
        }
        if let Some((vx, wz, since)) = self.twist {
            if self.t - since > self.cfg.base_timeout_s {
                self.twist = None;
            } else {
                self.base.yaw += wz * dt;
                self.base.x += vx * self.base.yaw.cos() * dt;
                self.base.y += vx * self.base.yaw.sin() * dt;
            }
        }
    }

    /// Position of a joint.
    pub fn position(&self, name: &str) -> Option<f64> {
        self.names.iter().position(|n| n == name).map(|i| self.q[i])
    }

    /// All positions by actuated-joint index.
    pub fn positions(&self) -> &[f64] {
        &self.q
    }

    /// Current positions as the model's joint values.
    pub fn joint_values(&self) -> echo_robot::JointValues {
        echo_robot::JointValues(self.q.clone())
    }

    /// Pose of `frame` (e.g. the head camera) in base_footprint now.
    pub fn frame_pose(
        &self,
        frame: &str,
    ) -> Result<nalgebra::Isometry3<f64>, echo_robot::RobotError> {
        self.model.fk(&self.joint_values(), frame)
    }

    /// Current joint state stamped `stamp_ns`.
    pub fn joint_state(&self, robot_id: &str, stamp_ns: u64) -> JointState {
        let mut header = Header::new(robot_id, "mock-robot", "");
        header.stamp_ns = stamp_ns;
        JointState {
            header,
            name: self.names.clone(),
            position: self.q.clone(),
            velocity: self.v.clone(),
            base: Some(self.base),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use echo_msgs::TrajectoryPoint;

    fn cmd(joint: &str, target: f64, t: f64) -> RobotCommand {
        RobotCommand {
            header: Header::new("r", "s", ""),
            trajectories: vec![ControllerTrajectory {
                controller: "head_controller".into(),
                joint_names: vec![joint.into()],
                points: vec![TrajectoryPoint {
                    time_from_start: t,
                    positions: vec![target],
                    velocities: vec![0.0],
                    accelerations: vec![0.0],
                }],
            }],
            base_twist: None,
        }
    }

    #[test]
    fn follows_commands_within_velocity_limits() {
        let mut r = SimRobot::new(SimRobotConfig::default(), RobotModel::tiago_dual());
        assert!(r.command(&cmd("head_1_joint", 1.0, 0.5)).is_empty());
        let mut last = 0.0;
        for _ in 0..200 {
            r.step(0.01);
            let q = r.position("head_1_joint").unwrap();
            assert!((q - last).abs() <= 3.0 * 0.01 + 1e-12, "velocity limit");
            last = q;
        }
        assert!((last - 1.0).abs() < 1e-3);
    }

    #[test]
    fn never_leaves_hard_limits_and_ignores_unknown_joints() {
        let mut r = SimRobot::new(SimRobotConfig::default(), RobotModel::tiago_dual());
        r.command(&cmd("head_1_joint", 5.0, 0.1));
        for _ in 0..300 {
            r.step(0.01);
        }
        let lim = r.model().limits("head_1_joint").unwrap();
        assert!((r.position("head_1_joint").unwrap() - lim.upper).abs() < 1e-12);
        assert_eq!(r.command(&cmd("elbow", 1.0, 0.1)).len(), 1);
    }
}
