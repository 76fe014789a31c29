//! `echoctl bench`: latency percentiles that criterion does not report.
//!
//! * `bridge`: processing time per keypoint frame of the perception bridge (median, p99).
//! * `safety`: one safety cycle (17 joints, separation, self-collision, rollout to rest).
//! * `forecaster`: one forward pass of the shipped forecaster at batch 1 and 16, candle and
//!   ONNX Runtime (prompt embeddings cached, as in the service).
//! * `bus`: round trip of a skeleton-sized message between two Zenoh peer sessions over TCP on
//!   loopback (A publishes, B echoes on another key, A times the return).
//! * `camera`: the pose estimator's stages at the TIAGo++ head camera's 640 × 480, with 1 and 2
//!   ONNX Runtime threads, and the bridge's step from its keypoints to a skeleton.
//! * `sizes`: inference (batch 1 and 16, candle and ONNX Runtime) and one training step
//!   (batch 64, candle) at the shipped width and at d_model 256 with 4 layers, as JSON for
//!   `scripts/bench-vs-pytorch`.

use std::time::{Duration, Instant};

use anyhow::Result;
use echo_bus::config::free_ports;
use echo_bus::stats::percentile_sorted;
use echo_bus::{topics, Bus, BusArgs};
use echo_perception::{BridgeConfig, PerceptionBridge};
use echo_robot::RobotModel;
use echo_sim::perception::{MockFormat, MockPerceptionConfig};
use echo_sim::scenario::bridge_inputs;

/// Options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// What to measure.
    #[arg(value_enum)]
    pub what: Bench,
    /// Checkpoint for `forecaster`.
    #[arg(long, default_value = "models/forecaster")]
    pub model: std::path::PathBuf,
    /// Samples.
    #[arg(long, default_value_t = 2000)]
    pub samples: usize,
    /// `e2e`: fleet sizes served by one forecaster.
    #[arg(long, value_delimiter = ',', default_value = "1,4,16")]
    pub robots: Vec<usize>,
    /// `e2e`: measured seconds per fleet size.
    #[arg(long, default_value_t = 15.0)]
    pub seconds: f64,
    /// `e2e`: the forecaster's checkpoint (an HRI model, so plans reach the safety service).
    #[arg(long, default_value = "models/hri")]
    pub e2e_model: std::path::PathBuf,
    /// `e2e`: the forecaster's backend.
    #[arg(long, value_enum, default_value_t = forecaster::BackendKind::Candle)]
    pub backend: forecaster::BackendKind,
    /// `forecaster`: time an untrained model of this width instead (`--model`'s architecture
    /// and prompt encoder otherwise; one head per 16 channels) — what a larger model costs.
    #[arg(long)]
    pub d_model: Option<usize>,
    /// `forecaster` with `--d-model`: self-attention layers.
    #[arg(long, default_value_t = 1)]
    pub self_layers: usize,
    /// `sizes`: write the medians here as JSON.
    #[arg(long)]
    pub json: Option<std::path::PathBuf>,
    /// `sizes`: fewer samples (a fifth).
    #[arg(long)]
    pub quick: bool,
    /// `camera`: the photograph of a person, scaled into the frame (default: `camera.png` from
    /// the fetched photos, `.cache/photos`).
    #[arg(long)]
    pub photo: Option<std::path::PathBuf>,
}

/// The benchmarks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Bench {
    /// The perception bridge's processing of one keypoint frame.
    Bridge,
    /// One safety control cycle.
    Safety,
    /// Forecaster inference per backend and batch size.
    Forecaster,
    /// A message through Zenoh between two sessions.
    Bus,
    /// The whole pipeline as processes, per number of robots.
    E2e,
    /// The pose estimator's stages on a 640 × 480 camera image.
    Camera,
    /// Inference and a training step at two model sizes, for the comparison with PyTorch.
    Sizes,
}

