//! System-test harness: starts Echo services as real OS processes, each with its own Zenoh
//! peer session on free loopback ports (explicit endpoints, no multicast), waits for their
//! liveliness tokens, and always stops them (SIGTERM, then SIGKILL: `echo_launch`) when dropped.
//! The pipeline's services start as the placement profiles describe them
//! ([`Harness::spawn_service`]: what `echoctl up` and `echoctl demo` run); a test's own stimuli
//! and tools (the mock perception's clip, a recorder, a replay) with the flags the test needs.

pub mod attack;
pub mod netns;

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context, Result};
use echo_bus::config::loopback_mesh;
use echo_bus::{keys, Bus, BusArgs};
use echo_launch::profile::{expand, Profile, Vars};
use echo_launch::{Group, Logs, ProcessSpec};

/// The repository root (profiles, scenarios, shipped models).
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The values the system tests fill into the placement profiles' placeholders: the shipped
/// models and deployment files of this checkout, the HRI model as the demo's forecaster, and no
/// scenario, bystander or start time (the tests start their own partner).
pub fn profile_vars() -> Vars {
    let root = repo();
    Vars::new()
        .set("models", root.join("models").display().to_string())
        .set("deploy", root.join("deploy").display().to_string())
        .set(
            "forecaster_model",
            root.join("models/hri").display().to_string(),
        )
        .set("format", "smpl24-points")
        .set_all("bystander", vec![])
        .set_all("scenario", vec![])
        .set_all("t0", vec![])
}

/// Directory holding the workspace's binaries for the profile the tests were built with.
pub fn bin_dir() -> PathBuf {
    // target/<profile>/deps/<test-exe> → target/<profile>
    let exe = std::env::current_exe().expect("test executable path");
    exe.parent()
        .and_then(Path::parent)
        .map(Path::to_path_buf)
        .expect("target directory")
}

/// Path of a workspace binary; a clear error if it was not built.
pub fn binary(name: &str) -> Result<PathBuf> {
    let p = bin_dir().join(name);
    if !p.is_file() {
        bail!(
            "{} is missing: build the workspace binaries first (cargo build --workspace --bins, \
             or run the tests with `cargo test --workspace`)",
            p.display()
        );
    }
    Ok(p)
}

/// A set of service processes on one loopback mesh, started and stopped by `echo_launch`.
pub struct Harness {
    robot: String,
    mesh: Vec<BusArgs>,
    next: usize,
    children: Group,
    log_dir: PathBuf,
}

impl Harness {
    /// A mesh with room for `services` processes plus the test's own session.
    pub fn new(robot: &str, services: usize) -> Result<Harness> {
        let log_dir = std::env::temp_dir().join(format!(
            "echo-system-{}-{}",
            std::process::id(),
            echo_msgs::now_ns() % 1_000_000_000
        ));
        std::fs::create_dir_all(&log_dir)?;
        Ok(Harness {
            robot: robot.to_string(),
            mesh: loopback_mesh(robot, services + 1),
            next: 1,
            children: Group::new(Duration::from_secs(3)),
            log_dir,
        })
    }

    /// Network flags for the test's own session.
    pub fn test_args(&self) -> BusArgs {
        self.mesh[0].clone()
    }

    /// Open the test's own bus session.
    pub async fn bus(&self, name: &str) -> Result<Bus> {
        Bus::open(&self.test_args(), name).await
    }

    /// Start `program` (a workspace binary) with `args`, on the next mesh slot; logs go to
    /// `<log_dir>/<label>.log`.
    pub fn spawn(&mut self, label: &str, program: &str, args: &[&str]) -> Result<()> {
        let net = self
            .mesh
            .get(self.next)
            .cloned()
            .with_context(|| format!("no mesh slot left for {label}"))?;
        self.next += 1;
        let mut all: Vec<String> = args.iter().map(|a| a.to_string()).collect();
        all.extend(net.to_cli());
        let all: Vec<&str> = all.iter().map(String::as_str).collect();
        self.spawn_raw(label, program, &all)
    }

    /// Start the service `service` of placement profile `profile` (`deploy/profiles/<profile>.json`,
    /// the description `echoctl up` and `echoctl demo` start) with its placeholders filled from
    /// `vars` and `extra` arguments appended, on the next mesh slot; labelled by its name.
    pub fn spawn_service(
        &mut self,
        profile: &str,
        service: &str,
        vars: &Vars,
        extra: &[&str],
    ) -> Result<()> {
        let p = Profile::load(profile, &repo().join("deploy"))?;
        let spec = p
            .service(service)
            .with_context(|| format!("profile {profile} has no service {service}"))?;
        let mut args = expand(spec, vars)?;
        args.extend(extra.iter().map(|a| a.to_string()));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        self.spawn(&spec.name, &spec.program, &args)
    }

