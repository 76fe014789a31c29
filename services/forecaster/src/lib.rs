//! The forecaster service: wiring and lifecycle around [`echo_forecast::ForecastServer`].
//!
//! Inputs, per served robot: `humans` (HumanSkeletons), `robot/state` (JointState), `prompt`
//! (InteractionIntent). Output: `forecast` (Forecast) per robot; `status/forecaster`.
//! Robots whose frames arrive within `--batch-window-ms` of each other share one forward pass.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use echo_bus::keys::{self, RobotId};
use echo_bus::shutdown::Shutdown;
use echo_bus::{topics, Bus, BusArgs, Received, Stats};
use echo_forecast::failover;
use echo_forecast::server::Counters;
use echo_forecast::{ForecastServer, Push, ServerConfig};
use echo_models::{Backend, CandleBackend, Checkpoint, ZeroVelocityBackend};
use echo_msgs::{Forecast, HumanSkeletons, InteractionIntent, JointState};
use echo_robot::RobotModel;
use futures::{Stream, StreamExt};

/// Service name (liveliness token, status key, logs).
pub const SERVICE: &str = "forecaster";

/// Command-line / environment configuration of the service.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Network (its `--robot` is served, plus any in `--robots`).
    #[command(flatten)]
    pub bus: BusArgs,
    /// More robots to serve from this process (comma-separated ids).
    #[arg(long, env = "ECHO_FORECAST_ROBOTS", value_delimiter = ',')]
    pub robots: Vec<String>,
    /// Checkpoint stem (<stem>.safetensors + <stem>.json).
    #[arg(
        long,
        env = "ECHO_FORECASTER_MODEL",
        default_value = "models/forecaster"
    )]
    pub model: PathBuf,
    /// Inference backend: auto (ONNX Runtime when it is there and agrees with candle, else
    /// candle), candle, onnx (the checkpoint exported at start-up and run by ONNX Runtime), or
    /// zero-velocity (the baseline, no model).
    #[arg(long, env = "ECHO_FORECAST_BACKEND", value_enum, default_value_t = BackendKind::Auto)]
    pub backend: BackendKind,
    /// How long a robot's new frame waits for other robots' frames to share its batch, ms.
    #[arg(long, default_value_t = 3)]
    pub batch_window_ms: u64,
    /// Serving configuration (JSON); defaults when absent.
    #[arg(long, env = "ECHO_FORECAST_CONFIG")]
    pub config: Option<PathBuf>,
    /// Robot description (URDF) for the robot stand-in; the embedded TIAGo++ when absent.
    #[arg(long, env = "ECHO_URDF")]
    pub urdf: Option<PathBuf>,
    /// Failover rank: 0 = primary; a standby of rank n publishes for a robot only while no
    /// instance of lower rank is alive for it (see echo_forecast::failover).
    #[arg(long, env = "ECHO_FORECAST_RANK", default_value_t = 0)]
    pub rank: u32,
    /// Human–human models: publish the average of the forecasts of the scene, its mirror image
    /// and the scene with the people's roles exchanged (ServerConfig::symmetrize; how the
    /// shipped forecaster is measured on real captures). Also settable in --config.
    #[arg(long, env = "ECHO_FORECAST_SYMMETRIZE")]
    pub symmetrize: bool,
}

/// One input event, tagged with the robot it belongs to.
#[derive(Debug)]
pub enum Input {
    /// Skeletons of a robot's perception.
    Skeletons(String, Received<HumanSkeletons>),
    /// A robot's joint state.
    JointState(String, Received<JointState>),
    /// A robot's prompt.
    Prompt(String, Received<InteractionIntent>),
}

/// Where forecasts go.
pub trait Output {
    /// Publish `msg` for `robot`.
    fn forecast(
        &mut self,
        robot: &str,
        msg: Forecast,
    ) -> impl std::future::Future<Output = Result<()>> + Send;
}

/// Per robot: its forecast publisher and whether this instance is active for it.
struct BusOutput {
    robots: Vec<(String, echo_bus::Publisher<Forecast>, Arc<AtomicBool>)>,
    stats: Arc<Stats>,
}

impl Output for BusOutput {
    async fn forecast(&mut self, robot: &str, msg: Forecast) -> Result<()> {
        match self.robots.iter().find(|(r, _, _)| r == robot) {
            Some((_, p, active)) if active.load(Ordering::Relaxed) => p.put(msg).await,
            Some(_) => {
                // Hot standby: the forecast is computed but another instance publishes.
                self.stats.dropped(edges::STANDBY, 1);
                Ok(())
            }
            None => Ok(()),
        }
    }
}