/// Run the chosen benchmark and print a one-line summary per case.
pub async fn run(args: Args) -> Result<()> {
    match args.what {
        Bench::Bridge => bridge(args.samples),
        Bench::Bus => bus(args.samples).await,
        Bench::Safety => {
            safety(args.samples);
            Ok(())
        }
        Bench::Forecaster => match args.d_model {
            Some(d) => {
                let stem = untrained(&args.model, d, args.self_layers)?;
                let r = forecaster(&stem, args.samples).map(|_| ());
                let _ = std::fs::remove_file(stem.with_extension("safetensors"));
                let _ = std::fs::remove_file(stem.with_extension("json"));
                r
            }
            None => forecaster(&args.model, args.samples).map(|_| ()),
        },
        Bench::Sizes => super::bench_sizes::run(&args.model, args.quick, args.json.as_deref()),
        Bench::E2e => e2e(&args).await,
        Bench::Camera => super::bench_camera::run(args.samples, args.photo.as_deref()),
    }
}

/// Perception → forecast → command across processes, for each fleet size.
async fn e2e(args: &Args) -> Result<()> {
    use super::fleet::{med_p99, run, FleetOptions};
    println!(
        "end to end over Zenoh on loopback, separate processes; model {} ({}); {} s per size; \
         median / p99 in ms",
        args.e2e_model.display(),
        args.backend,
        args.seconds
    );
    println!(
        "| robots | frames | forecasts | perception→skeletons | perception→forecast | model inference | pipeline overhead | forecast→command | perception→command |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for &n in &args.robots {
        let log_dir = std::env::temp_dir().join(format!("echo-e2e-{}-{n}", std::process::id()));
        let r = run(&FleetOptions {
            robots: n.max(1),
            with_safety: 1,
            seconds: args.seconds,
            model: args.e2e_model.clone(),
            backend: args.backend,
            log_dir: log_dir.clone(),
            rss_every: None,
        })
        .await?;
        // A run that failed returned above and keeps its logs (its error names them).
        let _ = std::fs::remove_dir_all(&log_dir);
        println!(
            "| {n} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.frames_sent,
            r.forecasts,
            med_p99(&r.to_humans_ms),
            med_p99(&r.to_forecast_ms),
            med_p99(&r.inference_ms),
            med_p99(&r.overhead_ms),
            med_p99(&r.forecast_to_command_ms),
            med_p99(&r.to_command_ms),
        );
    }
    Ok(())
}

/// One line: count, median, p99 and max of `v` (milliseconds).
/// Print a case's median, p99 and maximum; returns the median.
pub(crate) fn report(name: &str, mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    println!(
        "{name:<40} n={:<6} median {:8.3} ms   p99 {:8.3} ms   max {:8.3} ms",
        v.len(),
        percentile_sorted(&v, 50.0),
        percentile_sorted(&v, 99.0),
        v[v.len() - 1]
    );
    percentile_sorted(&v, 50.0)
}

/// A randomly initialised checkpoint of `like`'s architecture at width `d` (16 channels per
/// head) with `self_layers` self-attention layers, in the temporary folder: its stem.
pub(crate) fn untrained(
    like: &std::path::Path,
    d: usize,
    self_layers: usize,
) -> Result<std::path::PathBuf> {
    use candle_nn::{VarBuilder, VarMap};
    use echo_models::model::Forecaster;
    use echo_models::{Checkpoint, CheckpointMeta};
    anyhow::ensure!(
        d >= 16 && d.is_multiple_of(16),
        "--d-model must be a multiple of 16"
    );
    let mut meta = CheckpointMeta::load(like)?;
    meta.model.d_model = d;
    meta.model.heads = d / 16;
    meta.model.self_layers = self_layers;
    meta.command = format!("untrained, d_model {d}, {self_layers} self-attention layers");
    let vm = VarMap::new();
    Forecaster::new(
        meta.model.clone(),
        VarBuilder::from_varmap(&vm, candle_core::DType::F32, &candle_core::Device::Cpu),
    )?;
    let stem = std::env::temp_dir().join(format!("echo-bench-d{d}-{}", std::process::id()));
    Checkpoint::save(&vm, &meta, &stem)?;
    println!(
        "untrained forecaster: d_model {d}, {} heads, {self_layers} self-attention layers, {} rounds, {} parameters",
        d / 16,
        meta.model.rounds,
        vm.all_vars().iter().map(|v| v.elem_count()).sum::<usize>()
    );
    Ok(stem)
}