    /// Start the services `names` of placement profile `profile`, in that order, with the
    /// harness's placeholder values ([`profile_vars`]) and no extra arguments.
    pub fn spawn_services(&mut self, profile: &str, names: &[&str]) -> Result<()> {
        let vars = profile_vars();
        for n in names {
            self.spawn_service(profile, n, &vars, &[])?;
        }
        Ok(())
    }

    /// Start `program` with exactly `args` (no mesh flags), e.g. a router with its own endpoints.
    pub fn spawn_raw(&mut self, label: &str, program: &str, args: &[&str]) -> Result<()> {
        self.start(ProcessSpec::new(
            label,
            binary(program)?,
            echo_launch::args(args),
        ))
    }

    /// Start `program` with exactly `args` inside the network namespace `netns`.
    pub fn spawn_in(
        &mut self,
        label: &str,
        netns: &str,
        program: &str,
        args: &[&str],
    ) -> Result<()> {
        let spec = ProcessSpec::new(label, binary(program)?, echo_launch::args(args))
            .wrapped(&["ip", "netns", "exec", netns]);
        self.start(spec)
    }

    fn start(&mut self, mut spec: ProcessSpec) -> Result<()> {
        spec.env = vec![("RUST_LOG".into(), "info,zenoh=warn".into())];
        let logs = Logs::in_dir(&self.log_dir, &spec.label);
        self.children.start(&spec, &logs)?;
        Ok(())
    }

    /// Wait until every service in `services` has its liveliness token, or fail naming the
    /// ones missing (with the tail of their logs).
    pub async fn wait_alive(
        &mut self,
        bus: &Bus,
        services: &[&str],
        timeout: Duration,
    ) -> Result<()> {
        let watch = bus.watch_alive(&keys::alive_all(bus.robot())).await?;
        let missing = watch.wait_for(&self.robot, services, timeout).await;
        if !missing.is_empty() {
            let mut msg = format!("not alive after {timeout:?}: {}", missing.join(", "));
            for m in &missing {
                msg.push_str(&format!("\n--- {m} log:\n{}", self.log_tail(m)));
            }
            bail!(msg);
        }
        Ok(())
    }

    /// Process id of a started process.
    pub fn pid(&self, label: &str) -> Option<u32> {
        self.children.get(label).map(|p| p.id())
    }

    /// Kill a process at once (SIGKILL: a crash, no clean shutdown).
    pub fn kill(&mut self, label: &str) {
        if let Some(mut p) = self.children.take(label) {
            p.kill();
        }
    }

    /// Exit status of a process that has ended (None while it runs).
    pub fn exit_status(&mut self, label: &str) -> Option<std::process::ExitStatus> {
        self.children.get_mut(label).and_then(|p| p.try_status())
    }

    /// Whether a started process is still running.
    pub fn is_running(&mut self, label: &str) -> bool {
        self.children.get_mut(label).is_some_and(|p| p.is_running())
    }

    /// Directory of the processes' logs (`<label>.log`).
    pub fn log_dir(&self) -> &Path {
        &self.log_dir
    }

    /// The last lines of a service's log.
    pub fn log_tail(&self, label: &str) -> String {
        let text =
            std::fs::read_to_string(self.log_dir.join(format!("{label}.log"))).unwrap_or_default();
        let lines: Vec<&str> = text.lines().collect();
        lines[lines.len().saturating_sub(30)..].join("\n")
    }

    /// Stop one process: SIGTERM, then SIGKILL after `grace`. Returns whether it exited cleanly.
    pub fn stop(&mut self, label: &str, grace: Duration) -> bool {
        self.children
            .take(label)
            .is_some_and(|mut p| p.terminate(grace).is_clean())
    }
}

impl Drop for Harness {
    /// Stops every process; removes the log directory unless the test is panicking (a failed
    /// assertion) or `ECHO_KEEP_TEST_LOGS=1` is set, so passing runs leave nothing behind.
    fn drop(&mut self) {
        self.children.stop_all();
        let keep = std::thread::panicking()
            || std::env::var("ECHO_KEEP_TEST_LOGS").is_ok_and(|v| v == "1");
        if keep {
            eprintln!("service logs kept in {}", self.log_dir.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.log_dir);
        }
    }
}

