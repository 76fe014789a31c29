//! `echoctl scene`: Echo in 3D — a recording as a Foxglove MCAP or an animated GIF, or the live
//! bus as a Foxglove WebSocket server; `echoctl view`: the live bus in a browser.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{anyhow, Context, Result};
use echo_bus::shutdown::{self, Shutdown};
use echo_bus::{keys, Bus, BusArgs};
use echo_msgs::now_ns;
use echo_scene::foxglove::{convert_recording, FoxgloveOptions, LiveServer};
use echo_scene::web::WebViewer;
use echo_scene::{render_recording, RenderOptions, SceneBuilder};

/// Scene verbs.
#[derive(Debug, Clone, clap::Subcommand)]
pub enum Verb {
    /// Convert a recording into an MCAP Foxglove draws in 3D (/scene, /tf, and the raw JSON).
    Mcap(McapArgs),
    /// Render a recording as an animated GIF seen from beside the interaction.
    Gif(GifArgs),
    /// Serve the live bus to Foxglove (connect to ws://localhost:8765).
    Live(LiveArgs),
}

/// Options of `echoctl scene mcap`.
#[derive(Debug, Clone, clap::Args)]
pub struct McapArgs {
    /// The recording (from `echoctl record`).
    pub input: PathBuf,
    /// The Foxglove MCAP to write.
    pub output: PathBuf,
    /// Most scene updates per second of recording time.
    #[arg(long, default_value_t = 30.0)]
    pub scene_hz: f64,
    /// Leave out the bus's JSON messages (scenes and frames only).
    #[arg(long)]
    pub no_raw: bool,
}

/// Options of `echoctl scene gif`.
#[derive(Debug, Clone, clap::Args)]
pub struct GifArgs {
    /// The recording (from `echoctl record`).
    pub input: PathBuf,
    /// The GIF to write.
    pub output: PathBuf,
    /// Frames per second (at most 50).
    #[arg(long, default_value_t = 10.0)]
    pub fps: f64,
    /// Width in pixels (the height is ¾ of it).
    #[arg(long, default_value_t = 640)]
    pub width: u32,
}

/// Options of `echoctl scene live`.
#[derive(Debug, Clone, clap::Args)]
pub struct LiveArgs {
    /// Network.
    #[command(flatten)]
    pub bus: BusArgs,
    /// WebSocket port.
    #[arg(long, default_value_t = 8765)]
    pub port: u16,
    /// Address to listen on (0.0.0.0 to serve other machines).
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// Scene updates per second.
    #[arg(long, default_value_t = 30.0)]
    pub hz: f64,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long)]
    pub seconds: Option<f64>,
}

/// Run a scene verb.
pub async fn run(verb: Verb) -> Result<()> {
    match verb {
        Verb::Mcap(a) => mcap(a),
        Verb::Gif(a) => gif(a),
        Verb::Live(a) => live(a).await,
    }
}

fn mcap(a: McapArgs) -> Result<()> {
    let opts = FoxgloveOptions {
        scene_hz: a.scene_hz,
        keep_raw: !a.no_raw,
        ..FoxgloveOptions::default()
    };
    let s = convert_recording(&a.input, &a.output, &opts)?;
    println!(
        "wrote {}: {} scenes, {} frame updates, {} bus messages ({} not drawn: malformed)",
        a.output.display(),
        s.scenes,
        s.transforms,
        s.raw,
        s.rejected
    );
    Ok(())
}

