//! Determinism: scripted perception (a mock pose estimator and a simulated robot, seeded)
//! through the perception bridge → the forecaster → the safety service, each driven through its
//! own service loop with fixed clocks and no network, run twice and compared with stored golden
//! outputs. Timing fields (`stamp_ns`, `inference_ms`) are masked; every other number must
//! match within [`TOLERANCE`] (0.1 mm or 0.1 mrad: what differing float reduction orders on
//! another CPU may change, far below anything that matters to the robot).
//!
//! Regenerate the golden files after an intended change with
//! `ECHO_UPDATE_GOLDEN=1 cargo test -p echo-system-tests --test determinism`.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use echo_bus::{Received, Stats};
use echo_forecast::{ForecastServer, ServerConfig};
use echo_msgs::{
    ControlMode, Forecast, Header, HumanSkeletons, Interaction, InteractionIntent, RobotCommand,
    SafetyStatus,
};
use echo_robot::RobotModel;
use echo_safety::{SafetyConfig, Supervisor};
use echo_sim::perception::MockPerceptionConfig;
use echo_sim::robot::{SimRobot, SimRobotConfig};
use echo_sim::scenario::{bridge_inputs, T0_NS};
use serde_json::Value;

/// Largest difference accepted between a number and its golden value.
const TOLERANCE: f64 = 1e-4;
/// Keypoint frames scripted (15 Hz).
const FRAMES: usize = 60;
const ROBOT: &str = "tiago";

fn golden_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("golden")
        .join(format!("determinism-{name}.json"))
}

fn rx<M>(msg: M, at: Instant) -> Received<M> {
    Received { msg, at }
}

/// The instant a stamp corresponds to on the scripted monotonic clock.
fn at(t0: Instant, stamp_ns: u64) -> Instant {
    t0 + Duration::from_nanos(stamp_ns.saturating_sub(T0_NS))
}

#[derive(Default)]
struct Skeletons(Vec<HumanSkeletons>);
impl perception_bridge::Output for Skeletons {
    async fn skeletons(&mut self, msg: HumanSkeletons) -> anyhow::Result<()> {
        self.0.push(msg);
        Ok(())
    }
}

struct Forecasts(Arc<Mutex<Vec<Forecast>>>);
impl forecaster::Output for Forecasts {
    async fn forecast(&mut self, _robot: &str, msg: Forecast) -> anyhow::Result<()> {
        self.0.lock().expect("forecasts").push(msg);
        Ok(())
    }
}

/// Feeds a service loop one input at a time: `send` returns once the loop has finished with
/// the input (it asked for the next one), so the driver and the loop move in lockstep.
struct Feed {
    tx: tokio::sync::mpsc::Sender<forecaster::Input>,
    done: tokio::sync::mpsc::Receiver<()>,
}

impl Feed {
    async fn send(&mut self, input: forecaster::Input) {
        self.tx.send(input).await.expect("the loop ended early");
        self.done.recv().await.expect("the loop ended early");
    }
}

fn lockstep() -> (Feed, futures::stream::BoxStream<'static, forecaster::Input>) {
    use futures::StreamExt;
    let (tx, rx) = tokio::sync::mpsc::channel(1);
    let (done_tx, mut done) = tokio::sync::mpsc::channel(1);
    let stream = futures::stream::unfold(
        (rx, done_tx, false),
        |(mut rx, done_tx, started)| async move {
            if started {
                // The previous input is finished: the loop is asking for the next.
                let _ = done_tx.send(()).await;
            }
            rx.recv().await.map(|i| (i, (rx, done_tx, true)))
        },
    )
    .boxed();
    // No acknowledgement before the first input.
    let _ = done.try_recv();
    (Feed { tx, done }, stream)
}

#[derive(Default)]
struct Commands {
    commands: Vec<RobotCommand>,
    statuses: Vec<SafetyStatus>,
}
impl safety::Output for Commands {
    async fn command(&mut self, cmd: RobotCommand) -> anyhow::Result<()> {
        self.commands.push(cmd);
        Ok(())
    }
    async fn status(&mut self, st: SafetyStatus) -> anyhow::Result<()> {
        self.statuses.push(st);
        Ok(())
    }
}

