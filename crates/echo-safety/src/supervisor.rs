//! The safety supervisor: inputs in, one command and one status per control cycle out.
//!
//! Stop reasons (any one brakes every group to rest, then holds): latched e-stop; no joint
//! state for `state_deadline_ms`; a sensor fault (a measured sample out of the hard limits,
//! non-finite, or jumping faster than the joint can move: [`crate::measured`]) within the last
//! `fault_clear_ms`; a required service's liveliness lost; no valid plan for `plan_deadline_ms`
//! (receiver's monotonic clock); commanded and measured positions apart by more than
//! `tracking_tolerance`; hold mode. Recovery: as soon as the reasons clear, tracking resumes
//! from the filter's current state — never from a jump. The measured state never moves the
//! command: the command starts at the first plausible measured state (clamped into the hard
//! limits) and is continuous from then on; the one exception is an operator's e-stop reset at
//! rest, which re-anchors the command at a plausible measured state (`resync`).

use std::collections::{BTreeMap, HashSet};
use std::time::Instant;

use echo_msgs::{
    BaseTwist, ControlMode, ControllerTrajectory, EStop, EStopAction, Forecast, Header,
    HumanSkeletons, Interaction, InteractionIntent, JointState, RobotCommand, RobotPlan,
    SafetyState, TrajectoryPoint,
};
use echo_robot::collision::{min_self_distance, Part, RobotBody};
use echo_robot::groups::motion_groups;
use echo_robot::limits::kinematic_limits;
use echo_robot::{JointValues, RobotModel};

use crate::config::SafetyConfig;
use crate::filter::{Filter, Group, GroupStep, Reference};
use crate::joint::JointState1;
use crate::measured::{CheckedJoint, MonitorParams, StateFault, StateMonitor};
use crate::plan::{accept, ActivePlan, PlanError};
use crate::separation::{assess, human_capsules, Assessment, Person};

/// The outcome of one control cycle.
#[derive(Debug, Clone)]
pub struct Tick {
    /// The command to send (None until the robot's state is known).
    pub command: Option<RobotCommand>,
    /// Filter state.
    pub state: SafetyState,
    /// Why (empty when following freely).
    pub reasons: Vec<String>,
    /// Speed scale applied.
    pub speed_scale: f64,
    /// Smallest robot–human distance, m.
    pub min_separation_m: Option<f64>,
}

/// The supervisor.
pub struct Supervisor {
    cfg: SafetyConfig,
    model: RobotModel,
    body: RobotBody,
    filter: Filter,
    initialized: bool,
    plan: Option<ActivePlan>,
    plan_stamp: Option<u64>,
    plan_received: Option<Instant>,
    mode: ControlMode,
    interaction: Option<Interaction>,
    estop: Option<String>,
    state_at: Option<Instant>,
    measured: Vec<Option<f64>>,
    base_yaw: f64,
    /// Current skeletons.
    humans: Option<(Instant, Vec<Skeleton>)>,
    forecast: Option<(Instant, Vec<Vec<[f64; 3]>>)>,
    lost: HashSet<String>,
    monitor: StateMonitor,
    /// The latest sensor fault and when it was seen.
    sensor_fault: Option<(String, Instant)>,
    twist: (f64, f64),
    counters: BTreeMap<String, u64>,
    q_full: JointValues,
    filter_to_model: Vec<usize>,
}

/// One tracked person's joints, and whether they are the interaction partner.
type Skeleton = (bool, Vec<[f64; 3]>);

