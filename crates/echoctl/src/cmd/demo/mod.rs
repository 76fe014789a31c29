//! `echoctl demo`: the whole pipeline on loopback — every service a separate OS process (or a
//! task with `--single-process`), each with its own Zenoh peer session — driven by the mock
//! perception's scripted partner, with a live status line and a final summary.
//!
//! By default the robot meets a person: the HRI forecaster (`models/hri`) plans its motion,
//! the partner performs a mission (walk up and shake hands, hand an object over, wave
//! goodbye; `--scenario` picks another scenario file of `deploy/scenarios/`, such as one
//! interaction, or a file of your own; `--capture` replays a real capture), the demo
//! announces each interaction on `prompt`, and the summary says per interaction what the robot
//! did ([`mission`]). `--scenario watch` runs the human–human forecaster on the scripted partner
//! (the robot only watches), `--scenario imitation` the retargeter's mirroring.
//!
//! `--camera DIR` runs the pipeline from pictures instead (profile `camera`): the pose
//! estimator reads the folder's images, looped, in place of the mock perception. Nothing is
//! scripted, so no interaction is announced or scored; the summary says how often the bridge
//! tracked someone.
//!
//! Services whose binaries are not installed next to `echoctl` are absent from the demo.

mod mission;

use std::collections::BTreeMap;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use echo_bus::config::loopback_mesh;
use echo_bus::observer::{self, Seen};
use echo_bus::shutdown::{self, Shutdown, ShutdownTrigger};
use echo_bus::stats::latency_summary;
use echo_bus::topics;
use echo_bus::{keys, Bus, BusArgs};
use echo_eval::live::ForecastScore;
use echo_launch::profile::{expand, Profile, ServiceSpec, Vars};
use echo_launch::{Group, Logs, ProcessSpec, Stopped};
use echo_msgs::{now_ns, ControlMode, Header, Interaction, InteractionIntent, ServiceStatus};

use super::{mock_perception, mock_robot};

/// Options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Robot id.
    #[arg(long, default_value = "tiago")]
    pub robot: String,
    /// What happens: a human–robot mission — a scenario file, or its name under
    /// `deploy/scenarios/` (mission, wave, handshake, handover, high-five, walk-up) — `watch` (the human–human forecaster watches the scripted partner; the robot
    /// holds) or `imitation` (the robot mirrors the partner through the retargeter).
    #[arg(long, default_value = "mission")]
    pub scenario: String,
    /// Replay person A of a real two-person capture as the partner (two BVH files, one clock);
    /// the robot plays person B.
    #[arg(long, num_args = 2, value_names = ["A_BVH", "B_BVH"])]
    pub capture: Option<Vec<PathBuf>>,
    /// With --capture: its description (the interaction type is read from it).
    #[arg(
        long,
        default_value = "Two people walk up to each other and shake hands."
    )]
    pub capture_prompt: String,
    /// The HRI checkpoint the forecaster runs in the human–robot scenarios.
    #[arg(long, default_value = "models/hri")]
    pub hri: PathBuf,
    /// Run for this many seconds (default: one pass of the mission, or 20 s for watch and
    /// imitation; the partner's script repeats).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Run every service as a task in this process (still one Zenoh session each, over loopback).
    #[arg(long)]
    pub single_process: bool,
    /// Keypoint format of the mock estimator: smpl24-points or coco17-pixels-depth.
    #[arg(long, default_value = "smpl24-points")]
    pub format: String,
    /// Add a bystander to the scene.
    #[arg(long)]
    pub bystander: bool,
    /// Run the pipeline on the pictures in this folder (PNG, JPEG; looped) through the pose
    /// estimator instead of the scripted partner: profile `camera` unless --profile names
    /// another; no interaction is scripted or scored.
    #[arg(
        long,
        value_name = "DIR",
        conflicts_with_all = ["scenario", "capture", "bystander", "format"]
    )]
    pub camera: Option<PathBuf>,
    /// Directory for the services' logs (default: a fresh temporary directory).
    #[arg(long)]
    pub log_dir: Option<PathBuf>,
    /// Write no recording, Foxglove file or GIF.
    #[arg(long)]
    pub no_recording: bool,
    /// Watch it live in a browser: serve the viewer (`echoctl view`) on --view-port.
    #[arg(long)]
    pub view: bool,
    /// The viewer's HTTP port.
    #[arg(long, default_value_t = 8080)]
    pub view_port: u16,
    /// Write the summary as JSON to this file too.
    #[arg(long)]
    pub summary_json: Option<PathBuf>,
    /// The placement profile that lists the demo's services and their flags.
    #[arg(long, default_value = "demo")]
    pub profile: String,
    /// The deployment directory holding the profiles.
    #[arg(long, env = "ECHO_DEPLOY_DIR", default_value = "deploy")]
    pub deploy_dir: PathBuf,
}