fn intent() -> InteractionIntent {
    InteractionIntent {
        header: Header::new(ROBOT, "operator", ""),
        text: "The person offers a handshake and the robot shakes hands.".into(),
        interaction: Interaction::Handshake,
        mode: ControlMode::Forecast,
    }
}

/// The whole chain once; its outputs as JSON.
async fn pipeline(backend: &str) -> Value {
    let t0 = Instant::now();
    let script = bridge_inputs(FRAMES, MockPerceptionConfig::default());

    // Perception bridge: the receiver's wall clock is 20 ms after the newest capture.
    let mut inputs = vec![];
    for (js, kf) in &script {
        inputs.push(perception_bridge::Input::JointState(rx(
            js.clone(),
            at(t0, js.header.stamp_ns),
        )));
        inputs.push(perception_bridge::Input::Keypoints(rx(
            kf.clone(),
            at(t0, kf.header.stamp_ns),
        )));
    }
    let newest = std::sync::atomic::AtomicU64::new(T0_NS);
    let stream = futures::stream::iter(inputs.into_iter().inspect(|i| {
        if let perception_bridge::Input::Keypoints(k) = i {
            newest.fetch_max(k.msg.header.stamp_ns, std::sync::atomic::Ordering::Relaxed);
        }
    }));
    let mut skeletons = Skeletons::default();
    let bridge = echo_perception::PerceptionBridge::new(
        echo_perception::BridgeConfig::default(),
        RobotModel::tiago_dual(),
    );
    perception_bridge::run(
        stream,
        &mut skeletons,
        bridge,
        &Stats::new("perception-bridge"),
        || newest.load(std::sync::atomic::Ordering::Relaxed) + 20_000_000,
    )
    .await
    .expect("bridge");
    assert!(skeletons.0.len() >= FRAMES - 2, "{}", skeletons.0.len());

    // Forecaster (the HRI model: forecasts carry the robot's plan) and safety in lockstep on the
    // scripted clock, the loop closed through the simulated robot: 50 Hz safety cycles; the
    // forecaster gets the robot's joint state and each skeleton frame when its stamp comes up,
    // and its forecast reaches safety 30 ms later.
    let model = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../models/hri");
    let args = <ForecasterCli as clap::Parser>::parse_from([
        "forecaster",
        "--model",
        model.to_str().unwrap_or_default(),
        "--backend",
        backend,
    ])
    .args;
    let (be, text, name) = forecaster::load_backend(&args).expect("backend");
    let server = ForecastServer::new(
        ServerConfig::default(),
        be,
        text,
        &name,
        RobotModel::tiago_dual(),
    )
    .expect("server");
    let last_stamp = skeletons.0.last().map_or(T0_NS, |s| s.header.stamp_ns);
    let clock = Arc::new(AtomicU64::new(T0_NS));
    let forecasts = Arc::new(Mutex::new(Vec::<Forecast>::new()));
    let (mut feed, stream) = lockstep();
    let task = {
        let (clock, forecasts) = (clock.clone(), forecasts.clone());
        tokio::spawn(async move {
            let mut out = Forecasts(forecasts);
            forecaster::run(
                stream,
                &mut out,
                server,
                &Stats::new("forecaster"),
                Duration::ZERO,
                1,
                move || clock.load(Ordering::Relaxed),
            )
            .await
        })
    };
    feed.send(forecaster::Input::Prompt(ROBOT.into(), rx(intent(), t0)))
        .await;

    let sup = Supervisor::new(SafetyConfig::default(), RobotModel::tiago_dual()).expect("sup");
    let mut lp = safety::Loop::new(sup, ROBOT);
    let stats = Stats::new("safety");
    let mut out = Commands::default();
    let mut sim = SimRobot::new(SimRobotConfig::default(), RobotModel::tiago_dual());
    lp.on(safety::Input::Prompt(rx(intent(), t0)), &mut out, &stats)
        .await
        .expect("prompt");
    let mut frames = skeletons.0.iter().peekable();
    let mut delivered = 0;
    let cycles = (last_stamp - T0_NS) / 20_000_000 + 25;
    for c in 0..cycles {
        let stamp = T0_NS + c * 20_000_000;
        let now = at(t0, stamp);
        clock.store(stamp + 20_000_000, Ordering::Relaxed);
        let state = sim.joint_state(ROBOT, stamp);
        while let Some(s) = frames.next_if(|s| s.header.stamp_ns <= stamp) {
            feed.send(forecaster::Input::JointState(
                ROBOT.into(),
                rx(state.clone(), now),
            ))
            .await;
            feed.send(forecaster::Input::Skeletons(
                ROBOT.into(),
                rx(s.clone(), now),
            ))
            .await;
        }
        lp.on(safety::Input::State(rx(state, now)), &mut out, &stats)
            .await
            .expect("state");
        let ready: Vec<Forecast> = {
            let all = forecasts.lock().expect("forecasts");
            all[delivered..]
                .iter()
                .take_while(|f| f.header.stamp_ns + 30_000_000 <= stamp)
                .cloned()
                .collect()
        };
        delivered += ready.len();
        for f in ready {
            lp.on(safety::Input::Forecast(rx(f, now)), &mut out, &stats)
                .await
                .expect("forecast");
        }
        let before = out.commands.len();
        lp.on(safety::Input::Tick(now), &mut out, &stats)
            .await
            .expect("tick");
        if out.commands.len() > before {
            sim.command(&out.commands[before]);
        }
        sim.step(0.02);
    }
    drop(feed);
    task.await.expect("join").expect("forecaster");
    let forecasts = forecasts.lock().expect("forecasts").clone();
    assert!(forecasts.len() > 20, "{}", forecasts.len());
    assert!(forecasts.iter().all(|f| f.robot.is_some()));
    assert!(out.commands.len() as u64 >= cycles - 1);

    let mut doc = serde_json::json!({
        "skeletons": every(&skeletons.0, 5),
        "forecasts": forecasts.iter().step_by(4).map(thin).collect::<Vec<_>>(),
        "commands": out.commands.iter().step_by(10).map(thin_command).collect::<Vec<_>>(),
        "states": out.statuses.iter().map(|s| serde_json::json!([s.state, s.reasons])).collect::<Vec<_>>(),
    });
    mask(&mut doc);
    doc
}