impl Supervisor {
    /// A supervisor for `model` (arms, torso and head are filtered).
    pub fn new(cfg: SafetyConfig, model: RobotModel) -> Result<Supervisor, String> {
        cfg.check()?;
        let groups_spec = motion_groups();
        let joints: Vec<String> = groups_spec.iter().flat_map(|g| g.joints.clone()).collect();
        let limits = kinematic_limits(&model, &joints, cfg.soft_limits, &cfg.limits)
            .map_err(|e| e.to_string())?;
        let mut groups = vec![];
        let mut k = 0;
        for g in &groups_spec {
            groups.push(Group {
                name: g.name.to_string(),
                controller: g.controller.to_string(),
                joints: (k..k + g.joints.len()).collect(),
            });
            k += g.joints.len();
        }
        let filter_to_model = joints
            .iter()
            .map(|j| {
                model
                    .joint_index(j)
                    .ok_or_else(|| format!("model lacks joint {j}"))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let body = RobotBody::tiago(&model).map_err(|e| e.to_string())?;
        let n = joints.len();
        let hard: Vec<(f64, f64)> = joints
            .iter()
            .map(|j| {
                model
                    .limits(j)
                    .map(|l| (l.lower, l.upper))
                    .ok_or_else(|| format!("model lacks limits of {j}"))
            })
            .collect::<Result<_, _>>()?;
        let filter = Filter::new(
            joints,
            limits,
            groups,
            cfg.dt(),
            cfg.tracking_time_constant_s,
        )
        .with_hard_limits(hard, cfg.recovery_speed_scale);
        // Every actuated joint of the model is checked (grippers too: they shape the capsules).
        let checked = model
            .actuated_joints()
            .iter()
            .filter_map(|j| {
                model.limits(j).map(|l| CheckedJoint {
                    name: j.clone(),
                    lower: l.lower,
                    upper: l.upper,
                    velocity: l.velocity,
                })
            })
            .collect();
        let monitor = StateMonitor::new(
            checked,
            MonitorParams {
                tolerance: cfg.measured_tolerance,
                jitter_s: cfg.state_jitter_s,
                source_timeout_s: cfg.state_source_timeout_ms / 1e3,
            },
            cfg.state_source.clone(),
        );
        Ok(Supervisor {
            q_full: model.zero(),
            cfg,
            body,
            filter,
            initialized: false,
            plan: None,
            plan_stamp: None,
            plan_received: None,
            mode: ControlMode::Forecast,
            interaction: None,
            estop: None,
            state_at: None,
            measured: vec![None; n],
            base_yaw: 0.0,
            humans: None,
            forecast: None,
            lost: HashSet::new(),
            monitor,
            sensor_fault: None,
            twist: (0.0, 0.0),
            counters: BTreeMap::new(),
            filter_to_model,
            model,
        })
    }

    /// The filter (for inspection in tests and benchmarks).
    pub fn filter(&self) -> &Filter {
        &self.filter
    }

    /// Event and rejection counters.
    pub fn counters(&self) -> &BTreeMap<String, u64> {
        &self.counters
    }

    fn count(&mut self, key: &str) {
        *self.counters.entry(key.to_string()).or_default() += 1;
    }

    /// A measured joint state (any order, any subset) received at `now`. A sample from another
    /// source than the accepted one, or one that breaks a plausibility rule, is refused (counted
    /// as `state/<reason>`) and changes nothing but the fault latch: it never reaches the filter.
    pub fn on_joint_state(&mut self, js: &JointState, now: Instant) -> Result<(), StateFault> {
        match self.monitor.check(js, now) {
            Ok(switched) => {
                if switched {
                    self.count("state/source_changed");
                }
            }
            Err(e) => {
                self.count(&format!("state/{}", e.reason()));
                if e.is_sensor_fault() {
                    if self.sensor_fault.is_none() {
                        self.count("state/fault");
                    }
                    self.sensor_fault = Some((e.to_string(), now));
                }
                return Err(e);
            }
        }
        for (i, name) in self.filter.joints().to_vec().iter().enumerate() {
            if let Some(q) = js.position_of(name) {
                self.measured[i] = Some(q);
            }
        }
        if let Some(b) = js.base {
            self.base_yaw = b.yaw;
        }
        for (n, q) in js.name.iter().zip(&js.position) {
            if let Some(i) = self.model.joint_index(n) {
                self.q_full.0[i] = *q;
            }
        }
        self.state_at = Some(now);
        if !self.initialized
            && self.sensor_fault(now).is_none()
            && self.measured.iter().all(Option::is_some)
        {
            let q: Vec<f64> = self.measured.iter().map(|q| q.unwrap_or(0.0)).collect();
            self.filter.reset_to(&q);
            self.initialized = true;
        }
        Ok(())
    }

    /// The current sensor fault, if one was seen within `fault_clear_ms` of `now`.
    pub fn sensor_fault(&self, now: Instant) -> Option<&str> {
        self.sensor_fault.as_ref().and_then(|(why, at)| {
            (now.saturating_duration_since(*at).as_secs_f64() * 1e3 < self.cfg.fault_clear_ms)
                .then_some(why.as_str())
        })
    }

    /// A robot plan (from a forecast in forecast mode, from the retargeter in imitation mode).
    pub fn on_plan(&mut self, plan: &RobotPlan, now: Instant) -> Result<(), PlanError> {
        let r = self.check_plan(plan, now);
        match &r {
            Ok(active) => {
                self.plan = Some(active.clone());
                self.plan_stamp = Some(plan.header.stamp_ns);
                self.plan_received = Some(now);
                self.count("plan/accepted");
            }
            Err(e) => self.count(&format!("plan/{}", e.reason())),
        }
        r.map(|_| ())
    }

    fn check_plan(&self, plan: &RobotPlan, now: Instant) -> Result<ActivePlan, PlanError> {
        if plan.mode != self.mode {
            return Err(PlanError::WrongMode {
                got: plan.mode,
                active: self.mode,
            });
        }
        if let Some(last) = self.plan_stamp {
            if plan.header.stamp_ns <= last {
                return Err(PlanError::OutOfOrder {
                    stamp_ns: plan.header.stamp_ns,
                    last_ns: last,
                });
            }
        }
        if !self.initialized {
            return Err(PlanError::NoState);
        }
        // The plan must start near where the robot is commanded to be now.
        let current: Vec<Option<f64>> = self.filter.state().iter().map(|s| Some(s.q)).collect();
        accept(
            plan,
            self.filter.joints(),
            &current,
            self.cfg.start_tolerance,
            now,
        )
    }

    /// A forecast: the partner's future motion (for separation) and the robot's plan.
    pub fn on_forecast(&mut self, f: &Forecast, now: Instant) -> Result<(), PlanError> {
        let frames: Vec<Vec<[f64; 3]>> = f
            .human
            .iter()
            .take(self.cfg.separation.forecast_frames)
            .cloned()
            .collect();
        self.forecast = Some((now, frames));
        match &f.robot {
            Some(p) => self.on_plan(p, now),
            None => Ok(()),
        }
    }

    /// Current skeletons (every tracked person counts for separation; the partner may be
    /// touched in a contact interaction).
    pub fn on_humans(&mut self, s: &HumanSkeletons, now: Instant) {
        self.humans = Some((
            now,
            s.tracks
                .iter()
                .map(|t| (s.partner_id == Some(t.track_id), t.pose.joints.clone()))
                .collect(),
        ));
    }

    /// Interaction intent: sets the mode (a mode change drops the active plan) and whether
    /// the partner may be touched (contact mode).
    pub fn on_intent(&mut self, i: &InteractionIntent) {
        if i.mode != self.mode {
            self.plan = None;
            self.plan_stamp = None;
            self.count("mode_change");
        }
        self.mode = i.mode;
        self.interaction = Some(i.interaction);
    }

    /// E-stop engage (latched) or reset.
    pub fn on_estop(&mut self, e: &EStop) {
        match e.action {
            EStopAction::Engage => {
                self.estop = Some(e.reason.clone());
                self.count("estop/engaged");
            }
            EStopAction::Reset => {
                if self.estop.take().is_some() {
                    self.count("estop/reset");
                    // A reset never resumes an old plan.
                    self.plan = None;
                }
                self.resync_at_rest();
            }
        }
    }

    /// The operator's reset at rest re-anchors the command at the measured state when the two
    /// disagree beyond the tracking tolerance (the robot was moved, or stopped elsewhere): the
    /// only discontinuity of the command, and only from a plausible measured state (no sensor
    /// fault latched; [`Filter::reset_to`] clamps into the hard limits).
    fn resync_at_rest(&mut self) {
        if !self.initialized || !self.filter.all_rest() || self.sensor_fault.is_some() {
            return;
        }
        if !self.measured.iter().all(Option::is_some) {
            return;
        }
        let q: Vec<f64> = self.measured.iter().map(|q| q.unwrap_or(0.0)).collect();
        if q.iter()
            .zip(self.filter.state())
            .any(|(m, s)| (m - s.q).abs() > self.cfg.tracking_tolerance)
        {
            self.filter.reset_to(&q);
            self.count("resync");
        }
    }

    /// Liveliness of a required service changed.
    pub fn on_alive(&mut self, service: &str, alive: bool) {
        if alive {
            self.lost.remove(service);
        } else if self.cfg.required_alive.iter().any(|s| s == service) {
            self.lost.insert(service.to_string());
            self.count(&format!("liveliness_lost/{service}"));
        }
    }

    fn stop_reasons(&self, now: Instant) -> Vec<String> {
        let mut r = vec![];
        if let Some(why) = &self.estop {
            r.push(format!("e-stop: {why}"));
        }
        match self.state_at {
            None => r.push("no joint state yet".into()),
            Some(t) => {
                let age = now.saturating_duration_since(t).as_secs_f64() * 1e3;
                if age > self.cfg.state_deadline_ms {
                    r.push(format!(
                        "joint state {age:.0} ms old (limit {:.0} ms)",
                        self.cfg.state_deadline_ms
                    ));
                }
            }
        }
        if let Some(why) = self.sensor_fault(now) {
            r.push(format!("sensor fault: {why}"));
        }
        for s in &self.lost {
            r.push(format!("{s} liveliness lost"));
        }
        match self.mode {
            ControlMode::Hold => r.push("hold mode".into()),
            _ => match self.plan_received {
                None => r.push("no valid plan yet".into()),
                Some(t) => {
                    let age = now.saturating_duration_since(t).as_secs_f64() * 1e3;
                    if age > self.cfg.plan_deadline_ms {
                        r.push(format!(
                            "no valid plan for {age:.0} ms (deadline {:.0} ms)",
                            self.cfg.plan_deadline_ms
                        ));
                    }
                }
            },
        }
        for (i, s) in self.filter.state().iter().enumerate() {
            if let Some(m) = self.measured[i] {
                if (s.q - m).abs() > self.cfg.tracking_tolerance {
                    r.push(format!(
                        "{} is {:.3} from its command",
                        self.filter.joints()[i],
                        (s.q - m).abs()
                    ));
                    break;
                }
            }
        }
        r
    }

    fn robot_capsules(&self, q: &[f64]) -> Vec<(Part, echo_robot::collision::Capsule)> {
        let mut full = self.q_full.clone();
        for (i, &mi) in self.filter_to_model.iter().enumerate() {
            full.0[mi] = q[i];
        }
        self.body.at(&self.model, &full)
    }

    fn reference(&self, plan: &ActivePlan, t: f64) -> Reference {
        let mut r = Reference::hold(self.filter.joints().len());
        for (k, &i) in plan.index.iter().enumerate() {
            let (q, v) = plan.sample(k, t);
            r.q[i] = Some(q);
            r.v[i] = v;
        }
        r
    }

    fn people(&self, now: Instant) -> Vec<Person> {
        let timeout = self.cfg.separation.human_timeout_s;
        let fresh = |t: &Instant| now.saturating_duration_since(*t).as_secs_f64() <= timeout;
        let mut out = vec![];
        if let Some((t, people)) = &self.humans {
            if fresh(t) {
                out.extend(people.iter().map(|(partner, p)| Person {
                    partner: *partner,
                    capsules: human_capsules(p),
                }));
            }
        }
        if let Some((t, frames)) = &self.forecast {
            if fresh(t) {
                // A forecast is of the partner.
                out.extend(frames.iter().map(|p| Person {
                    partner: true,
                    capsules: human_capsules(p),
                }));
            }
        }
        out
    }

    /// One control cycle at `now`.
    pub fn tick(&mut self, now: Instant) -> Tick {
        if self.sensor_fault.is_some() && self.sensor_fault(now).is_none() {
            self.sensor_fault = None;
            self.count("state/fault_cleared");
        }
        if !self.initialized {
            let reasons = match self.sensor_fault(now) {
                Some(why) => vec![format!("sensor fault: {why}")],
                None => vec!["waiting for the robot's joint state".into()],
            };
            return Tick {
                command: None,
                state: SafetyState::Holding,
                reasons,
                speed_scale: 0.0,
                min_separation_m: None,
            };
        }
        let dt = self.filter.dt();
        let mut reasons = self.stop_reasons(now);
        let stopping = !reasons.is_empty();
        let n_groups = self.filter.groups().len();

        // Separation: robot now vs people now and forecast.
        let q_now: Vec<f64> = self.filter.state().iter().map(|s| s.q).collect();
        let q_next: Vec<f64> = self.filter.state().iter().map(|s| s.q + s.v * dt).collect();
        let caps_now = self.robot_capsules(&q_now);
        let caps_next = self.robot_capsules(&q_next);
        let mut vr: f64 = 0.0;
        for ((_, a), (_, b)) in caps_now.iter().zip(&caps_next) {
            vr = vr.max((b.a - a.a).norm().max((b.b - a.b).norm()) / dt);
        }
        let people = self.people(now);
        let ts = self.filter.stop_time();
        let sep: Assessment = assess(
            &self.cfg.separation,
            &caps_now,
            &caps_next,
            &people,
            self.interaction,
            vr,
            ts,
        );
        let scale = sep.scale;
        if scale < 1.0 && sep.min_distance.is_finite() {
            let pair = sep
                .closest
                .map(|(r, h)| format!(", robot {r:?} to person's {h:?}"))
                .unwrap_or_default();
            reasons.push(format!(
                "separation {:.2} m{pair} (protective {:.2} m): speed × {:.2}",
                sep.min_distance, sep.protective, scale
            ));
        }
        if let Some(c) = sep.clearance.filter(|c| c.violated()) {
            reasons.push(format!(
                "clearance {:.2} m, robot {:?} to partner's {:?} (required {:.2} m)",
                c.distance, c.robot, c.human, c.required
            ));
        }
        // At or inside the protective distance or a clearance: a protective stop (brake to
        // rest), not a crawl.
        let stopping = if sep.stop() {
            reasons.push(
                "protective stop: a person is within the protective separation distance".into(),
            );
            true
        } else {
            stopping
        };
        // The contact cap by feedback: every moving group slows by contact_speed / vr (its
        // scale becomes that fraction of its current speed relative to its limits).
        let mut scales: Vec<f64> = vec![scale; n_groups];
        if sep.contact_scale < 1.0 {
            let (state, limits) = (self.filter.state(), self.filter.limits());
            for (g, group) in self.filter.groups().iter().enumerate() {
                let ratio = group
                    .joints
                    .iter()
                    .map(|&i| state[i].v.abs() / limits[i].velocity.max(1e-9))
                    .fold(0.0, f64::max);
                scales[g] = scales[g].min(ratio * sep.contact_scale);
            }
        }
        let scale = scale.min(sep.contact_scale);
        if sep.contact_scale < 1.0 {
            reasons.push(format!(
                "contact mode: partner {:.2} m away, speed capped at {:.2} m/s",
                sep.partner_distance, self.cfg.separation.contact_speed_mps
            ));
        }

        // Self-collision: arms brake when they would come closer than the margin.
        let self_now = min_self_distance(&caps_now);
        let self_next = min_self_distance(&caps_next);
        let self_brake = self_next < self.cfg.self_collision_margin_m && self_next < self_now;
        if self_brake {
            reasons.push(format!(
                "self-collision distance {self_next:.3} m: arms braking"
            ));
            self.count("self_collision_brake");
        }
        let brake: Vec<bool> = self
            .filter
            .groups()
            .iter()
            .map(|g| stopping || (self_brake && g.name.starts_with("arm")))
            .collect();

        let plan_t = self.plan.as_ref().map(|p| p.age(now));
        let reference = match (&self.plan, plan_t) {
            (Some(p), Some(t)) if !stopping => self.reference(p, t + dt),
            _ => Reference::hold(self.filter.joints().len()),
        };
        let steps = self.filter.step(&reference, &scales, &brake);
        // The command: the rollout of the tracking horizon, then a stop to rest.
        let command = self.command(plan_t.map(|t| t + dt), stopping, &scales);
        self.step_twist(plan_t, stopping, scale);

        let state = if self.estop.is_some() {
            SafetyState::EStopped
        } else if stopping {
            if self.filter.all_rest() {
                SafetyState::Holding
            } else {
                SafetyState::Stopping
            }
        } else if steps.iter().any(|s| *s != GroupStep::Tracked) || scale < 1.0 {
            SafetyState::Limiting
        } else {
            SafetyState::Following
        };
        if steps.contains(&GroupStep::Braked) && !stopping && !self_brake {
            reasons.push("a group braked to keep a feasible stop inside its limits".into());
        }
        Tick {
            command: Some(command),
            state,
            reasons,
            speed_scale: if stopping { 0.0 } else { scale },
            min_separation_m: sep.min_distance.is_finite().then_some(sep.min_distance),
        }
    }

    fn command(&self, plan_t: Option<f64>, stopping: bool, scales: &[f64]) -> RobotCommand {
        let dt = self.filter.dt();
        let mut sim = self.filter.clone();
        let n_track = if stopping {
            0
        } else {
            (self.cfg.horizon_s / dt).round() as usize
        };
        let mut states: Vec<Vec<JointState1>> = vec![sim.state().to_vec()];
        let n_groups = sim.groups().len();
        for k in 0..n_track {
            let r = match (&self.plan, plan_t) {
                (Some(p), Some(t)) => self.reference(p, t + (k + 1) as f64 * dt),
                _ => Reference::hold(sim.joints().len()),
            };
            sim.step(&r, scales, &vec![false; n_groups]);
            states.push(sim.state().to_vec());
        }
        let mut guard = 0;
        while !sim.all_rest() && guard < 1000 {
            sim.brake_all();
            states.push(sim.state().to_vec());
            guard += 1;
        }
        // Points every `point_every` cycles, always including the first and the final rest.
        let every = self.cfg.point_every.max(1);
        let mut picks: Vec<usize> = (0..states.len()).step_by(every).collect();
        if picks.last() != Some(&(states.len() - 1)) {
            picks.push(states.len() - 1);
        }
        let trajectories = self
            .filter
            .groups()
            .iter()
            .map(|g| ControllerTrajectory {
                controller: g.controller.clone(),
                joint_names: g
                    .joints
                    .iter()
                    .map(|&j| self.filter.joints()[j].clone())
                    .collect(),
                points: picks
                    .iter()
                    .map(|&k| TrajectoryPoint {
                        time_from_start: (k + 1) as f64 * dt,
                        positions: g.joints.iter().map(|&j| states[k][j].q).collect(),
                        velocities: g.joints.iter().map(|&j| states[k][j].v).collect(),
                        accelerations: g.joints.iter().map(|&j| states[k][j].a).collect(),
                    })
                    .collect(),
            })
            .collect();
        RobotCommand {
            header: Header::new("", "safety", ""),
            trajectories,
            base_twist: Some(BaseTwist {
                linear_x: self.twist.0,
                angular_z: self.twist.1,
            }),
        }
    }

    /// Base twist: toward the plan's base motion within limits, scaled; to zero when stopping.
    fn step_twist(&mut self, plan_t: Option<f64>, stopping: bool, scale: f64) {
        let b = &self.cfg.base;
        let dt = self.filter.dt();
        let (mut vx, mut wz) = (0.0, 0.0);
        if b.enabled && !stopping {
            if let (Some(p), Some(t)) = (&self.plan, plan_t) {
                if let (Some(p0), Some(p1)) = (p.base(t), p.base(t + dt)) {
                    let (dx, dy) = (p1.x - p0.x, p1.y - p0.y);
                    let yaw = self.base_yaw;
                    vx = (dx * yaw.cos() + dy * yaw.sin()) / dt;
                    wz = wrap(p1.yaw - p0.yaw) / dt;
                }
            }
            vx = vx.clamp(-b.max_reverse_mps, b.max_linear_mps) * scale;
            wz = wz.clamp(-b.max_angular_rps, b.max_angular_rps) * scale;
        }
        let (cx, cz) = self.twist;
        self.twist = (
            cx + (vx - cx).clamp(-b.max_linear_acc * dt, b.max_linear_acc * dt),
            cz + (wz - cz).clamp(-b.max_angular_acc * dt, b.max_angular_acc * dt),
        );
    }
}

fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI
}