fn gif(a: GifArgs) -> Result<()> {
    let opts = RenderOptions {
        fps: a.fps,
        width: a.width,
        ..RenderOptions::default()
    };
    let started = std::time::Instant::now();
    let s = render_recording(&a.input, &a.output, &opts)?;
    println!(
        "wrote {}: {} frames of {}×{}, {:.1} s ({:.1} s recorded, {} messages, {} malformed) in {:.1} s",
        a.output.display(),
        s.frames,
        s.width,
        s.height,
        s.duration_s,
        s.recording_s,
        s.messages,
        s.rejected,
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

async fn live(a: LiveArgs) -> Result<()> {
    check_hz(a.hz)?;
    let bus = Bus::open(&a.bus, "echoctl-scene").await?;
    let server = LiveServer::start(&a.host, a.port)
        .await
        .with_context(|| format!("serving Foxglove on {}:{}", a.host, a.port))?;
    println!(
        "Foxglove: open connection ws://{}:{} (robot {}); Ctrl-C to stop",
        if a.host == "0.0.0.0" {
            "localhost"
        } else {
            &a.host
        },
        server.port(),
        bus.robot()
    );
    let builder = follow(
        &bus,
        a.hz,
        a.seconds,
        shutdown::on_signals(),
        |key, payload, t| server.publish_raw(key, payload, t),
        |builder, t| server.publish(builder, t),
    )
    .await?;
    let stats = builder.stats();
    println!(
        "served {} messages ({} malformed) to {} client(s)",
        stats.accepted.values().sum::<u64>(),
        stats.rejected_total(),
        server.clients()
    );
    server.stop().await;
    bus.close().await
}

/// Options of `echoctl view`.
#[derive(Debug, Clone, clap::Args)]
pub struct ViewArgs {
    /// Network.
    #[command(flatten)]
    pub bus: BusArgs,
    /// HTTP port (0: any free port; the address is printed).
    #[arg(long, default_value_t = 8080)]
    pub port: u16,
    /// Address to listen on (0.0.0.0 to serve other machines).
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// Scene updates per second.
    #[arg(long, default_value_t = 15.0)]
    pub hz: f64,
    /// Directory holding three.js (`three.module.js`, `OrbitControls.js`; default: found by
    /// `scripts/setup`'s `.cache/web`).
    #[arg(long)]
    pub assets: Option<PathBuf>,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long)]
    pub seconds: Option<f64>,
}

/// `echoctl view`: the live bus in a browser (a three.js page served from this process).
pub async fn view(a: ViewArgs) -> Result<()> {
    serve_view(a, shutdown::on_signals()).await
}

/// Serve the viewer until `stop` (or `--seconds`).
pub async fn serve_view(a: ViewArgs, stop: Shutdown) -> Result<()> {
    check_hz(a.hz)?;
    let assets = a.assets.clone().or_else(echo_scene::web::locate_assets);
    if assets.is_none() {
        eprintln!(
            "warning: three.js not found (looked in {}); run scripts/setup — the page will say so",
            echo_scene::web::asset_dirs()
                .iter()
                .map(|d| d.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let bus = Bus::open(&a.bus, "echoctl-view").await?;
    let server = WebViewer::start(&a.host, a.port, assets.as_deref())
        .await
        .with_context(|| format!("serving the viewer on {}:{}", a.host, a.port))?;
    // Tests and scripts read this line for the address.
    println!(
        "viewer: open {} (robot {}); Ctrl-C to stop",
        server.url(),
        bus.robot()
    );
    let builder = follow(
        &bus,
        a.hz,
        a.seconds,
        stop,
        |_, _, _| {},
        |builder, t| server.publish(&builder.scene(t)),
    )
    .await?;
    let stats = builder.stats();
    println!(
        "viewer: {} messages ({} malformed), {} scenes, {} page polls",
        stats.accepted.values().sum::<u64>(),
        stats.rejected_total(),
        server.published(),
        server.polls()
    );
    server.stop().await;
    bus.close().await
}

fn check_hz(hz: f64) -> Result<()> {
    if !(hz.is_finite() && hz > 0.0 && hz <= 1000.0) {
        return Err(anyhow!("--hz must be in (0, 1000], got {hz}"));
    }
    Ok(())
}

/// Follow the robot's bus keys into a [`SceneBuilder`] until `stop` or `seconds`: every message
/// goes to `on_message` (key, payload, receive time), and `hz` times a second `on_tick` gets
/// the builder.
async fn follow(
    bus: &Bus,
    hz: f64,
    seconds: Option<f64>,
    mut stop: Shutdown,
    on_message: impl Fn(&str, &[u8], u64),
    on_tick: impl Fn(&SceneBuilder, u64),
) -> Result<SceneBuilder> {
    let key = keys::robot_all(bus.robot());
    let sub = bus
        .session()
        .declare_subscriber(key.as_str())
        .await
        .map_err(|e| anyhow!("subscribing to {key}: {e}"))?;
    let mut builder = SceneBuilder::new().for_robot(bus.robot().as_str());
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / hz));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let deadline = seconds.map(|s| tokio::time::Instant::now() + Duration::from_secs_f64(s));
    loop {
        tokio::select! {
            s = sub.recv_async() => match s {
                Ok(s) => {
                    let t = now_ns();
                    let payload = s.payload().to_bytes();
                    builder.on_message_at(s.key_expr().as_str(), &payload, Some(t));
                    on_message(s.key_expr().as_str(), &payload, t);
                }
                Err(_) => break,
            },
            _ = tick.tick() => on_tick(&builder, now_ns()),
            _ = stop.wait() => break,
            _ = async { match deadline { Some(d) => tokio::time::sleep_until(d).await, None => std::future::pending().await } } => break,
        }
    }
    drop(sub);
    Ok(builder)
}
