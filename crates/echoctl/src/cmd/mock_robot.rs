//! `echoctl mock-robot`: the simulated TIAGo++ controllers on the bus.

use std::time::Duration;

use anyhow::Result;
use echo_bus::shutdown::Shutdown;
use echo_bus::{topics, Bus, BusArgs};
use echo_msgs::now_ns;
use echo_robot::RobotModel;
use echo_sim::robot::{SimRobot, SimRobotConfig};

/// Service name.
pub const SERVICE: &str = "mock-robot";

/// Simulated robot options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Network.
    #[command(flatten)]
    pub bus: BusArgs,
    /// Sweep the head pan by this amplitude (rad) while no head command is active.
    #[arg(long, default_value_t = 0.0)]
    pub head_sweep: f64,
    /// Head sweep period, s.
    #[arg(long, default_value_t = 6.0)]
    pub head_sweep_period: f64,
    /// Joint-state rate, Hz.
    #[arg(long, default_value_t = 100.0)]
    pub rate: f64,
}

/// Accept commands, integrate, publish joint states at the configured rate until `stop`.
pub async fn serve(args: Args, mut stop: Shutdown) -> Result<()> {
    let cfg = SimRobotConfig {
        head_sweep_rad: args.head_sweep,
        head_sweep_period_s: args.head_sweep_period,
        rate_hz: args.rate,
        ..Default::default()
    };
    let bus = Bus::open(&args.bus, SERVICE).await?;
    let robot_id = bus.robot().clone();
    let commands = bus.subscribe(&topics::command(&robot_id)).await?;
    let states = bus.publisher(&topics::robot_state(&robot_id)).await?;
    let _alive = bus.declare_alive().await?;
    let reporter = bus.spawn_status_reporter(Duration::from_secs(1), stop.clone());
    let stats = bus.stats();
    let mut sim = SimRobot::new(cfg.clone(), RobotModel::tiago_dual());
    let dt = 1.0 / cfg.rate_hz.max(1.0);
    let mut tick = tokio::time::interval(Duration::from_secs_f64(dt));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    tracing::info!(robot = %robot_id, rate_hz = cfg.rate_hz, "simulated robot running");
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            _ = stop.wait() => break,
        }
        for c in commands.drain() {
            for problem in sim.command(&c.msg) {
                stats.rejected("command", "unknown_joint", &problem);
            }
        }
        sim.step(dt);
        states
            .put(sim.joint_state(robot_id.as_str(), now_ns()))
            .await?;
    }
    let _ = tokio::time::timeout(Duration::from_secs(2), reporter).await;
    bus.close().await
}
