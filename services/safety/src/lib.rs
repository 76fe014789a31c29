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
use echo_bus::{keys, topics, Bus, BusArgs};
use echo_msgs::{now_ns, SafetyState, SafetyStatus};
use echo_robot::RobotModel;
use echo_safety::{SafetyConfig, Supervisor};

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
    states: zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
}

async fn ros2(bus: &Bus, ns: &str) -> Result<Ros2> {
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
    Ok(Ros2 {
        trajectories,
        twist,
        states,
    })
}

/// Open the bus and run the control loop until `stop`.
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
    let mut sup = Supervisor::new(cfg.clone(), model).map_err(anyhow::Error::msg)?;
    let bus = Bus::open(&args.bus, SERVICE).await?;
    let robot = bus.robot().clone();
    let forecasts = bus.subscribe(&topics::forecast(&robot)).await?;
    let retargets = bus.subscribe(&topics::retarget(&robot)).await?;
    let states = bus.subscribe(&topics::robot_state(&robot)).await?;
    let humans = bus.subscribe(&topics::humans(&robot)).await?;
    let prompts = bus.subscribe(&topics::prompt(&robot)).await?;
    let estops = bus.subscribe(&topics::estop(&robot)).await?;
    let commands = bus.publisher(&topics::command(&robot)).await?;
    let status_pub = bus.publisher(&topics::safety_status(&robot)).await?;
    let alive = bus.watch_alive(&keys::alive_all(&robot)).await?;
    let ros = match &args.ros2_namespace {
        Some(ns) => Some(ros2(&bus, ns).await?),
        None => None,
    };
    let _token = bus.declare_alive().await?;
    let reporter = bus.spawn_status_reporter(Duration::from_secs(1), stop.clone());
    let stats = bus.stats();
    let mut was_alive: Vec<bool> = cfg.required_alive.iter().map(|_| false).collect();
    let mut tick = tokio::time::interval(Duration::from_secs_f64(cfg.dt()));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut last_state = None;
    let mut cycle: u64 = 0;
    tracing::info!(robot = %robot, rate_hz = cfg.rate_hz, required = ?cfg.required_alive, "safety running");
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            _ = stop.wait() => break,
        }
        let now = Instant::now();
        for e in estops.drain() {
            sup.on_estop(&e.msg);
        }
        for p in prompts.drain() {
            sup.on_intent(&p.msg);
        }
        for s in states.drain() {
            if let Err(e) = sup.on_joint_state(&s.msg, s.at) {
                stats.rejected("robot_state", e.reason(), &e.to_string());
            }
        }
        if let Some(r) = &ros {
            while let Ok(Some(sample)) = r.states.try_recv() {
                let bytes = sample.payload().to_bytes();
                match echo_ros2::decode::<echo_ros2::RosJointState>(&bytes)
                    .map_err(|e| e.to_string())
                    .and_then(|js| {
                        echo_ros2::joint_state(&js, robot.as_str(), "ros2")
                            .map_err(|e| e.to_string())
                    }) {
                    Ok(js) => {
                        if let Err(e) = sup.on_joint_state(&js, now) {
                            stats.rejected("ros2_joint_states", e.reason(), &e.to_string());
                        }
                    }
                    Err(e) => stats.rejected("ros2_joint_states", "invalid", &e),
                }
            }
        }
        for h in humans.drain() {
            sup.on_humans(&h.msg, h.at);
        }
        for f in forecasts.drain() {
            if let Err(e) = sup.on_forecast(&f.msg, f.at) {
                stats.rejected("forecast", e.reason(), &e.to_string());
            }
        }
        for p in retargets.drain() {
            if let Err(e) = sup.on_plan(&p.msg, p.at) {
                stats.rejected("retarget", e.reason(), &e.to_string());
            }
        }
        for (i, svc) in cfg.required_alive.iter().enumerate() {
            let up = alive.is_alive(robot.as_str(), svc);
            // A service that was never seen counts as lost too: no robot motion without it.
            if up != was_alive[i] || (!up && cycle == 0) {
                sup.on_alive(svc, up);
                was_alive[i] = up;
            }
        }
        let started = Instant::now();
        let t = sup.tick(now);
        stats.latency_ms(started.elapsed().as_secs_f64() * 1e3);
        if let Some(mut cmd) = t.command {
            cmd.header = bus.header("");
            if let Some(r) = &ros {
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
            commands.put(cmd).await?;
        }
        let changed = last_state != Some(t.state);
        if changed || cycle.is_multiple_of(5) {
            if changed {
                tracing::info!(state = ?t.state, reasons = ?t.reasons, "safety state");
            }
            last_state = Some(t.state);
            let mut header = bus.header("");
            header.stamp_ns = now_ns();
            status_pub
                .put(SafetyStatus {
                    header,
                    state: t.state,
                    reasons: t.reasons,
                    speed_scale: t.speed_scale.clamp(0.0, 1.0),
                    min_separation_m: t.min_separation_m,
                    counters: sup.counters().clone(),
                })
                .await?;
        }
        stats.set_notes(vec![format!(
            "state {:?}",
            last_state.unwrap_or(SafetyState::Holding)
        )]);
        cycle += 1;
    }
    let _ = tokio::time::timeout(Duration::from_secs(2), reporter).await;
    bus.close().await
}
