//! `echoctl`: Echo's command-line tool.
//!
//! Lifecycle: `demo`, `up`. Monitoring: `monitor`, `list`, `record`, `replay`, `scene`, `view`. Stand-ins: `mock-perception`, `mock-robot`.
//! Models and data: `data`, `train`, `eval`, `export`. Measurement: `bench`. Network: `router`.

use anyhow::Result;
use clap::{Parser, Subcommand};
use echo_bus::{shutdown, telemetry};

mod cmd;

/// Echo: social behaviour for TIAGo++ over a Zenoh pipeline.
#[derive(Debug, Parser)]
#[command(name = "echoctl", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the whole pipeline on loopback with the mock perception and the simulated robot.
    #[command(display_order = 1)]
    Demo(cmd::demo::Args),
    /// Start and supervise what runs on this host (a profile from deploy/profiles/).
    #[command(display_order = 2)]
    Up(cmd::up::Args),
    /// Print live messages on a key expression (like `ros2 topic echo`).
    #[command(display_order = 10)]
    Monitor(cmd::monitor::Args),
    /// List the services that are alive (from liveliness tokens).
    #[command(display_order = 11)]
    List(cmd::list::Args),
    /// Generate, describe and export interaction datasets.
    #[command(display_order = 40, subcommand)]
    Data(cmd::data::Verb),
    /// Score predictors on a dataset split (paper-style table).
    #[command(display_order = 41)]
    Eval(cmd::eval::Args),
    /// Train a model on generated interactions (forecaster).
    #[command(display_order = 42)]
    Train(cmd::train::Args),
    /// Export a checkpoint for another runtime (onnx).
    #[command(display_order = 43)]
    Export(cmd::export::Args),
    /// Record bus traffic to an MCAP file (receive times kept).
    #[command(display_order = 12)]
    Record(cmd::record::RecordArgs),
    /// Play an MCAP recording back onto the bus at its original rate (or faster).
    #[command(display_order = 13)]
    Replay(cmd::record::ReplayArgs),
    /// Echo in 3D: a recording as a Foxglove MCAP (`mcap`) or a GIF (`gif`), the live bus for
    /// Foxglove (`live`).
    #[command(display_order = 14, subcommand)]
    Scene(cmd::scene::Verb),
    /// Watch the robot live in a browser: serves a three.js page that follows the bus
    /// (http://localhost:8080).
    #[command(display_order = 15)]
    View(cmd::scene::ViewArgs),
    /// Run a Zenoh router (the same engine as zenohd, from this binary).
    #[command(display_order = 50)]
    Router(cmd::router::Args),
    /// Measure latency percentiles: `bridge`, `safety`, `forecaster`, `bus`, `e2e` (perception → command).
    #[command(display_order = 30)]
    Bench(cmd::bench::Args),
    /// Several robots through the whole pipeline for minutes: memory, deadlines, latency.
    #[command(display_order = 31)]
    Soak(cmd::soak::Args),
    /// Publish a scripted person as pose-estimator keypoints at 15 Hz.
    #[command(display_order = 20)]
    MockPerception(cmd::mock_perception::Args),
    /// Announce the interaction (text, type, control mode) to a robot.
    #[command(display_order = 22)]
    Prompt(cmd::prompt::Args),
    /// Simulate the TIAGo++ controllers: follow commands, publish joint states at 100 Hz.
    #[command(display_order = 21)]
    MockRobot(cmd::mock_robot::Args),
}

fn main() -> Result<()> {
    // Before the runtime's threads start: candle's thread count, read once.
    echo_models::threads::fix_candle_thread_count();
    tokio::runtime::Runtime::new()?.block_on(run())
}

async fn run() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Demo(a) => {
            // The demo prints its own status line; keep its log quiet unless asked.
            if std::env::var_os("RUST_LOG").is_none() {
                std::env::set_var("RUST_LOG", "warn");
            }
            telemetry::init();
            cmd::demo::run(a).await
        }
        Command::Up(a) => {
            telemetry::init();
            cmd::up::run(a).await
        }
        Command::Monitor(a) => {
            telemetry::init();
            cmd::monitor::run(a).await
        }
        Command::List(a) => {
            telemetry::init();
            cmd::list::run(a).await
        }
        Command::Data(v) => cmd::data::run(v),
        Command::Eval(a) => cmd::eval::run(a),
        Command::Train(a) => cmd::train::run(a),
        Command::Export(a) => cmd::export::run(a),
        Command::Record(a) => {
            telemetry::init();
            cmd::record::record(a).await
        }
        Command::Replay(a) => {
            telemetry::init();
            cmd::record::replay(a).await
        }
        Command::Scene(v) => {
            telemetry::init();
            cmd::scene::run(v).await
        }
        Command::View(a) => {
            telemetry::init();
            cmd::scene::view(a).await
        }
        Command::Router(a) => {
            let _denied = cmd::router::init_logging();
            cmd::router::run(a).await
        }
        Command::Bench(a) => {
            telemetry::init();
            cmd::bench::run(a).await
        }
        Command::Soak(a) => {
            if std::env::var_os("RUST_LOG").is_none() {
                std::env::set_var("RUST_LOG", "warn");
            }
            telemetry::init();
            cmd::soak::run_soak(a).await
        }
        Command::MockPerception(a) => {
            telemetry::init();
            cmd::mock_perception::serve(a, shutdown::on_signals()).await
        }
        Command::Prompt(a) => {
            telemetry::init();
            cmd::prompt::serve(a, shutdown::on_signals()).await
        }
        Command::MockRobot(a) => {
            telemetry::init();
            cmd::mock_robot::serve(a, shutdown::on_signals()).await
        }
    }
}
