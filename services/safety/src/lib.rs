//! The safety service: wiring and lifecycle around [`echo_safety::Supervisor`].
//!
//! Inputs: `forecast` (robot plan + partner forecast), `retarget` (plans in imitation mode),
//! `robot/state`, `humans`, `prompt` (mode and interaction), `estop`, liveliness of the services
//! in `required_alive`. Outputs every control cycle: `command`; at 10 Hz and on every state
//! change: `safety/status`. With `--ros2-namespace`, the command also goes out as CDR
//! JointTrajectory per controller and a Twist, and joint states are read from `/joint_states`,
//! following zenoh-bridge-ros2dds conventions.

use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use echo_bus::shutdown::Shutdown;
use echo_bus::{keys, topics, Bus, BusArgs, Received, Stats};
use echo_msgs::{
    now_ns, EStop, Forecast, Header, HumanSkeletons, InteractionIntent, JointState, RobotCommand,
    RobotPlan, SafetyState, SafetyStatus,
};
use echo_robot::RobotModel;
use echo_safety::{SafetyConfig, Supervisor};
use futures::{Stream, StreamExt};

/// Service name.
pub const SERVICE: &str = "safety";

/// Command-line / environment configuration.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Network.
    #[command(flatten)]
    pub bus: BusArgs,
    /// Safety configuration (JSON); defaults when absent.
    #[arg(long, env = "ECHO_SAFETY_CONFIG")]
    pub config: Option<std::path::PathBuf>,
    /// Robot description (URDF); the embedded TIAGo++ when absent.
    #[arg(long, env = "ECHO_URDF")]
    pub urdf: Option<std::path::PathBuf>,
    /// Services whose liveliness is required (lost → stop), comma-separated; adds to the config.
    #[arg(long, value_delimiter = ',')]
    pub require: Vec<String>,
    /// Also speak ROS 2 through zenoh-bridge-ros2dds under this namespace ("/" for none).
    #[arg(long)]
    pub ros2_namespace: Option<String>,
}

struct Ros2 {
    trajectories: Vec<(String, zenoh::pubsub::Publisher<'static>)>,
    twist: zenoh::pubsub::Publisher<'static>,
}

type Ros2States =
    zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>;

async fn ros2(bus: &Bus, ns: &str) -> Result<(Ros2, Ros2States)> {
    let s = bus.session();
    let mut trajectories = vec![];
    for g in echo_robot::groups::motion_groups() {
        let key = echo_ros2::ros_key(ns, &echo_ros2::trajectory_topic(g.controller));
        let p = s
            .declare_publisher(key.clone())
            .congestion_control(zenoh::qos::CongestionControl::Block)
            .priority(zenoh::qos::Priority::RealTime)
            .express(true)
            .await
            .map_err(|e| anyhow!("ROS 2 publisher {key}: {e}"))?;
        trajectories.push((g.controller.to_string(), p));
    }
    let tk = echo_ros2::ros_key(ns, echo_ros2::BASE_TWIST_TOPIC);
    let twist = s
        .declare_publisher(tk.clone())
        .await
        .map_err(|e| anyhow!("ROS 2 publisher {tk}: {e}"))?;
    let sk = echo_ros2::ros_key(ns, echo_ros2::JOINT_STATES_TOPIC);
    let states = s
        .declare_subscriber(sk.clone())
        .with(zenoh::handlers::FifoChannel::new(256))
        .await
        .map_err(|e| anyhow!("ROS 2 subscriber {sk}: {e}"))?;
    Ok((
        Ros2 {
            trajectories,
            twist,
        },
        states,
    ))
}

/// One input event of the control loop, in the order the loop sees them.
#[derive(Debug)]
pub enum Input {
    /// An e-stop engage or reset.
    EStop(Received<EStop>),
    /// Mode and interaction.
    Prompt(Received<InteractionIntent>),
    /// A measured joint state (JSON `robot/state`).
    State(Received<JointState>),
    /// A ROS 2 `sensor_msgs/JointState` in CDR, received at the instant given.
    Ros2State(Vec<u8>, Instant),
    /// Tracked people.
    Humans(Received<HumanSkeletons>),
    /// A forecast (with the robot's plan in forecast mode).
    Forecast(Received<Forecast>),
    /// A retargeter plan (imitation mode).
    Retarget(Received<RobotPlan>),
    /// A required service's liveliness changed.
    Alive(String, bool),
    /// One control cycle at this instant: a command and, every 5th cycle or on a state change,
    /// a status.
    Tick(Instant),
}

/// Where the loop's outputs go.
pub trait Output {
    /// The command of one cycle (the only path to the robot).
    fn command(
        &mut self,
        cmd: RobotCommand,
    ) -> impl std::future::Future<Output = Result<()>> + Send;
    /// The safety status.
    fn status(&mut self, st: SafetyStatus) -> impl std::future::Future<Output = Result<()>> + Send;
}

/// The control loop's state between events.
pub struct Loop {
    sup: Supervisor,
    robot: String,
    cycle: u64,
    last_state: Option<SafetyState>,
}

impl Loop {
    /// A loop around `sup` for robot `robot`.
    pub fn new(sup: Supervisor, robot: &str) -> Loop {
        Loop {
            sup,
            robot: robot.to_string(),
            cycle: 0,
            last_state: None,
        }
    }