#[derive(clap::Parser)]
struct ForecasterCli {
    #[command(flatten)]
    args: forecaster::Args,
}

/// Every `n`-th item (from the first) as JSON.
fn every<T: serde::Serialize>(v: &[T], n: usize) -> Vec<Value> {
    v.iter()
        .step_by(n)
        .map(|x| serde_json::to_value(x).unwrap_or(Value::Null))
        .collect()
}

/// A forecast at the reported horizons only (frames 3, 8, 15, 23: 0.2, 0.5, 1.0, 1.5 s), its
/// robot plan likewise.
fn thin(f: &Forecast) -> Value {
    let pick = |n: usize| [2usize, 7, 14, 22].into_iter().filter(move |k| *k < n);
    let mut f = f.clone();
    f.human = pick(f.human.len()).map(|k| f.human[k].clone()).collect();
    if let Some(p) = f.robot.as_mut() {
        p.points = pick(p.points.len()).map(|k| p.points[k].clone()).collect();
    }
    serde_json::to_value(f).unwrap_or(Value::Null)
}

/// A command with each trajectory's first and last point (and how many there were).
fn thin_command(c: &RobotCommand) -> Value {
    let mut c = c.clone();
    let counts: Vec<usize> = c.trajectories.iter().map(|t| t.points.len()).collect();
    for t in &mut c.trajectories {
        if t.points.len() > 2 {
            t.points = vec![t.points[0].clone(), t.points[t.points.len() - 1].clone()];
        }
    }
    serde_json::json!({ "points": counts, "command": c })
}