/// Services that exist as tasks in this binary (for `--single-process`).
const IN_PROCESS: &[&str] = &[
    "mock-robot",
    "perception-bridge",
    "forecaster",
    "retargeter",
    "safety",
    "mock-perception",
    "pose-estimator",
];

/// A profile's service, ready to start: its spec and its arguments with the scenario's values.
struct Planned {
    spec: ServiceSpec,
    args: Vec<String>,
}

#[derive(Default)]
struct KeyStats {
    count: u64,
    bytes: u64,
    ages_ms: Vec<f64>,
}

#[derive(Default)]
struct Observed {
    keys: BTreeMap<String, KeyStats>,
    status: BTreeMap<String, ServiceStatus>,
    partner_frames: u64,
    /// Skeleton frames with at least one tracked person.
    tracked_frames: u64,
    human_frames: u64,
    safety: Option<String>,
    forecasts: ForecastScore,
    /// Human–robot scenarios: what the robot did, per interaction.
    mission: Option<mission::MissionObserver>,
    /// Every bus message of the run (MCAP), for the Foxglove file and the GIF.
    recorder: Option<echo_record::Recorder<std::io::BufWriter<std::fs::File>>>,
    recording_errors: u64,
}

/// The services of a demo: processes (started and stopped by `echo_launch`), or tasks of this
/// process with `--single-process`.
struct Running {
    processes: Group,
    tasks: Vec<(String, ShutdownTrigger, tokio::task::JoinHandle<Result<()>>)>,
}

