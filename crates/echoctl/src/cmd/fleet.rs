//! A fleet under load, for `echoctl bench e2e` and `echoctl soak`: the `fleet` placement profile
//! (`deploy/profiles/fleet.json`) started as one perception bridge per robot, one forecaster
//! serving every robot (batched), a safety service per robot that has one, all as separate
//! processes with Zenoh peer sessions on loopback. This process plays the
//! robots' cameras and joint encoders (pose-estimator frames at 15 Hz stamped when sent, joint
//! states at 50 Hz) and times what comes back:
//!
//! - perception → skeletons: a `humans` arrival − when the robot's latest frame was sent (the
//!   bridge resamples to the model-rate grid, so its stamps are grid times, not frame times);
//! - perception → forecast: a `forecast` arrival − when that robot's latest frame was sent, and
//!   the model's own `inference_ms` from the message, so overhead = latency − inference;
//! - forecast → command: the safety service's next command after the forecast arrived (its
//!   control loop runs at a fixed 50 Hz, so this includes waiting for the next cycle).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use echo_bus::config::loopback_mesh;
use echo_bus::stats::{latency_summary, process_rss_mib};
use echo_bus::{keys, topics, Bus, BusArgs, RobotId};
use echo_launch::profile::{expand, Profile, Vars};
use echo_launch::{Group, Logs, ProcessSpec};
use echo_msgs::{now_ns, ControlMode, Header, InteractionIntent, JointState, KeypointFrame};
use echo_sim::perception::MockPerceptionConfig;
use echo_sim::scenario::bridge_inputs;

/// What to run.
#[derive(Debug, Clone)]
pub struct FleetOptions {
    /// Robots served by the one forecaster.
    pub robots: usize,
    /// Robots (the first ones) that also get a safety service.
    pub with_safety: usize,
    /// Measured seconds (after warm-up).
    pub seconds: f64,
    /// Forecaster checkpoint (an HRI model makes robot plans, so commands follow).
    pub model: PathBuf,
    /// Forecaster backend.
    pub backend: forecaster::BackendKind,
    /// Where the services' logs go (the caller removes them once it has judged the run).
    pub log_dir: PathBuf,
    /// Sample every child's resident memory this often (soak).
    pub rss_every: Option<Duration>,
}

/// Latency samples (ms) and counts from one run.
#[derive(Debug, Default, Clone, serde::Serialize)]
pub struct FleetReport {
    /// Robots served.
    pub robots: usize,
    /// Frames sent (all robots).
    pub frames_sent: u64,
    /// Forecasts received (all robots).
    pub forecasts: u64,
    /// Frames whose forecast did not arrive within the safety's plan deadline (200 ms).
    pub missed_deadlines: u64,
    /// Perception → skeletons, ms.
    pub to_humans_ms: Vec<f64>,
    /// Perception → forecast, ms.
    pub to_forecast_ms: Vec<f64>,
    /// Model inference per forecast, ms.
    pub inference_ms: Vec<f64>,
    /// Per forecast: its latency minus its own inference time, ms.
    pub overhead_ms: Vec<f64>,
    /// Forecast → next command of the same robot, ms.
    pub forecast_to_command_ms: Vec<f64>,
    /// Perception → that command, ms.
    pub to_command_ms: Vec<f64>,
    /// Resident memory per process over time: (seconds since start, MiB).
    pub rss_mib: BTreeMap<String, Vec<(f64, f64)>>,
}

/// Median and p99 of `v` ("–" when empty).
pub fn med_p99(v: &[f64]) -> String {
    match latency_summary(v.iter().copied()) {
        Some(s) => format!("{:.2} / {:.2}", s.median_ms, s.p99_ms),
        None => "–".into(),
    }
}

/// The services of the `fleet` placement profile, with the run's values filled in.
struct FleetProfile {
    profile: Profile,
    vars: Vars,
}

impl FleetProfile {
    fn load(opts: &FleetOptions, ids: &[RobotId]) -> Result<FleetProfile> {
        let deploy = echo_assets::deploy_dir(Path::new("deploy"));
        let profile = Profile::load("fleet", &deploy)?;
        let serve: Vec<&str> = ids.iter().skip(1).map(|r| r.as_str()).collect();
        let vars = Vars::new()
            .set("model", opts.model.display().to_string())
            .set("backend", opts.backend.to_string())
            .set_all(
                "serve",
                match serve.is_empty() {
                    true => vec![],
                    false => vec![serve.join(",")],
                },
            );
        Ok(FleetProfile { profile, vars })
    }

    /// Start the profile's service `name` as `label` with the network flags `net`.
    fn spawn(
        &self,
        children: &mut Group,
        exe_dir: &Path,
        log_dir: &Path,
        name: &str,
        label: &str,
        net: Vec<String>,
    ) -> Result<()> {
        let spec = self
            .profile
            .service(name)
            .ok_or_else(|| anyhow!("profile fleet has no service {name}"))?;
        let mut args = expand(spec, &self.vars)?;
        args.extend(net);
        let spec = ProcessSpec::new(label, exe_dir.join(&spec.program), args);
        children.start(&spec, &Logs::in_dir(log_dir, label))?;
        Ok(())
    }
}