/// Keep each robot's active flag and the plain `forecaster` token in line with the live ranks
/// (see [`echo_forecast::failover`]) until `stop`.
async fn follow_failover(
    bus: Arc<Bus>,
    watch: echo_bus::liveliness::AliveWatch,
    rank: u32,
    robots: Vec<(RobotId, Arc<AtomicBool>)>,
    mut seen_at_start: Vec<(String, String)>,
    mut stop: Shutdown,
) {
    let mut tokens: HashMap<String, zenoh::liveliness::LivelinessToken> = HashMap::new();
    loop {
        let changed = watch.changed();
        let mut alive = watch.snapshot();
        // The first decision also counts what the start-up query saw, in case the watch's
        // history has not arrived yet.
        alive.append(&mut seen_at_start);
        for (robot, active) in &robots {
            let ranks: Vec<u32> = alive
                .iter()
                .filter(|(r, _)| r == robot.as_str())
                .filter_map(|(_, s)| failover::parse_instance(SERVICE, s))
                .collect();
            let want = failover::is_active(rank, &ranks);
            if want == active.load(Ordering::Relaxed) {
                continue;
            }
            if want {
                match bus
                    .session()
                    .liveliness()
                    .declare_token(keys::alive(robot, SERVICE))
                    .await
                {
                    Ok(t) => {
                        tokens.insert(robot.to_string(), t);
                    }
                    Err(e) => tracing::warn!(%robot, "declaring the active token: {e}"),
                }
                tracing::warn!(%robot, rank, live_ranks = ?ranks, "active: serving forecasts");
            } else {
                tokens.remove(robot.as_str());
                tracing::warn!(%robot, rank, live_ranks = ?ranks, "standing by: a lower rank is alive");
            }
            active.store(want, Ordering::Relaxed);
        }
        tokio::select! {
            _ = changed => {}
            _ = stop.wait() => break,
        }
    }
}

/// The forecaster's inference backends.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BackendKind {
    /// The fastest backend that runs the same model: ONNX Runtime when its library loads and
    /// its outputs agree with candle's within `PARITY_TOLERANCE` on a probe batch at start-up,
    /// candle otherwise (the reason logged).
    Auto,
    /// The checkpoint run by candle.
    Candle,
    /// The checkpoint exported to ONNX at start-up and run by ONNX Runtime.
    Onnx,
    /// The zero-velocity baseline (no model).
    ZeroVelocity,
}

impl std::fmt::Display for BackendKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        use clap::ValueEnum;
        let v = self.to_possible_value().expect("no skipped variants");
        f.write_str(v.get_name())
    }
}

/// Load the backend named by `args` and the sentence encoder its model needs.
pub fn load_backend(
    args: &Args,
) -> Result<(Box<dyn Backend>, Option<echo_text::SentenceEncoder>, String)> {
    let dev = candle_core::Device::Cpu;
    let mut ck = Checkpoint::load(&args.model, &dev)
        .with_context(|| format!("loading the forecaster {}", args.model.display()))?;
    let text = ck.text.take();
    let name = args
        .model
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "forecaster".into());
    let backend: Box<dyn Backend> = match args.backend {
        BackendKind::Auto => {
            let cfg = ck.meta.model.clone();
            let mut candle = CandleBackend::new(ck, dev);
            match echo_onnx::OrtBackend::from_checkpoint(&args.model, cfg, 0).and_then(|mut ort| {
                echo_models::disagreement(&mut candle, &mut ort, 4).map(|d| (ort, d))
            }) {
                Ok((ort, d)) if d <= echo_models::PARITY_TOLERANCE => {
                    tracing::info!("serving with ONNX Runtime (agrees with candle within {d:.1e})");
                    Box::new(ort)
                }
                Ok((_, d)) => {
                    tracing::warn!(
                        "ONNX Runtime differs from candle by {d:.1e} (more than {:.0e}): serving with candle",
                        echo_models::PARITY_TOLERANCE
                    );
                    Box::new(candle)
                }
                Err(e) => {
                    tracing::info!("serving with candle (ONNX Runtime: {e:#})");
                    Box::new(candle)
                }
            }
        }
        BackendKind::Candle => Box::new(CandleBackend::new(ck, dev)),
        BackendKind::Onnx => Box::new(echo_onnx::OrtBackend::from_checkpoint(
            &args.model,
            ck.meta.model.clone(),
            0,
        )?),
        BackendKind::ZeroVelocity => Box::new(ZeroVelocityBackend::new(ck.meta.model.clone())),
    };
    Ok((backend, text, name))
}