/// Run the demo.
pub async fn run(args: Args) -> Result<()> {
    let exe_dir = std::env::current_exe()?
        .parent()
        .map(Path::to_path_buf)
        .ok_or_else(|| anyhow!("cannot locate the echoctl binary's directory"))?;
    let setup = Setup::from_args(&args)?;
    let deploy = echo_assets::deploy_dir(&args.deploy_dir);
    let profile_name = match (&setup.camera, args.profile.as_str()) {
        (Some(_), "demo") => "camera",
        (_, name) => name,
    };
    let profile = Profile::load(profile_name, &deploy)?;
    let vars = setup.vars(&args);
    let mut available = vec![];
    let mut absent = vec![];
    for spec in &profile.services {
        let installed = match spec.program.as_str() {
            "echoctl" => true,
            _ if args.single_process => IN_PROCESS.contains(&spec.name.as_str()),
            program => exe_dir.join(program).is_file(),
        };
        match installed {
            true => available.push(Planned {
                args: expand(spec, &vars)?,
                spec: spec.clone(),
            }),
            false => absent.push(spec.name.as_str()),
        }
    }
    let log_dir = match &args.log_dir {
        Some(d) => d.clone(),
        None => std::env::temp_dir().join(format!("echo-demo-{}", std::process::id())),
    };
    std::fs::create_dir_all(&log_dir).with_context(|| format!("creating {}", log_dir.display()))?;

    // One slot per service, the demo's own session, and the viewer's.
    let mesh = loopback_mesh(&args.robot, available.len() + 2);
    let bus = Bus::open(&mesh[0], "echoctl-demo").await?;
    let robot = bus.robot().clone();
    let watch = bus.watch_alive(&keys::alive_all(&robot)).await?;
    let observed = Arc::new(Mutex::new(Observed::default()));
    let _sub = subscribe_all(&bus, observed.clone()).await?;

    println!(
        "echo demo: robot '{robot}', {} over Zenoh on loopback ({})",
        available
            .iter()
            .map(|p| p.spec.name.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        if args.single_process {
            "single process"
        } else {
            "one process per service"
        }
    );
    if !absent.is_empty() {
        println!(
            "not installed, so not part of this demo: {}",
            absent.join(", ")
        );
    }
    println!("logs: {}", log_dir.display());
    if let Some(c) = &setup.camera {
        println!(
            "camera: {} image(s) from {}, looped; nothing is scripted, so no interaction is scored",
            c.images,
            c.dir.display()
        );
    }
    if let Some(m) = &setup.mission {
        println!(
            "scenario '{}' ({:.0} s): {}",
            m.name,
            m.duration(),
            m.segments
                .iter()
                .map(|s| format!("{:?} at {:.1} s", s.interaction, s.start_s))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let mut running = Running {
        processes: Group::new(Duration::from_secs(5)),
        tasks: vec![],
    };
    for (i, planned) in available.iter().enumerate() {
        let net = &mesh[i + 1];
        let name = planned.spec.name.as_str();
        if args.single_process {
            // An `echoctl <verb>` service's arguments start with its verb.
            let skip = usize::from(planned.spec.program == "echoctl");
            let (trigger, handle) = start_task(name, net, planned.args[skip..].to_vec())?;
            running.tasks.push((name.to_string(), trigger, handle));
        } else {
            let spec = process_spec(&exe_dir, planned, net);
            running
                .processes
                .start(&spec, &Logs::in_dir(&log_dir, name))?;
        }
    }

    // The browser viewer follows the bus from its own session, in this process.
    let viewer = if args.view {
        let (trigger, stop) = shutdown::pair();
        let a = super::scene::ViewArgs {
            bus: mesh[available.len() + 1].clone(),
            port: args.view_port,
            host: "127.0.0.1".into(),
            hz: 15.0,
            assets: None,
            seconds: None,
        };
        Some((trigger, tokio::spawn(super::scene::serve_view(a, stop))))
    } else {
        None
    };

    let names: Vec<&str> = available.iter().map(|p| p.spec.name.as_str()).collect();
    let missing = watch
        .wait_for(robot.as_str(), &names, Duration::from_secs(20))
        .await;
    let mut failure = None;
    if !missing.is_empty() {
        failure = Some(format!(
            "services did not come up within 20 s: {}",
            missing.join(", ")
        ));
    }

    // Count from now: the rates in the summary are over the demo's own duration.
    let started = Instant::now();
    let mission_obs = setup
        .mission
        .clone()
        .map(|m| mission::MissionObserver::new(m, setup.t0_ns));
    let recording = log_dir.join("recording.mcap");
    let recorder = match args.no_recording {
        true => None,
        false => Some(echo_record::Recorder::new(std::io::BufWriter::new(
            std::fs::File::create(&recording)
                .with_context(|| format!("creating {}", recording.display()))?,
        ))?),
    };
    *observed.lock().unwrap_or_else(|e| e.into_inner()) = Observed {
        mission: mission_obs,
        recorder,
        ..Observed::default()
    };
    let mut stop = shutdown::on_signals();
    let prompt = bus.publisher(&topics::prompt(&robot)).await?;
    // One pass of the mission (from its start, which may lie ahead), or 20 s.
    let duration = args.duration.unwrap_or_else(|| match &setup.mission {
        Some(m) => {
            let ahead = (setup.t0_ns as f64 - now_ns() as f64) / 1e9;
            ahead.max(0.0) + m.duration() + 1.0
        }
        None => 20.0,
    });
    if failure.is_none() {
        let mut tick = tokio::time::interval(Duration::from_millis(500));
        let tty = std::io::stdout().is_terminal();
        let mut ticks = 0u64;
        while started.elapsed().as_secs_f64() < duration {
            tokio::select! {
                _ = tick.tick() => {}
                _ = stop.wait() => break,
            }
            let lost: Vec<&str> = names
                .iter()
                .copied()
                .filter(|s| !watch.is_alive(robot.as_str(), s))
                .collect();
            if !lost.is_empty() {
                failure = Some(format!(
                    "service(s) stopped during the demo: {}",
                    lost.join(", ")
                ));
                break;
            }
            if setup.imitation && ticks.is_multiple_of(2) {
                prompt
                    .put(InteractionIntent {
                        header: Header::new(robot.as_str(), "", ""),
                        text: "One person copies the other's arm movements like a mirror.".into(),
                        interaction: Interaction::Imitation,
                        mode: ControlMode::Imitation,
                    })
                    .await?;
            }
            // Human–robot: the current interaction is announced (its description conditions
            // the forecaster, its type lets the safety service allow gripper–hand contact at
            // low speed).
            if let (Some(m), true) = (&setup.mission, ticks.is_multiple_of(2)) {
                let t = (now_ns() as f64 - setup.t0_ns as f64) / 1e9;
                let t = t.max(0.0).rem_euclid(m.duration().max(1e-3));
                if let Some(seg) = m.segment_at(t) {
                    prompt
                        .put(InteractionIntent {
                            header: Header::new(robot.as_str(), "", ""),
                            text: seg.text.clone(),
                            interaction: seg.interaction,
                            mode: ControlMode::Forecast,
                        })
                        .await?;
                }
            }
            let line = status_line(
                started.elapsed().as_secs_f64(),
                &observed.lock().unwrap_or_else(|e| e.into_inner()),
            );
            if tty {
                print!("\r{line}");
                let _ = std::io::stdout().flush();
            } else if ticks.is_multiple_of(4) {
                println!("{line}");
            }
            ticks += 1;
        }
        println!();
    }
    let elapsed = started.elapsed().as_secs_f64();
    drop(watch);
    // Let the services publish their final status, then stop them.
    stop_all(running).await;
    if let Some((trigger, handle)) = viewer {
        trigger.trigger();
        match handle.await {
            Ok(Err(e)) => eprintln!("viewer: {e:#}"),
            Err(e) => eprintln!("viewer: {e}"),
            Ok(Ok(())) => {}
        }
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    let summary = summary(&observed.lock().unwrap_or_else(|e| e.into_inner()), elapsed);
    println!("{}", render_summary(&summary));
    let recorder = observed
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .recorder
        .take();
    if let Some(r) = recorder {
        match r.finish() {
            Ok(_) => pictures(&recording, &log_dir),
            Err(e) => eprintln!("the recording could not be finished: {e}"),
        }
    }
    if let Some(p) = &args.summary_json {
        std::fs::write(p, serde_json::to_vec_pretty(&summary)?)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    bus.close().await?;
    if let Some(f) = failure {
        anyhow::bail!("{f} (logs in {})", log_dir.display());
    }
    // Pictures need not show someone facing the robot: there a tracked person is the result.
    let (frames, what) = match setup.camera {
        Some(_) => ("tracked_frames", "tracked anyone in the pictures"),
        None => ("partner_frames", "reported a partner"),
    };
    if names.contains(&"perception-bridge") && summary["humans"][frames].as_u64() == Some(0) {
        anyhow::bail!(
            "the perception bridge never {what} (logs in {})",
            log_dir.display()
        );
    }
    Ok(())
}

/// The run as a Foxglove file and an animated GIF, from its recording.
fn pictures(recording: &Path, dir: &Path) {
    println!("recording: {}", recording.display());
    let foxglove = dir.join("foxglove.mcap");
    match echo_scene::foxglove::convert_recording(
        recording,
        &foxglove,
        &echo_scene::foxglove::FoxgloveOptions::default(),
    ) {
        Ok(_) => println!(
            "Foxglove (3D scene on /scene, open the file in Foxglove): {}",
            foxglove.display()
        ),
        Err(e) => eprintln!("no Foxglove file: {e}"),
    }
    let gif = dir.join("demo.gif");
    match echo_scene::render_recording(recording, &gif, &echo_scene::RenderOptions::default()) {
        Ok(s) => println!(
            "animation ({} frames, {:.1} s): {}",
            s.frames,
            s.duration_s,
            gif.display()
        ),
        Err(e) => eprintln!("no animation: {e}"),
    }
}

/// The command line of one service process: its program next to echoctl, its arguments (the
/// verb first for `echoctl <verb>`), then the network flags.
fn process_spec(exe_dir: &Path, planned: &Planned, net: &BusArgs) -> ProcessSpec {
    let mut argv = planned.args.clone();
    let verb = usize::from(planned.spec.program == "echoctl").min(argv.len());
    let rest = argv.split_off(verb);
    argv.extend(net.to_cli());
    argv.extend(rest);
    ProcessSpec::new(
        &planned.spec.name,
        exe_dir.join(&planned.spec.program),
        argv,
    )
}

/// What the demo plays, decided once before the services start.
struct Setup {
    /// Human–robot scenarios: the partner's mission (the HRI forecaster plans the robot).
    mission: Option<echo_sim::mission::Mission>,
    /// The robot mirrors the partner (retargeter plans).
    imitation: bool,
    /// Mission time 0 (ns since the UNIX epoch): a few seconds ahead, so the services are up
    /// before the partner moves.
    t0_ns: u64,
    /// `--camera`: the pictures the pose estimator reads.
    camera: Option<Pictures>,
}

/// A folder of pictures for the pose estimator.
struct Pictures {
    /// The folder, absolute (the services may run elsewhere).
    dir: PathBuf,
    /// How many images it holds.
    images: usize,
}

/// Seconds between launching the services and the partner's first move.
const LEAD_IN_S: f64 = 4.0;

impl Setup {
    fn from_args(args: &Args) -> Result<Setup> {
        let t0_ns = now_ns() + (LEAD_IN_S * 1e9) as u64;
        if let Some(dir) = &args.camera {
            let dir = std::fs::canonicalize(dir)
                .with_context(|| format!("--camera {}", dir.display()))?;
            let images = pose_estimator::image_files(&dir)?.len();
            return Ok(Setup {
                mission: None,
                imitation: false,
                t0_ns,
                camera: Some(Pictures { dir, images }),
            });
        }
        let (mission, imitation) = match (args.scenario.as_str(), &args.capture) {
            (_, Some(files)) => (
                mock_perception::mission_of(None, Some(files), &args.capture_prompt)?,
                false,
            ),
            ("watch", None) => (None, false),
            ("imitation", None) => (None, true),
            (s, None) => (
                Some(
                    echo_sim::mission::Mission::load(s, &echo_assets::deploy_dir(&args.deploy_dir))
                        .map_err(|e| anyhow!("--scenario: {e}; or watch, imitation"))?,
                ),
                false,
            ),
        };
        Ok(Setup {
            mission,
            imitation,
            t0_ns,
            camera: None,
        })
    }

    /// The values of the demo profiles' placeholders for this run.
    fn vars(&self, args: &Args) -> Vars {
        let human_robot = self.mission.is_some();
        let scenario = match (&args.capture, human_robot) {
            (_, false) => vec![],
            (Some(files), true) => {
                let mut v = vec!["--capture".to_string()];
                v.extend(files.iter().map(|f| f.display().to_string()));
                v.extend(["--capture-prompt".into(), args.capture_prompt.clone()]);
                v
            }
            // The file itself, absolute: the partner's process may run elsewhere.
            (None, true) => {
                let deploy = echo_assets::deploy_dir(&args.deploy_dir);
                let file = echo_sim::mission::scenario_path(&args.scenario, &deploy)
                    .ok()
                    .and_then(|p| std::fs::canonicalize(p).ok())
                    .map(|p| p.display().to_string())
                    .unwrap_or_else(|| args.scenario.clone());
                vec!["--scenario".into(), file]
            }
        };
        let t0 = match human_robot {
            true => vec!["--t0-ns".to_string(), self.t0_ns.to_string()],
            false => vec![],
        };
        Vars::new()
            .set("models", "models")
            // The HRI model plans for the robot; watch and imitation use the service's default.
            .set_all(
                "forecaster_model",
                human_robot
                    .then(|| args.hri.display().to_string())
                    .into_iter()
                    .collect(),
            )
            .set("format", args.format.clone())
            .set_all(
                "bystander",
                args.bystander
                    .then(|| "--bystander".to_string())
                    .into_iter()
                    .collect(),
            )
            .set_all("scenario", scenario)
            .set_all("t0", t0)
            .set_all(
                "images",
                self.camera
                    .iter()
                    .map(|c| c.dir.display().to_string())
                    .collect(),
            )
    }
}

type Task = (ShutdownTrigger, tokio::task::JoinHandle<Result<()>>);

fn start_task(name: &str, net: &BusArgs, flags: Vec<String>) -> Result<Task> {
    use clap::Parser;
    #[derive(Parser)]
    struct Wrap<T: clap::Args> {
        #[command(flatten)]
        inner: T,
    }
    let mut argv = vec![name.to_string()];
    argv.extend(net.to_cli());
    argv.extend(flags);
    let (trigger, stop): (ShutdownTrigger, Shutdown) = shutdown::pair();
    let handle = match name {
        "mock-robot" => {
            let a = Wrap::<mock_robot::Args>::try_parse_from(&argv)?.inner;
            tokio::spawn(mock_robot::serve(a, stop))
        }
        "mock-perception" => {
            let a = Wrap::<mock_perception::Args>::try_parse_from(&argv)?.inner;
            tokio::spawn(mock_perception::serve(a, stop))
        }
        "perception-bridge" => {
            let a = Wrap::<perception_bridge::Args>::try_parse_from(&argv)?.inner;
            tokio::spawn(perception_bridge::serve(a, stop))
        }
        "safety" => {
            let a = Wrap::<safety::Args>::try_parse_from(&argv)?.inner;
            tokio::spawn(safety::serve(a, stop))
        }
        "forecaster" => {
            let a = Wrap::<forecaster::Args>::try_parse_from(&argv)?.inner;
            tokio::spawn(forecaster::serve(a, stop))
        }
        "retargeter" => {
            let a = Wrap::<retargeter::Args>::try_parse_from(&argv)?.inner;
            tokio::spawn(retargeter::serve(a, stop))
        }
        "pose-estimator" => {
            let a = Wrap::<pose_estimator::Args>::try_parse_from(&argv)?.inner;
            tokio::spawn(pose_estimator::serve(a, stop))
        }
        other => anyhow::bail!("{other} cannot run in-process"),
    };
    Ok((trigger, handle))
}

/// Stop the services: tasks by their shutdown triggers (reverse start order, 5 s each),
/// processes by SIGTERM in reverse start order with one 5 s deadline before SIGKILL.
async fn stop_all(running: Running) {
    let Running {
        mut processes,
        tasks,
    } = running;
    for (name, trigger, handle) in tasks.into_iter().rev() {
        trigger.trigger();
        match tokio::time::timeout(Duration::from_secs(5), handle).await {
            Ok(Ok(Err(e))) => eprintln!("{name} failed: {e:#}"),
            Err(_) => eprintln!("{name} did not stop within 5 s"),
            _ => {}
        }
    }
    let stopped = tokio::task::spawn_blocking(move || processes.stop_all())
        .await
        .unwrap_or_default();
    for (name, how) in stopped {
        match how {
            Stopped::Killed => eprintln!("{name} did not stop within 5 s: killed"),
            Stopped::Exited(status) if !status.success() => {
                eprintln!("{name} exited with {status}")
            }
            Stopped::Exited(_) => {}
        }
    }
}

/// Every message on the robot's keys, typed (`echo_bus::observer`): recorded, counted, and
/// handed to the live scores and the mission's account.
async fn subscribe_all(
    bus: &Bus,
    observed: Arc<Mutex<Observed>>,
) -> Result<zenoh::pubsub::Subscriber<()>> {
    observer::observe(bus, &keys::robot_all(bus.robot()), move |ob| {
        let mut o = observed.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(r) = o.recorder.as_mut() {
            if r.write(&ob.key, ob.received_ns, &ob.payload).is_err() {
                o.recording_errors += 1;
            }
        }
        match ob.seen() {
            Some(Seen::ServiceStatus(st)) => {
                o.status.insert(st.service.clone(), st.clone());
            }
            Some(Seen::Safety(st)) => {
                let state = serde_json::to_value(st.state)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_string))
                    .unwrap_or_default();
                o.safety = Some(if st.reasons.is_empty() {
                    state
                } else {
                    format!("{state} ({})", st.reasons.join("; "))
                });
                if let Some(m) = o.mission.as_mut() {
                    m.on_safety(st);
                }
            }
            Some(Seen::Forecast(f)) => o.forecasts.on_forecast(f),
            Some(Seen::RobotState(js)) => {
                if let Some(m) = o.mission.as_mut() {
                    m.on_state(js);
                }
            }
            Some(Seen::Humans(h)) => {
                if let Some(m) = o.mission.as_mut() {
                    m.on_humans(h);
                }
                o.forecasts.on_humans(h);
                o.human_frames += 1;
                if !h.tracks.is_empty() {
                    o.tracked_frames += 1;
                }
                if h.partner_id.is_some() {
                    o.partner_frames += 1;
                }
            }
            _ => {}
        }
        let age = ob.age_ms();
        let ks = o.keys.entry(ob.short_key().to_string()).or_default();
        ks.count += 1;
        ks.bytes += ob.payload.len() as u64;
        if let Some(age) = age {
            if ks.ages_ms.len() < 100_000 {
                ks.ages_ms.push(age);
            }
        }
    })
    .await
}

fn status_line(t: f64, o: &Observed) -> String {
    let rate = |k: &str| {
        o.keys
            .get(k)
            .map(|s| s.count as f64 / t.max(1e-3))
            .unwrap_or(0.0)
    };
    let (rejected, dropped) = totals(o);
    let latency = o
        .status
        .get("perception-bridge")
        .and_then(|s| s.latency.as_ref())
        .map(|l| format!(" bridge {:.2} ms", l.median_ms))
        .unwrap_or_default();
    let safety = o
        .safety
        .as_ref()
        .map(|s| format!("  safety {s}"))
        .unwrap_or_default();
    let forecast = if o.keys.contains_key("forecast") {
        let inf = latency_summary(o.forecasts.inference_ms.iter().copied())
            .map(|l| format!(" inference {:.1} ms", l.median_ms))
            .unwrap_or_default();
        let err = o
            .forecasts
            .means()
            .map(|(m, h, _)| format!(", 1.0 s error {m:.0} mm (hold {h:.0})"))
            .unwrap_or_default();
        format!("  forecast {:4.1} Hz{inf}{err}", rate("forecast"))
    } else {
        String::new()
    };
    format!(
        "t={t:5.1}s  keypoints {:5.1} Hz  humans {:5.1} Hz (partner {:>3})  robot/state {:5.1} Hz{latency}{forecast}{safety}  rejected {rejected}  dropped {dropped}   ",
        rate("perception/raw"),
        rate("humans"),
        o.partner_frames,
        rate("robot/state"),
    )
}

fn totals(o: &Observed) -> (u64, u64) {
    let sum = |m: fn(&ServiceStatus) -> &BTreeMap<String, u64>| -> u64 {
        o.status.values().flat_map(|s| m(s).values()).sum()
    };
    (sum(|s| &s.rejected), sum(|s| &s.dropped))
}

fn summary(o: &Observed, elapsed: f64) -> serde_json::Value {
    let mut keys_json = serde_json::Map::new();
    for (k, s) in &o.keys {
        let lat = latency_summary(s.ages_ms.iter().copied());
        keys_json.insert(
            k.clone(),
            serde_json::json!({
                "messages": s.count,
                "rate_hz": s.count as f64 / elapsed.max(1e-3),
                "bytes": s.bytes,
                "age_median_ms": lat.map(|l| l.median_ms),
                "age_p99_ms": lat.map(|l| l.p99_ms),
            }),
        );
    }
    let mut services = serde_json::Map::new();
    for (name, s) in &o.status {
        services.insert(
            name.clone(),
            serde_json::json!({
                "rejected": s.rejected,
                "dropped": s.dropped,
                "latency": s.latency,
                "last_error": s.last_error,
            }),
        );
    }
    let (rejected, dropped) = totals(o);
    let interactions = o.mission.as_ref().map(|m| m.reports());
    let forecast = o.forecasts.means().map(|(m, h, n)| {
        let inf = latency_summary(o.forecasts.inference_ms.iter().copied());
        serde_json::json!({
            "scored": n,
            "error_1s_mm": m,
            "hold_error_1s_mm": h,
            "inference_median_ms": inf.map(|l| l.median_ms),
            "inference_p99_ms": inf.map(|l| l.p99_ms),
        })
    });
    serde_json::json!({
        "duration_s": elapsed,
        "forecast": forecast,
        "scenario": o.mission.as_ref().map(|m| m.mission.name.clone()),
        "interactions": interactions,
        "keys": keys_json,
        "services": services,
        "humans": {
            "frames": o.human_frames,
            "tracked_frames": o.tracked_frames,
            "partner_frames": o.partner_frames,
        },
        "safety_state": o.safety,
        "rejected_total": rejected,
        "dropped_total": dropped,
    })
}

fn render_summary(s: &serde_json::Value) -> String {
    let mut out = String::new();
    out.push_str(&format!(
        "\nsummary after {:.1} s\n{:<28} {:>8} {:>8} {:>12} {:>12}\n",
        s["duration_s"].as_f64().unwrap_or(0.0),
        "key (echo/<robot>/…)",
        "msgs",
        "Hz",
        "age med ms",
        "age p99 ms"
    ));
    if let Some(keys) = s["keys"].as_object() {
        for (k, v) in keys {
            let f = |x: &serde_json::Value| {
                x.as_f64()
                    .map(|x| format!("{x:.2}"))
                    .unwrap_or_else(|| "-".into())
            };
            out.push_str(&format!(
                "{:<28} {:>8} {:>8.1} {:>12} {:>12}\n",
                k,
                v["messages"].as_u64().unwrap_or(0),
                v["rate_hz"].as_f64().unwrap_or(0.0),
                f(&v["age_median_ms"]),
                f(&v["age_p99_ms"]),
            ));
        }
    }
    if let Some(svcs) = s["services"].as_object() {
        for (name, v) in svcs {
            let lat = v["latency"]
                .as_object()
                .map(|l| {
                    format!(
                        " processing median {:.3} ms p99 {:.3} ms",
                        l["median_ms"].as_f64().unwrap_or(0.0),
                        l["p99_ms"].as_f64().unwrap_or(0.0)
                    )
                })
                .unwrap_or_default();
            let total = |x: &serde_json::Value| {
                x.as_object()
                    .map(|m| m.values().filter_map(|v| v.as_u64()).sum::<u64>())
                    .unwrap_or(0)
            };
            out.push_str(&format!(
                "{name}: rejected {} dropped {}{lat}\n",
                total(&v["rejected"]),
                total(&v["dropped"])
            ));
        }
    }
    if let Some(f) = s["forecast"].as_object() {
        out.push_str(&format!(
            "forecast: {} scored at 1.0 s, mean joint error {:.0} mm (holding the last pose: {:.0} mm); inference median {:.2} ms p99 {:.2} ms\n",
            f["scored"],
            f["error_1s_mm"].as_f64().unwrap_or(0.0),
            f["hold_error_1s_mm"].as_f64().unwrap_or(0.0),
            f["inference_median_ms"].as_f64().unwrap_or(0.0),
            f["inference_p99_ms"].as_f64().unwrap_or(0.0),
        ));
    }
    if let Ok(reports) = serde_json::from_value::<Vec<echo_eval::behaviour::InteractionReport>>(
        s["interactions"].clone(),
    ) {
        out.push_str(&mission::render(&reports));
    }
    if let Some(st) = s["safety_state"].as_str() {
        out.push_str(&format!("safety: final state {st}\n"));
    }
    out.push_str(&format!(
        "someone tracked in {}, a partner in {} of {} skeleton frames; {} inputs rejected, {} \
         dropped in total",
        s["humans"]["tracked_frames"],
        s["humans"]["partner_frames"],
        s["humans"]["frames"],
        s["rejected_total"],
        s["dropped_total"]
    ));
    out
}