/// Check every point of a command against the robot's hard limits (position, velocity);
/// returns the number of points checked and appends what is violated to `violations`.
pub fn check_command_limits(
    model: &echo_robot::RobotModel,
    cmd: &echo_msgs::RobotCommand,
    violations: &mut Vec<String>,
) -> usize {
    let mut points = 0;
    for tr in &cmd.trajectories {
        for p in &tr.points {
            points += 1;
            for (k, n) in tr.joint_names.iter().enumerate() {
                let Some(l) = model.limits(n) else {
                    violations.push(format!("unknown joint {n}"));
                    continue;
                };
                let (x, v) = (p.positions[k], p.velocities[k]);
                if x < l.lower - 1e-9 || x > l.upper + 1e-9 {
                    violations.push(format!("{n} at {x:.4} outside its limits"));
                }
                if v.abs() > l.velocity * (1.0 + 1e-6) {
                    violations.push(format!("{n} at {v:.4}/s over its limit"));
                }
            }
        }
    }
    points
}

/// The services of the human–robot pipeline the demo's scenarios run (their liveliness names).
pub const HRI_SERVICES: [&str; 4] = ["mock-robot", "perception-bridge", "forecaster", "safety"];

/// Start the human–robot pipeline as processes, as the `demo` profile describes it: the
/// simulated robot, the perception bridge, the forecaster with the shipped HRI model
/// (`models/hri`) and the safety service requiring the robot ([`HRI_SERVICES`]; the partner,
/// mock perception, is started by the test).
pub fn spawn_hri_pipeline(h: &mut Harness) -> Result<()> {
    h.spawn_services("demo", &HRI_SERVICES)
}

/// The human–robot pipeline started ([`spawn_hri_pipeline`]) on a fresh mesh for `robot`, the
/// test's own bus session, its taps, and every service alive: what a human–robot system test
/// starts from (the partner is started by the test).
pub async fn start_hri_pipeline(robot: &str) -> Result<(Harness, Bus, HriTaps)> {
    let mut h = Harness::new(robot, 5)?;
    spawn_hri_pipeline(&mut h)?;
    let bus = h.bus("system-test").await?;
    let taps = HriTaps::open(&bus).await?;
    h.wait_alive(&bus, &HRI_SERVICES, Duration::from_secs(60))
        .await?;
    Ok((h, bus, taps))
}

/// Announce a mission segment's interaction to the robot (text, type, forecast mode).
pub async fn announce(
    prompt: &echo_bus::Publisher<echo_msgs::InteractionIntent>,
    robot: &str,
    seg: &echo_sim::mission::Segment,
) -> Result<()> {
    prompt
        .put(echo_msgs::InteractionIntent {
            header: echo_msgs::Header::new(robot, "", ""),
            text: seg.text.clone(),
            interaction: seg.interaction,
            mode: echo_msgs::ControlMode::Forecast,
        })
        .await?;
    Ok(())
}

/// A test's taps on the human–robot pipeline: the prompt it announces on and the inboxes it
/// reads (joint states, people, commands, safety status, forecasts).
pub struct HriTaps {
    /// Announces the interaction.
    pub prompt: echo_bus::Publisher<echo_msgs::InteractionIntent>,
    /// The robot's measured joints.
    pub states: echo_bus::Inbox<echo_msgs::JointState>,
    /// The people the bridge tracks.
    pub humans: echo_bus::Inbox<echo_msgs::HumanSkeletons>,
    /// The safety service's commands.
    pub commands: echo_bus::Inbox<echo_msgs::RobotCommand>,
    /// The safety service's status.
    pub safety: echo_bus::Inbox<echo_msgs::SafetyStatus>,
    /// The forecaster's forecasts (with the robot's plans).
    pub forecasts: echo_bus::Inbox<echo_msgs::Forecast>,
}

impl HriTaps {
    /// Open every tap on `bus`'s robot.
    pub async fn open(bus: &Bus) -> Result<HriTaps> {
        use echo_bus::topics;
        let r = bus.robot();
        Ok(HriTaps {
            prompt: bus.publisher(&topics::prompt(r)).await?,
            states: bus.subscribe(&topics::robot_state(r)).await?,
            humans: bus.subscribe(&topics::humans(r)).await?,
            commands: bus.subscribe(&topics::command(r)).await?,
            safety: bus.subscribe(&topics::safety_status(r)).await?,
            forecasts: bus.subscribe(&topics::forecast(r)).await?,
        })
    }
}