    /// The state reported last.
    pub fn state(&self) -> Option<SafetyState> {
        self.last_state
    }

    /// Take one input; a tick produces the cycle's outputs. Rejections are counted in `stats`
    /// under `<edge>/<reason>`.
    pub async fn on<O: Output>(
        &mut self,
        input: Input,
        output: &mut O,
        stats: &Stats,
    ) -> Result<()> {
        match input {
            Input::EStop(e) => self.sup.on_estop(&e.msg),
            Input::Prompt(p) => self.sup.on_intent(&p.msg),
            Input::State(s) => {
                if let Err(e) = self.sup.on_joint_state(&s.msg, s.at) {
                    stats.rejected("robot_state", e.reason(), &e.to_string());
                }
            }
            Input::Ros2State(bytes, at) => {
                match echo_ros2::decode::<echo_ros2::RosJointState>(&bytes)
                    .map_err(|e| e.to_string())
                    .and_then(|js| {
                        echo_ros2::joint_state(&js, &self.robot, "ros2").map_err(|e| e.to_string())
                    }) {
                    Ok(js) => {
                        if let Err(e) = self.sup.on_joint_state(&js, at) {
                            stats.rejected("ros2_joint_states", e.reason(), &e.to_string());
                        }
                    }
                    Err(e) => stats.rejected("ros2_joint_states", "invalid", &e),
                }
            }
            Input::Humans(h) => self.sup.on_humans(&h.msg, h.at),
            Input::Forecast(f) => {
                if let Err(e) = self.sup.on_forecast(&f.msg, f.at) {
                    stats.rejected("forecast", e.reason(), &e.to_string());
                }
            }
            Input::Retarget(p) => {
                if let Err(e) = self.sup.on_plan(&p.msg, p.at) {
                    stats.rejected("retarget", e.reason(), &e.to_string());
                }
            }
            Input::Alive(service, up) => self.sup.on_alive(&service, up),
            Input::Tick(now) => self.tick(now, output, stats).await?,
        }
        Ok(())
    }

    async fn tick<O: Output>(&mut self, now: Instant, output: &mut O, stats: &Stats) -> Result<()> {
        let started = Instant::now();
        let t = self.sup.tick(now);
        stats.latency_ms(started.elapsed().as_secs_f64() * 1e3);
        if let Some(cmd) = t.command {
            output.command(cmd).await?;
        }
        let changed = self.last_state != Some(t.state);
        if changed || self.cycle.is_multiple_of(5) {
            if changed {
                tracing::info!(state = ?t.state, reasons = ?t.reasons, "safety state");
            }
            self.last_state = Some(t.state);
            let mut header = Header::new(&self.robot, "", "");
            header.stamp_ns = now_ns();
            output
                .status(SafetyStatus {
                    header,
                    state: t.state,
                    reasons: t.reasons,
                    speed_scale: t.speed_scale.clamp(0.0, 1.0),
                    min_separation_m: t.min_separation_m,
                    counters: self.sup.counters().clone(),
                })
                .await?;
        }
        self.cycle += 1;
        Ok(())
    }
}

/// Run the control loop over `inputs` until they end (the service feeds it from the bus, tests
/// from a script).
pub async fn run<S, O>(mut inputs: S, output: &mut O, lp: &mut Loop, stats: &Stats) -> Result<()>
where
    S: Stream<Item = Input> + Unpin,
    O: Output,
{
    while let Some(input) = inputs.next().await {
        lp.on(input, output, stats).await?;
    }
    Ok(())
}

/// The bus (and ROS 2) as the loop's output.
struct BusOutput {
    bus: Bus,
    commands: echo_bus::Publisher<RobotCommand>,
    status: echo_bus::Publisher<SafetyStatus>,
    ros: Option<Ros2>,
}

impl Output for BusOutput {
    async fn command(&mut self, mut cmd: RobotCommand) -> Result<()> {
        cmd.header = self.bus.header("");
        if let Some(r) = &self.ros {
            for (controller, traj) in echo_ros2::trajectories(&cmd) {
                if let Some((_, p)) = r.trajectories.iter().find(|(c, _)| *c == controller) {
                    let bytes = echo_ros2::encode(&traj)?;
                    p.put(bytes)
                        .await
                        .map_err(|e| anyhow!("ROS 2 trajectory: {e}"))?;
                }
            }
            let bytes = echo_ros2::encode(&echo_ros2::twist(&cmd))?;
            r.twist
                .put(bytes)
                .await
                .map_err(|e| anyhow!("ROS 2 twist: {e}"))?;
        }
        self.commands.put(cmd).await
    }