/// The one field of a forecast the load generator reads.
#[derive(serde::Deserialize)]
struct Inference {
    inference_ms: f64,
}

/// Arrival times (ns) per robot, in arrival order.
#[derive(Default)]
struct Arrivals {
    sent: Vec<Vec<u64>>,
    humans: Vec<(usize, u64)>,
    /// (robot, arrival, inference ms).
    forecasts: Vec<(usize, u64, f64)>,
    commands: Vec<Vec<u64>>,
}

/// Start the fleet, load it for `seconds` after a warm-up, and return what was measured.
pub async fn run(opts: &FleetOptions) -> Result<FleetReport> {
    let exe_dir = std::env::current_exe()?
        .parent()
        .map(Path::to_path_buf)
        .ok_or_else(|| anyhow!("cannot locate the echoctl binary's directory"))?;
    std::fs::create_dir_all(&opts.log_dir)?;
    let ids: Vec<RobotId> = (0..opts.robots)
        .map(|i| RobotId::new(&format!("fleet{i:02}")))
        .collect::<std::result::Result<_, _>>()?;
    let n_proc = opts.robots + 1 + opts.with_safety.min(opts.robots);
    let mesh = loopback_mesh(ids[0].as_str(), n_proc + 1);
    let net = |slot: usize, robot: &RobotId| -> Vec<String> {
        let mut a: BusArgs = mesh[slot].clone();
        a.robot = robot.to_string();
        a.to_cli()
    };
    let fleet = FleetProfile::load(opts, &ids)?;
    let mut children = Group::new(Duration::from_secs(5));
    let mut slot = 1;
    let log_dir = &opts.log_dir;
    for r in &ids {
        let label = format!("bridge-{r}");
        fleet.spawn(
            &mut children,
            &exe_dir,
            log_dir,
            "perception-bridge",
            &label,
            net(slot, r),
        )?;
        slot += 1;
    }
    for r in ids.iter().take(opts.with_safety) {
        let label = format!("safety-{r}");
        fleet.spawn(
            &mut children,
            &exe_dir,
            log_dir,
            "safety",
            &label,
            net(slot, r),
        )?;
        slot += 1;
    }
    let fc = net(slot, &ids[0]);
    fleet.spawn(
        &mut children,
        &exe_dir,
        log_dir,
        "forecaster",
        "forecaster",
        fc,
    )?;

    let mut own = mesh[0].clone();
    own.robot = ids[0].to_string();
    let bus = Bus::open(&own, "fleet-load").await?;
    let watch = bus.watch_alive(&keys::alive_fleet()).await?;
    for r in &ids {
        let mut want = vec!["perception-bridge", "forecaster"];
        if ids.iter().position(|x| x == r).unwrap_or(0) < opts.with_safety {
            want.push("safety");
        }
        let missing = watch
            .wait_for(r.as_str(), &want, Duration::from_secs(120))
            .await;
        anyhow::ensure!(
            missing.is_empty(),
            "{r}: not alive: {missing:?} (logs in {})",
            opts.log_dir.display()
        );
    }

    // What comes back, timed in the subscriber callbacks.
    let arrivals = Arc::new(Mutex::new(Arrivals {
        sent: vec![vec![]; opts.robots],
        commands: vec![vec![]; opts.robots],
        ..Default::default()
    }));
    let measuring = Arc::new(std::sync::atomic::AtomicBool::new(false));
    // Each arrival is timed in the subscriber callback and recorded only while measuring.
    type Record = Box<dyn Fn(&mut Arrivals, u64, &[u8]) + Send + Sync>;
    let mut subs = vec![];
    for (i, r) in ids.iter().enumerate() {
        let mut wanted: Vec<(String, Record)> = vec![
            (
                keys::humans(r),
                Box::new(move |a, t, _| a.humans.push((i, t))),
            ),
            (
                keys::forecast(r),
                Box::new(move |a, t, b| {
                    if let Ok(f) = serde_json::from_slice::<Inference>(b) {
                        a.forecasts.push((i, t, f.inference_ms));
                    }
                }),
            ),
        ];
        if i < opts.with_safety {
            wanted.push((
                keys::command(r),
                Box::new(move |a, t, _| a.commands[i].push(t)),
            ));
        }
        for (key, record) in wanted {
            let (a, m) = (arrivals.clone(), measuring.clone());
            subs.push(
                bus.session()
                    .declare_subscriber(key)
                    .callback(move |s| {
                        let t = now_ns();
                        if m.load(std::sync::atomic::Ordering::Relaxed) {
                            let bytes = s.payload().to_bytes();
                            record(&mut a.lock().unwrap_or_else(|e| e.into_inner()), t, &bytes);
                        }
                    })
                    .await
                    .map_err(|e| anyhow!("{e}"))?,
            );
        }
    }

    // The robots' cameras and encoders.
    let script = bridge_inputs(900, MockPerceptionConfig::default());
    let mut raw_pubs = vec![];
    let mut state_pubs = vec![];
    let mut prompt_pubs = vec![];
    for r in &ids {
        raw_pubs.push(bus.publisher(&topics::perception_raw(r)).await?);
        state_pubs.push(bus.publisher(&topics::robot_state(r)).await?);
        prompt_pubs.push(bus.publisher(&topics::prompt(r)).await?);
    }
    let frame_of = |k: usize, r: &RobotId| -> (JointState, KeypointFrame) {
        let (mut js, mut f) = script[k % script.len()].clone();
        js.header.robot_id = r.to_string();
        f.header.robot_id = r.to_string();
        (js, f)
    };
    let warmup = Duration::from_secs(4);
    let started = Instant::now();
    let total = warmup + Duration::from_secs_f64(opts.seconds);
    let mut frame_tick = tokio::time::interval(Duration::from_secs_f64(1.0 / 15.0));
    let mut state_tick = tokio::time::interval(Duration::from_millis(20));
    let mut rss_tick = tokio::time::interval(opts.rss_every.unwrap_or(Duration::from_secs(3600)));
    frame_tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    state_tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut report = FleetReport {
        robots: opts.robots,
        ..Default::default()
    };
    let mut k = 0usize;
    let mut measuring_since = None;
    while started.elapsed() < total {
        if measuring_since.is_none() && started.elapsed() >= warmup {
            measuring.store(true, std::sync::atomic::Ordering::Relaxed);
            measuring_since = Some(now_ns());
        }
        tokio::select! {
            _ = frame_tick.tick() => {
                k += 1;
                for (i, r) in ids.iter().enumerate() {
                    let (_, mut f) = frame_of(k, r);
                    f.header.stamp_ns = now_ns();
                    let sent = f.header.stamp_ns;
                    raw_pubs[i].put(f).await?;
                    arrivals.lock().unwrap_or_else(|e| e.into_inner()).sent[i].push(sent);
                    if measuring_since.is_some() {
                        report.frames_sent += 1;
                    }
                    if k % 15 == 1 {
                        prompt_pubs[i].put(InteractionIntent {
                            header: Header::new(r.as_str(), "", ""),
                            text: "One person waves, and the other waves back.".into(),
                            interaction: echo_msgs::Interaction::Wave,
                            mode: ControlMode::Forecast,
                        }).await?;
                    }
                }
            }
            _ = state_tick.tick() => {
                for (i, r) in ids.iter().enumerate() {
                    let (mut js, _) = frame_of(k, r);
                    js.header.stamp_ns = now_ns();
                    state_pubs[i].put(js).await?;
                }
            }
            _ = rss_tick.tick(), if opts.rss_every.is_some() => {
                let t = started.elapsed().as_secs_f64();
                for (label, pid) in children.pids() {
                    if let Some(m) = process_rss_mib(pid) {
                        report.rss_mib.entry(label).or_default().push((t, m));
                    }
                }
            }
        }
    }
    measuring.store(false, std::sync::atomic::Ordering::Relaxed);
    if let Some(label) = children.first_ended() {
        anyhow::bail!(
            "{label} exited during the run (log in {})",
            opts.log_dir.display()
        );
    }
    drop(subs);
    drop(children);
    let a = std::mem::take(&mut *arrivals.lock().unwrap_or_else(|e| e.into_inner()));
    // Latency from the robot's latest frame sent before an arrival.
    let since_frame = |i: usize, t: u64| -> Option<u64> {
        let sent = &a.sent[i];
        let k = sent.partition_point(|s| *s <= t);
        (k > 0).then(|| t - sent[k - 1])
    };
    report.to_humans_ms = a
        .humans
        .iter()
        .filter_map(|(i, t)| since_frame(*i, *t))
        .map(|d| d as f64 / 1e6)
        .collect();
    report.forecasts = a.forecasts.len() as u64;
    for &(i, t, inference) in &a.forecasts {
        let Some(d) = since_frame(i, t) else {
            continue;
        };
        let lat = d as f64 / 1e6;
        report.to_forecast_ms.push(lat);
        report.inference_ms.push(inference);
        report.overhead_ms.push(lat - inference);
        // The robot's first command at or after the forecast arrived.
        let cmds = &a.commands[i];
        if let Some(tc) = cmds.get(cmds.partition_point(|c| *c < t)) {
            report.forecast_to_command_ms.push((tc - t) as f64 / 1e6);
            report.to_command_ms.push(lat + (tc - t) as f64 / 1e6);
        }
    }
    // A missed deadline: a robot went longer than the safety's plan deadline (200 ms) without a
    // forecast, i.e. the safety service would have started to stop it.
    let mut per_robot: Vec<Vec<u64>> = vec![vec![]; opts.robots];
    for (i, t, _) in &a.forecasts {
        per_robot[*i].push(*t);
    }
    report.missed_deadlines = per_robot
        .iter_mut()
        .map(|ts| {
            ts.sort_unstable();
            ts.windows(2).filter(|w| w[1] - w[0] > 200_000_000).count() as u64
        })
        .sum();
    bus.close().await?;
    Ok(report)
}