/// One inference case's result: backend, batch, median (ms), samples.
pub(crate) type Measured = (String, usize, f64, usize);

/// Time each backend on `stem` at batch 1 and 16 (`samples` at batch 1, a quarter at 16).
pub(crate) fn forecaster(stem: &std::path::Path, samples: usize) -> Result<Vec<Measured>> {
    use echo_models::{Backend, CandleBackend, Checkpoint};
    let dev = candle_core::Device::Cpu;
    let mut ck = Checkpoint::load(stem, &dev)?;
    let cfg = ck.meta.model.clone();
    let text = ck.text.take();
    let mut backends: Vec<(String, Box<dyn Backend>)> =
        vec![("candle-cpu".into(), Box::new(CandleBackend::new(ck, dev)))];
    // ONNX Runtime with its own choice of intra-op threads (one per core), and with one thread:
    // a model this small spends much of a batch-1 call handing work to the pool.
    for (label, threads) in [("onnxruntime-cpu", 0), ("onnxruntime-cpu-1t", 1)] {
        match echo_onnx::OrtBackend::from_checkpoint(stem, cfg.clone(), threads) {
            Ok(b) => backends.push((label.into(), Box::new(b))),
            Err(e) => println!("{label}: not measured ({e})"),
        }
    }
    let prompt = "One person extends a handshake with their right hand, while the other reciprocates with their own.";
    let emb = match &text {
        Some(e) => {
            let t = Instant::now();
            let v = e.embed_one(prompt)?;
            report(
                "prompt embedding (MiniLM, first time)",
                vec![t.elapsed().as_secs_f64() * 1e3],
            );
            let t = Instant::now();
            e.embed_one(prompt)?;
            report(
                "prompt embedding (cached)",
                vec![t.elapsed().as_secs_f64() * 1e3],
            );
            v
        }
        None => vec![],
    };
    // Real windows: observed features of generated test interactions.
    let clips =
        echo_motion::synth::generate_split(echo_motion::synth::Split::Test, 0..13, 2, &|| {});
    let windows: Vec<_> = clips
        .iter()
        .flat_map(|c| echo_eval::window::windows(c, 4))
        .collect();
    let mut out = Vec::new();
    for b in [1usize, 16] {
        let ws: Vec<&echo_eval::Window> = windows.iter().cycle().take(b).collect();
        let (_, obs) = echo_train::encode_observed(&ws, cfg.obs);
        let text: Vec<f32> = (0..b).flat_map(|_| emb.iter().copied()).collect();
        for (label, be) in backends.iter_mut() {
            for _ in 0..10 {
                be.predict(b, &obs, &text)?;
            }
            let n = if b == 1 { samples } else { samples / 4 };
            let mut v = Vec::with_capacity(n);
            for _ in 0..n.max(10) {
                let t = Instant::now();
                be.predict(b, &obs, &text)?;
                v.push(t.elapsed().as_secs_f64() * 1e3);
            }
            let n = v.len();
            let median = report(&format!("forecaster {label} batch {b}"), v);
            out.push((label.clone(), b, median, n));
        }
    }
    Ok(out)
}

fn bridge(samples: usize) -> Result<()> {
    let model = RobotModel::tiago_dual();
    for (name, format, bystander) in [
        ("bridge smpl24, 1 person", MockFormat::Smpl24Points, false),
        ("bridge smpl24, 2 people", MockFormat::Smpl24Points, true),
        (
            "bridge coco17, 1 person",
            MockFormat::Coco17PixelsDepth,
            false,
        ),
    ] {
        let inputs = bridge_inputs(
            samples + 10,
            MockPerceptionConfig {
                format,
                bystander,
                ..Default::default()
            },
        );
        let mut br = PerceptionBridge::new(BridgeConfig::default(), model.clone());
        let mut times = Vec::with_capacity(samples);
        let mut tracked = 0usize;
        for (i, (js, f)) in inputs.iter().enumerate() {
            br.on_joint_state(js);
            let t = Instant::now();
            let out = br.on_keypoints(f, f.header.stamp_ns + 30_000_000)?;
            let dt = t.elapsed().as_secs_f64() * 1e3;
            if out.skeletons.iter().any(|s| !s.tracks.is_empty()) {
                tracked += 1;
            }
            std::hint::black_box(out);
            if i >= 10 {
                times.push(dt);
            }
        }
        // The script loops every 13 s (the person jumps back to the start), and at 0.9 m with the
        // head turned part of the body leaves a 640 × 480 image: those frames track nobody.
        if tracked < inputs.len() / 2 {
            anyhow::bail!(
                "only {tracked} of {} frames produced a tracked person",
                inputs.len()
            );
        }
        report(
            &format!("{name} ({}% tracked)", 100 * tracked / inputs.len()),
            times,
        );
    }
    Ok(())
}