    async fn status(&mut self, mut st: SafetyStatus) -> Result<()> {
        let stamp = st.header.stamp_ns;
        st.header = self.bus.header("");
        st.header.stamp_ns = stamp;
        self.status.put(st).await
    }
}

/// Open the bus and run the control loop until `stop`: every cycle, the inputs that arrived
/// (e-stop, prompt, joint states, ROS 2 joint states, people, forecasts, plans, liveliness
/// changes, in that order), then a tick.
pub async fn serve(args: Args, mut stop: Shutdown) -> Result<()> {
    let mut cfg = match &args.config {
        Some(p) => SafetyConfig::from_file(p).map_err(anyhow::Error::msg)?,
        None => SafetyConfig::default(),
    };
    cfg.required_alive.extend(args.require.iter().cloned());
    let model = match &args.urdf {
        Some(p) => {
            RobotModel::from_urdf_file(p).with_context(|| format!("loading {}", p.display()))?
        }
        None => RobotModel::tiago_dual(),
    };
    let sup = Supervisor::new(cfg.clone(), model).map_err(anyhow::Error::msg)?;
    let bus = Bus::open(&args.bus, SERVICE).await?;
    let robot = bus.robot().clone();
    let forecasts = bus.subscribe(&topics::forecast(&robot)).await?;
    let retargets = bus.subscribe(&topics::retarget(&robot)).await?;
    let states = bus.subscribe(&topics::robot_state(&robot)).await?;
    let humans = bus.subscribe(&topics::humans(&robot)).await?;
    let prompts = bus.subscribe(&topics::prompt(&robot)).await?;
    let estops = bus.subscribe(&topics::estop(&robot)).await?;
    let alive = bus.watch_alive(&keys::alive_all(&robot)).await?;
    let (ros, ros_states) = match &args.ros2_namespace {
        Some(ns) => {
            let (out, states) = ros2(&bus, ns).await?;
            (Some(out), Some(states))
        }
        None => (None, None),
    };
    let mut out = BusOutput {
        commands: bus.publisher(&topics::command(&robot)).await?,
        status: bus.publisher(&topics::safety_status(&robot)).await?,
        bus: bus.clone(),
        ros,
    };
    let _token = bus.declare_alive().await?;
    let reporter = bus.spawn_status_reporter(Duration::from_secs(1), stop.clone());
    let stats = bus.stats();
    let mut lp = Loop::new(sup, robot.as_str());
    let mut was_alive: Vec<bool> = cfg.required_alive.iter().map(|_| false).collect();
    let mut tick = tokio::time::interval(Duration::from_secs_f64(cfg.dt()));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut cycle: u64 = 0;
    tracing::info!(robot = %robot, rate_hz = cfg.rate_hz, required = ?cfg.required_alive, "safety running");
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            _ = stop.wait() => break,
        }
        let now = Instant::now();
        let mut inputs: Vec<Input> = vec![];
        inputs.extend(estops.drain().into_iter().map(Input::EStop));
        inputs.extend(prompts.drain().into_iter().map(Input::Prompt));
        inputs.extend(states.drain().into_iter().map(Input::State));
        if let Some(rs) = &ros_states {
            while let Ok(Some(sample)) = rs.try_recv() {
                inputs.push(Input::Ros2State(sample.payload().to_bytes().to_vec(), now));
            }
        }
        inputs.extend(humans.drain().into_iter().map(Input::Humans));
        inputs.extend(forecasts.drain().into_iter().map(Input::Forecast));
        inputs.extend(retargets.drain().into_iter().map(Input::Retarget));
        for (i, svc) in cfg.required_alive.iter().enumerate() {
            let up = alive.is_alive(robot.as_str(), svc);
            // A service that was never seen counts as lost too: no robot motion without it.
            if up != was_alive[i] || (!up && cycle == 0) {
                inputs.push(Input::Alive(svc.clone(), up));
                was_alive[i] = up;
            }
        }
        inputs.push(Input::Tick(now));
        for input in inputs {
            lp.on(input, &mut out, &stats).await?;
        }
        stats.set_notes(vec![format!(
            "state {:?}",
            lp.state().unwrap_or(SafetyState::Holding)
        )]);
        cycle += 1;
    }
    let _ = tokio::time::timeout(Duration::from_secs(2), reporter).await;
    bus.close().await
}