/// An inbox as a stream of inputs tagged with the robot they belong to.
fn tagged<M: Send + 'static>(
    inbox: echo_bus::Inbox<M>,
    robot: String,
    wrap: fn(String, Received<M>) -> Input,
) -> futures::stream::BoxStream<'static, Input> {
    futures::stream::unfold(inbox, move |ib| {
        let robot = robot.clone();
        async move { ib.recv().await.map(|m| (wrap(robot, m), ib)) }
    })
    .boxed()
}

/// Open the bus, wire inputs and outputs, and run until `stop` triggers.
pub async fn serve(args: Args, stop: Shutdown) -> Result<()> {
    let mut cfg = match &args.config {
        Some(p) => serde_json::from_slice::<ServerConfig>(
            &std::fs::read(p).with_context(|| format!("reading {}", p.display()))?,
        )
        .with_context(|| format!("parsing {}", p.display()))?,
        None => ServerConfig::default(),
    };
    // The histories never refuse a stamp the bus was told to let through.
    cfg.max_future_ms = cfg.max_future_ms.max(args.bus.max_clock_skew_ms() as f64);
    cfg.symmetrize |= args.symmetrize;
    let robot_model = match &args.urdf {
        Some(p) => {
            RobotModel::from_urdf_file(p).with_context(|| format!("loading {}", p.display()))?
        }
        None => RobotModel::tiago_dual(),
    };
    let (backend, text, model_name) = load_backend(&args)?;
    let backend_name = backend.name();
    let server = ForecastServer::new(cfg, backend, text, &model_name, robot_model)?;

    let bus = Arc::new(Bus::open(&args.bus, SERVICE).await?);
    let mut robots: Vec<RobotId> = vec![bus.robot().clone()];
    for r in &args.robots {
        let id = RobotId::new(r).map_err(|e| anyhow::anyhow!("--robots: {e}"))?;
        if !robots.contains(&id) {
            robots.push(id);
        }
    }
    // Ranks are unique per robot: refuse to start on a taken one.
    let instance = failover::instance_name(SERVICE, args.rank);
    let watch = bus.watch_alive(&keys::alive_fleet()).await?;
    let mut seen = vec![];
    for r in &robots {
        let now = bus
            .alive_now(&keys::alive_all(r), Duration::from_millis(800))
            .await?;
        let taken = now.iter().any(|(_, s)| *s == instance);
        seen.extend(now);
        anyhow::ensure!(
            !taken,
            "robot {r} already has a forecaster of rank {} (use another --rank)",
            args.rank
        );
    }
    let mut streams = vec![];
    let mut outputs = vec![];
    let mut flags = vec![];
    let mut tokens = vec![];
    for r in &robots {
        let name = r.as_str().to_string();
        let sk = bus.subscribe(&topics::humans(r)).await?;
        let js = bus.subscribe(&topics::robot_state(r)).await?;
        let pr = bus.subscribe(&topics::prompt(r)).await?;
        streams.push(tagged(sk, name.clone(), Input::Skeletons));
        streams.push(tagged(js, name.clone(), Input::JointState));
        streams.push(tagged(pr, name.clone(), Input::Prompt));
        let active = Arc::new(AtomicBool::new(false));
        outputs.push((
            name,
            bus.publisher(&topics::forecast(r)).await?,
            active.clone(),
        ));
        flags.push((r.clone(), active));
        let key = keys::alive(r, &instance);
        tokens.push(
            bus.session()
                .liveliness()
                .declare_token(key.clone())
                .await
                .map_err(|e| anyhow::anyhow!("declaring liveliness token {key}: {e}"))?,
        );
    }
    let failover_task = tokio::spawn(follow_failover(
        bus.clone(),
        watch,
        args.rank,
        flags,
        seen,
        stop.clone(),
    ));
    let reporter = bus.spawn_status_reporter(Duration::from_secs(1), stop.clone());
    let mut stop_inputs = stop.clone();
    let inputs = futures::stream::select_all(streams)
        .take_until(Box::pin(async move { stop_inputs.wait().await }));
    let stats = bus.stats();
    let what = if server.robot_agent() {
        "forecasting the partner and the robot (HRI model): robot plans go to safety"
    } else {
        "forecasting the partner (human-human model: no robot plan)"
    };
    stats.set_notes(vec![
        format!("model {model_name} on {backend_name}"),
        format!("failover rank {} ({instance})", args.rank),
        what.into(),
        format!(
            "serving {}",
            robots
                .iter()
                .map(|r| r.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    ]);
    tracing::info!(robots = robots.len(), model = %model_name, backend = %backend_name, "forecaster running");
    let mut output = BusOutput {
        robots: outputs,
        stats: stats.clone(),
    };
    run(
        Box::pin(inputs),
        &mut output,
        server,
        &stats,
        Duration::from_millis(args.batch_window_ms),
        robots.len(),
        echo_msgs::now_ns,
    )
    .await?;
    let _ = tokio::time::timeout(Duration::from_secs(2), reporter).await;
    let _ = tokio::time::timeout(Duration::from_secs(2), failover_task).await;
    drop(tokens);
    drop(output);
    match Arc::try_unwrap(bus) {
        Ok(bus) => bus.close().await?,
        Err(_) => tracing::warn!("bus still shared at shutdown; closing by drop"),
    }
    tracing::info!("forecaster stopped");
    Ok(())
}

/// Edge names in counters.
pub mod edges {
    /// Skeleton input.
    pub const HUMANS: &str = "humans";
    /// Prompt input.
    pub const PROMPT: &str = "prompt";
    /// Forecast output (model failures).
    pub const FORECAST: &str = "forecast";
    /// Forecasts computed but not published: another instance is active.
    pub const STANDBY: &str = "forecast_standby";
    /// Robot histories dropped and restarted because every frame had been refused as reordered
    /// for `resync_after_ms` (counted under `dropped`).
    pub const RESYNC: &str = "humans_resync";
    /// Robot plans refined to reach the partner's hand in a contact interaction (counted under
    /// `published`).
    pub const CONTACT: &str = "plan_contact_refined";
    /// Robot plans given a visible wave (counted under `published`).
    pub const WAVE: &str = "plan_wave_refined";
}

fn handle(server: &mut ForecastServer, stats: &Stats, input: Input, wall_now_ns: u64) {
    match input {
        Input::Skeletons(r, m) => match server.on_skeletons_at(&r, &m.msg, wall_now_ns, m.at) {
            Ok(Some(Push::Resynced { stalled_ms })) => {
                stats.dropped(edges::RESYNC, 1);
                tracing::warn!(
                    robot = %r,
                    stalled_ms,
                    "every skeleton frame refused as reordered since the last accepted one: \
                     history restarted"
                );
            }
            Ok(_) => {}
            Err(e) => stats.rejected(edges::HUMANS, e.reason(), &format!("{r}: {e}")),
        },
        Input::JointState(r, m) => server.on_joint_state(&r, &m.msg),
        Input::Prompt(r, m) => {
            if let Err(e) = server.on_prompt(&r, &m.msg) {
                stats.rejected(edges::PROMPT, e.reason(), &format!("{r}: {e}"));
            }
        }
    }
}

/// Run over `inputs` until they end. After a frame makes a robot ready, inputs are taken for up
/// to `window` more (or until all `robots` are ready) so their forecasts share one batch.
/// `wall_now_ns` reads the receiver's wall clock (frames stamped too far ahead of it are
/// refused); each input's own receive instant is its monotonic time. Returns the server's
/// counters.
pub async fn run<S, O>(
    mut inputs: S,
    output: &mut O,
    mut server: ForecastServer,
    stats: &Stats,
    window: Duration,
    robots: usize,
    wall_now_ns: impl Fn() -> u64,
) -> Result<Counters>
where
    S: Stream<Item = Input> + Unpin,
    O: Output,
{
    let mut ended = false;
    while !ended {
        let Some(input) = inputs.next().await else {
            break;
        };
        handle(&mut server, stats, input, wall_now_ns());
        if server.pending() == 0 {
            continue;
        }
        let deadline = tokio::time::Instant::now() + window;
        while server.pending() < robots {
            match tokio::time::timeout_at(deadline, inputs.next()).await {
                Ok(Some(i)) => handle(&mut server, stats, i, wall_now_ns()),
                Ok(None) => {
                    ended = true;
                    break;
                }
                Err(_) => break,
            }
        }
        let before = server.counters();
        let batch = server.run_batch();
        let after = server.counters();
        for _ in before.contact_refined..after.contact_refined {
            stats.published(edges::CONTACT);
        }
        for _ in before.wave_refined..after.wave_refined {
            stats.published(edges::WAVE);
        }
        for (robot, res) in batch {
            match res {
                Ok(f) => {
                    stats.latency_ms(f.inference_ms);
                    output.forecast(&robot, f).await?;
                }
                Err(e) => stats.rejected(edges::FORECAST, e.reason(), &format!("{robot}: {e}")),
            }
        }
    }
    Ok(server.counters())
}