fn safety(samples: usize) {
    use echo_safety::bench_support::{moving_scene, Scene};
    for (scene, label) in [
        (
            Scene::PersonInView,
            "safety cycle, 17 joints, person in view",
        ),
        (
            Scene::HandshakePartner,
            "safety cycle, 17 joints, handshake partner (contact mode)",
        ),
    ] {
        let (mut sup, mut feed) = moving_scene(scene);
        let mut now = Instant::now();
        let mut times = Vec::with_capacity(samples);
        for i in 0..samples + 50 {
            now += Duration::from_millis(20);
            feed(&mut sup, now);
            let t = Instant::now();
            let tick = sup.tick(now);
            let dt = t.elapsed().as_secs_f64() * 1e3;
            std::hint::black_box(tick);
            if i >= 50 {
                times.push(dt);
            }
        }
        report(label, times);
    }
}

async fn bus(samples: usize) -> Result<()> {
    let ports = free_ports(2);
    let a = Bus::open(
        &BusArgs::loopback("bench", &[ports[0]], &[ports[1]]),
        "bench-a",
    )
    .await?;
    let b = Bus::open(
        &BusArgs::loopback("bench", &[ports[1]], &[ports[0]]),
        "bench-b",
    )
    .await?;
    let r = a.robot().clone();
    // A skeleton-sized payload: one real bridge output.
    let frame = bridge_inputs(12, MockPerceptionConfig::default());
    let mut br = PerceptionBridge::new(BridgeConfig::default(), RobotModel::tiago_dual());
    let mut sample = None;
    for (js, f) in &frame {
        br.on_joint_state(js);
        sample = br
            .on_keypoints(f, f.header.stamp_ns + 1)?
            .skeletons
            .pop()
            .or(sample);
    }
    let mut sample = sample.ok_or_else(|| anyhow::anyhow!("no skeleton to send"))?;
    sample.header.robot_id = r.to_string();
    let size = echo_msgs::encode(&sample).len();
    let ping = topics::humans(&r);
    // The echo goes back on the same kind of topic of a second robot id.
    let echo_robot = echo_bus::RobotId::new("bench-echo")?;
    let pong = topics::humans(&echo_robot);
    let a_pub = a.publisher(&ping).await?;
    let a_sub = a.subscribe(&pong).await?;
    let b_sub = b.subscribe(&ping).await?;
    let b_pub = b.publisher(&pong).await?;
    let echo = tokio::spawn(async move {
        while let Some(mut m) = b_sub.recv().await {
            m.msg.header.robot_id = "bench-echo".into();
            if b_pub.put(m.msg).await.is_err() {
                break;
            }
        }
    });
    tokio::time::sleep(Duration::from_millis(500)).await;
    let mut times = Vec::with_capacity(samples);
    for i in 0..samples + 50 {
        let t = Instant::now();
        a_pub.put(sample.clone()).await?;
        match tokio::time::timeout(Duration::from_secs(1), a_sub.recv()).await {
            Ok(Some(_)) => {
                if i >= 50 {
                    times.push(t.elapsed().as_secs_f64() * 1e3);
                }
            }
            _ => anyhow::bail!("echo lost after {i} round trips"),
        }
    }
    report(&format!("bus round trip ({size} B JSON)"), times);
    echo.abort();
    a.close().await?;
    b.close().await
}