/// Timing fields out; numbers rounded to the micro-unit (the golden file stays readable).
fn mask(v: &mut Value) {
    match v {
        Value::Object(m) => {
            for k in ["stamp_ns", "inference_ms"] {
                m.remove(k);
            }
            m.values_mut().for_each(mask);
        }
        Value::Array(a) => a.iter_mut().for_each(mask),
        Value::Number(n) => {
            if let Some(x) = n.as_f64().filter(|_| !n.is_u64() && !n.is_i64()) {
                *v = serde_json::json!((x * 1e6).round() / 1e6);
            }
        }
        _ => {}
    }
}

/// The first place where `a` and `b` differ beyond the tolerance, as a path.
fn differ(a: &Value, b: &Value, path: &str) -> Option<String> {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64()?, y.as_f64()?);
            ((x - y).abs() > TOLERANCE).then(|| format!("{path}: {x} vs {y}"))
        }
        (Value::Array(x), Value::Array(y)) => {
            if x.len() != y.len() {
                return Some(format!("{path}: {} items vs {}", x.len(), y.len()));
            }
            x.iter()
                .zip(y)
                .enumerate()
                .find_map(|(i, (p, q))| differ(p, q, &format!("{path}[{i}]")))
        }
        (Value::Object(x), Value::Object(y)) => {
            if x.len() != y.len() || x.keys().any(|k| !y.contains_key(k)) {
                return Some(format!("{path}: fields differ"));
            }
            x.iter()
                .find_map(|(k, p)| differ(p, &y[k], &format!("{path}.{k}")))
        }
        _ => (a != b).then(|| format!("{path}: {a} vs {b}")),
    }
}

async fn check(backend: &str) {
    let first = pipeline(backend).await;
    let second = pipeline(backend).await;
    if let Some(d) = differ(&first, &second, "") {
        panic!("{backend}: two runs differ at {d}");
    }
    let path = golden_path(backend);
    if std::env::var("ECHO_UPDATE_GOLDEN").as_deref() == Ok("1") {
        std::fs::create_dir_all(path.parent().expect("dir")).expect("golden dir");
        std::fs::write(&path, serde_json::to_vec(&first).expect("json")).expect("write");
        eprintln!("wrote {}", path.display());
        return;
    }
    let golden: Value = serde_json::from_slice(
        &std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())),
    )
    .expect("golden JSON");
    if let Some(d) = differ(&first, &golden, "") {
        panic!(
            "{backend}: output differs from {} at {d} (ECHO_UPDATE_GOLDEN=1 regenerates it after an intended change)",
            path.display()
        );
    }
}

#[tokio::test]
async fn zero_velocity_pipeline_is_deterministic_and_matches_its_golden_output() {
    check("zero-velocity").await;
}

#[tokio::test]
async fn shipped_model_pipeline_is_deterministic_and_matches_its_golden_output() {
    check("candle").await;
}

#[test]
fn a_single_changed_value_is_found() {
    let a =
        serde_json::json!({"commands": [{"q": [0.1, 0.2, 0.3]}], "states": [["following", []]]});
    let mut b = a.clone();
    assert_eq!(differ(&a, &b, ""), None);
    b["commands"][0]["q"][1] = serde_json::json!(0.2 + 2.0 * TOLERANCE);
    assert_eq!(
        differ(&a, &b, ""),
        Some(format!(
            ".commands[0].q[1]: 0.2 vs {}",
            0.2 + 2.0 * TOLERANCE
        ))
    );
    let mut c = a.clone();
    c["commands"][0]["q"][1] = serde_json::json!(0.2 + 0.5 * TOLERANCE);
    assert_eq!(differ(&a, &c, ""), None, "within the tolerance");
    let mut d = a.clone();
    d["states"][0][0] = serde_json::json!("holding");
    assert!(differ(&a, &d, "").is_some());
}
