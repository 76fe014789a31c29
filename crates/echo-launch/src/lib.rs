//! Starting and stopping Echo's processes — the one place that spawns a service, sends it
//! SIGTERM, waits for a deadline and kills it. `echoctl up` (with restarts), `echoctl demo`,
//! the fleet behind `echoctl bench e2e` / `soak`, and the system-test harness all use it.
//!
//! ```text
//! ProcessSpec ──start──▶ Process ──terminate(grace)──▶ SIGTERM … deadline … SIGKILL
//!                          │
//!       Group (many; stopped in reverse start order on drop, one shared deadline)
//!       supervise (one; restarted after exit: back-off 1 s doubling to 30 s, reset when healthy)
//! ```

pub mod profile;

use std::ffi::OsString;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;

/// Why a process could not be started.
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    /// The program is not there (not built, or a wrong directory).
    #[error("{0} is missing: build the workspace binaries first (cargo build --workspace --bins)")]
    Missing(PathBuf),
    /// The log file could not be created.
    #[error("creating the log {path}: {source}")]
    Log {
        /// Log file.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The OS refused to start it.
    #[error("starting {label} ({program}): {source}")]
    Spawn {
        /// Process label.
        label: String,
        /// Program.
        program: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
}

/// What to run.
#[derive(Debug, Clone, PartialEq)]
pub struct ProcessSpec {
    /// Name in logs and lookups (a service name, or e.g. `safety-r2`).
    pub label: String,
    /// The program.
    pub program: PathBuf,
    /// Its arguments.
    pub args: Vec<String>,
    /// Run it through this command first (e.g. `["ip", "netns", "exec", "ns1"]`).
    pub wrapper: Vec<String>,
    /// Extra environment.
    pub env: Vec<(String, String)>,
}

impl ProcessSpec {
    /// `program` with `args`, labelled `label`; services log at `info` (Zenoh at `warn`) unless
    /// `ECHO_SERVICE_LOG` says otherwise.
    pub fn new(label: &str, program: impl Into<PathBuf>, args: Vec<String>) -> ProcessSpec {
        ProcessSpec {
            label: label.to_string(),
            program: program.into(),
            args,
            wrapper: vec![],
            env: vec![(
                "RUST_LOG".into(),
                std::env::var("ECHO_SERVICE_LOG").unwrap_or_else(|_| "info,zenoh=warn".into()),
            )],
        }
    }

    /// Run through `wrapper` (its first item is the program started).
    pub fn wrapped(mut self, wrapper: &[&str]) -> ProcessSpec {
        self.wrapper = wrapper.iter().map(|s| s.to_string()).collect();
        self
    }

    /// The full command line, as it would be typed.
    pub fn command_line(&self) -> String {
        let mut v: Vec<String> = self.wrapper.clone();
        v.push(self.program.display().to_string());
        v.extend(self.args.iter().cloned());
        v.join(" ")
    }
}

/// Where a process's standard output and error go.
#[derive(Debug, Clone, PartialEq)]
pub enum Logs {
    /// Both into this file (created, truncated).
    File(PathBuf),
    /// Both onto this process's standard error, each line prefixed with `[label]`.
    Prefixed,
    /// Discarded.
    Null,
}

impl Logs {
    /// `<dir>/<label>.log`.
    pub fn in_dir(dir: &Path, label: &str) -> Logs {
        Logs::File(dir.join(format!("{label}.log")))
    }
}

/// How a stopped process ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stopped {
    /// It exited (by itself, or on SIGTERM) with this status.
    Exited(ExitStatus),
    /// It outlived the deadline and was killed.
    Killed,
}

impl Stopped {
    /// Exited with status 0: a clean shutdown.
    pub fn is_clean(&self) -> bool {
        matches!(self, Stopped::Exited(s) if s.success())
    }
}

/// A running process.
#[derive(Debug)]
pub struct Process {
    label: String,
    child: Child,
}

impl Process {
    /// Start `spec` with its output going to `logs`.
    pub fn start(spec: &ProcessSpec, logs: &Logs) -> Result<Process, LaunchError> {
        if spec.wrapper.is_empty() && !spec.program.is_file() {
            return Err(LaunchError::Missing(spec.program.clone()));
        }
        let mut cmd = match spec.wrapper.split_first() {
            Some((first, rest)) => {
                let mut c = Command::new(first);
                c.args(rest).arg(&spec.program);
                c
            }
            None => Command::new(&spec.program),
        };
        cmd.args(&spec.args).stdin(Stdio::null());
        for (k, v) in &spec.env {
            cmd.env(k, v);
        }
        match logs {
            Logs::File(path) => {
                let log = std::fs::File::create(path).map_err(|source| LaunchError::Log {
                    path: path.clone(),
                    source,
                })?;
                let err = log.try_clone().map_err(|source| LaunchError::Log {
                    path: path.clone(),
                    source,
                })?;
                cmd.stdout(Stdio::from(log)).stderr(Stdio::from(err));
            }
            Logs::Prefixed => {
                cmd.stdout(Stdio::piped()).stderr(Stdio::piped());
            }
            Logs::Null => {
                cmd.stdout(Stdio::null()).stderr(Stdio::null());
            }
        }
        let mut child = cmd.spawn().map_err(|source| LaunchError::Spawn {
            label: spec.label.clone(),
            program: spec.program.clone(),
            source,
        })?;
        if *logs == Logs::Prefixed {
            let out = child
                .stdout
                .take()
                .map(|p| Box::new(p) as Box<dyn std::io::Read + Send>);
            let err = child
                .stderr
                .take()
                .map(|p| Box::new(p) as Box<dyn std::io::Read + Send>);
            for pipe in [out, err].into_iter().flatten() {
                let label = spec.label.clone();
                std::thread::spawn(move || {
                    for line in BufReader::new(pipe).lines().map_while(Result::ok) {
                        eprintln!("[{label}] {line}");
                    }
                });
            }
        }
        Ok(Process {
            label: spec.label.clone(),
            child,
        })
    }

    /// Its label.
    pub fn label(&self) -> &str {
        &self.label
    }

    /// Its process id.
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    /// Its exit status once it has ended (None while it runs).
    pub fn try_status(&mut self) -> Option<ExitStatus> {
        self.child.try_wait().ok().flatten()
    }

    /// Whether it still runs.
    pub fn is_running(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// Send it a signal (no effect once it has ended).
    pub fn signal(&mut self, sig: Signal) {
        if self.is_running() {
            let _ = kill(Pid::from_raw(self.child.id() as i32), sig);
        }
    }

    /// SIGKILL now (a crash: no clean shutdown), and reap it.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// Wait until it ends or `deadline` passes; kill it then.
    fn reap_by(&mut self, deadline: Instant) -> Stopped {
        loop {
            if let Some(s) = self.try_status() {
                return Stopped::Exited(s);
            }
            if Instant::now() >= deadline {
                self.kill();
                return Stopped::Killed;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// SIGTERM, wait up to `grace`, then SIGKILL. Blocks (call it from a blocking task in
    /// async code).
    pub fn terminate(&mut self, grace: Duration) -> Stopped {
        self.signal(Signal::SIGTERM);
        self.reap_by(Instant::now() + grace)
    }
}

/// Processes started together and stopped together: SIGTERM to all in reverse start order,
/// one shared deadline, SIGKILL for what is left. Dropping the group stops them.
#[derive(Debug)]
pub struct Group {
    procs: Vec<Process>,
    grace: Duration,
}

impl Group {
    /// An empty group whose members get `grace` to stop.
    pub fn new(grace: Duration) -> Group {
        Group {
            procs: vec![],
            grace,
        }
    }

    /// Start `spec` into the group.
    pub fn start(&mut self, spec: &ProcessSpec, logs: &Logs) -> Result<&mut Process, LaunchError> {
        let p = Process::start(spec, logs)?;
        self.procs.push(p);
        Ok(self.procs.last_mut().expect("just pushed"))
    }

    /// A member by label.
    pub fn get(&self, label: &str) -> Option<&Process> {
        self.procs.iter().find(|p| p.label == label)
    }

    /// A member by label, to query or signal.
    pub fn get_mut(&mut self, label: &str) -> Option<&mut Process> {
        self.procs.iter_mut().find(|p| p.label == label)
    }

    /// Take a member out of the group (the caller stops it).
    pub fn take(&mut self, label: &str) -> Option<Process> {
        let pos = self.procs.iter().position(|p| p.label == label)?;
        Some(self.procs.remove(pos))
    }

    /// The label of the first member (in start order) that is no longer running.
    pub fn first_ended(&mut self) -> Option<&str> {
        let i = self.procs.iter_mut().position(|p| !p.is_running())?;
        Some(self.procs[i].label.as_str())
    }

    /// Members' labels in start order.
    pub fn labels(&self) -> Vec<&str> {
        self.procs.iter().map(|p| p.label.as_str()).collect()
    }

    /// Members' (label, pid).
    pub fn pids(&self) -> Vec<(String, u32)> {
        self.procs
            .iter()
            .map(|p| (p.label.clone(), p.id()))
            .collect()
    }

    /// Stop every member (SIGTERM in reverse start order, then wait on one deadline) and report
    /// how each ended, in reverse start order.
    pub fn stop_all(&mut self) -> Vec<(String, Stopped)> {
        for p in self.procs.iter_mut().rev() {
            p.signal(Signal::SIGTERM);
        }
        let deadline = Instant::now() + self.grace;
        self.procs
            .drain(..)
            .rev()
            .map(|mut p| {
                let s = p.reap_by(deadline);
                (p.label, s)
            })
            .collect()
    }
}

impl Drop for Group {
    fn drop(&mut self) {
        self.stop_all();
    }
}

/// When `supervise` restarts a process that exited.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RestartPolicy {
    /// Wait before the first restart.
    pub first_backoff: Duration,
    /// Longest wait (the wait doubles after each exit).
    pub max_backoff: Duration,
    /// A run this long resets the wait to `first_backoff`.
    pub healthy_after: Duration,
    /// Time a stopping process gets between SIGTERM and SIGKILL.
    pub grace: Duration,
}

impl Default for RestartPolicy {
    fn default() -> Self {
        RestartPolicy {
            first_backoff: Duration::from_secs(1),
            max_backoff: Duration::from_secs(30),
            healthy_after: Duration::from_secs(60),
            grace: Duration::from_secs(5),
        }
    }
}

/// What a supervision ended with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Supervised {
    /// Times the process was started.
    pub starts: u32,
}

/// Keep one process running until `stop` resolves: restart it after every exit with the
/// policy's back-off; on `stop`, SIGTERM → grace → SIGKILL. Returns an error only when it
/// cannot be started at all.
pub async fn supervise(
    spec: ProcessSpec,
    logs: Logs,
    policy: RestartPolicy,
    stop: impl std::future::Future<Output = ()>,
) -> Result<Supervised, LaunchError> {
    tokio::pin!(stop);
    let mut backoff = policy.first_backoff;
    let mut starts = 0;
    loop {
        let started = Instant::now();
        let mut p = Process::start(&spec, &logs)?;
        starts += 1;
        let status = loop {
            tokio::select! {
                _ = &mut stop => {
                    let grace = policy.grace;
                    let _ = tokio::task::spawn_blocking(move || p.terminate(grace)).await;
                    return Ok(Supervised { starts });
                }
                _ = tokio::time::sleep(Duration::from_millis(50)) => {
                    if let Some(s) = p.try_status() {
                        break s;
                    }
                }
            }
        };
        if started.elapsed() >= policy.healthy_after {
            backoff = policy.first_backoff;
        }
        eprintln!(
            "[{}] exited ({status}); restarting in {:.1} s",
            spec.label,
            backoff.as_secs_f64()
        );
        tokio::select! {
            _ = &mut stop => return Ok(Supervised { starts }),
            _ = tokio::time::sleep(backoff) => {}
        }
        backoff = (backoff * 2).min(policy.max_backoff);
    }
}

/// Send `sig` to any process by id (e.g. a crash injected into a supervised child); whether it
/// was delivered.
pub fn send_signal(pid: u32, sig: Signal) -> bool {
    kill(Pid::from_raw(pid as i32), sig).is_ok()
}

pub use nix::sys::signal::Signal as Sig;

/// Arguments as owned strings.
pub fn args<I, S>(items: I) -> Vec<String>
where
    I: IntoIterator<Item = S>,
    S: Into<OsString>,
{
    items
        .into_iter()
        .map(|s| s.into().to_string_lossy().into_owned())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sh(label: &str, script: &str) -> ProcessSpec {
        ProcessSpec::new(label, "/bin/sh", args(["-c", script]))
    }

    #[test]
    fn sigterm_stops_a_process_cleanly_and_its_output_is_logged() {
        let dir = tempfile::tempdir().unwrap();
        let spec = sh(
            "talker",
            "trap 'echo bye; exit 0' TERM; echo hello; while :; do sleep 0.05; done",
        );
        let mut p = Process::start(&spec, &Logs::in_dir(dir.path(), "talker")).unwrap();
        std::thread::sleep(Duration::from_millis(300));
        assert!(p.is_running());
        let t = Instant::now();
        let s = p.terminate(Duration::from_secs(5));
        assert!(s.is_clean(), "{s:?}");
        assert!(t.elapsed() < Duration::from_secs(2));
        let log = std::fs::read_to_string(dir.path().join("talker.log")).unwrap();
        assert!(log.contains("hello") && log.contains("bye"), "{log}");
    }

    #[test]
    fn a_process_that_ignores_sigterm_is_killed_at_the_deadline() {
        let spec = sh("stubborn", "trap '' TERM; exec sleep 30");
        let mut p = Process::start(&spec, &Logs::Null).unwrap();
        std::thread::sleep(Duration::from_millis(200));
        let t = Instant::now();
        assert_eq!(p.terminate(Duration::from_millis(400)), Stopped::Killed);
        let waited = t.elapsed();
        assert!(waited >= Duration::from_millis(400) && waited < Duration::from_secs(3));
        assert!(!p.is_running());
    }

    #[test]
    fn a_group_stops_everything_on_one_deadline_and_on_drop() {
        let mut g = Group::new(Duration::from_millis(500));
        g.start(&sh("a", "trap '' TERM; exec sleep 30"), &Logs::Null)
            .unwrap();
        g.start(&sh("b", "trap '' TERM; exec sleep 30"), &Logs::Null)
            .unwrap();
        g.start(&sh("c", "exec sleep 30"), &Logs::Null).unwrap();
        assert_eq!(g.labels(), ["a", "b", "c"]);
        // Let the shells install their traps.
        std::thread::sleep(Duration::from_millis(300));
        let t = Instant::now();
        assert_eq!(g.first_ended(), None);
        let stopped = g.stop_all();
        // One shared deadline, not one per member.
        assert!(
            t.elapsed() < Duration::from_millis(1500),
            "{:?}",
            t.elapsed()
        );
        let labels: Vec<&str> = stopped.iter().map(|(l, _)| l.as_str()).collect();
        assert_eq!(labels, ["c", "b", "a"], "reverse start order");
        assert!(matches!(stopped[0].1, Stopped::Exited(_)));
        assert_eq!(stopped[1].1, Stopped::Killed);

        let pid;
        {
            let mut g = Group::new(Duration::from_millis(200));
            pid = g
                .start(&sh("d", "exec sleep 30"), &Logs::Null)
                .unwrap()
                .id();
        }
        // Reaped: the pid no longer names a live process of ours.
        assert!(kill(Pid::from_raw(pid as i32), None).is_err());
    }

    #[test]
    fn a_missing_program_is_a_clear_error() {
        let e = Process::start(
            &ProcessSpec::new("ghost", "/nonexistent/forecaster", vec![]),
            &Logs::Null,
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("/nonexistent/forecaster is missing"),
            "{e}"
        );
    }

    #[tokio::test]
    async fn supervise_restarts_after_exits_and_stops_on_request() {
        let dir = tempfile::tempdir().unwrap();
        let count = dir.path().join("starts");
        let script = format!("echo x >> {}; exit 3", count.display());
        let policy = RestartPolicy {
            first_backoff: Duration::from_millis(50),
            max_backoff: Duration::from_millis(100),
            healthy_after: Duration::from_secs(60),
            grace: Duration::from_secs(1),
        };
        let r = supervise(
            sh("crashy", &script),
            Logs::Null,
            policy,
            tokio::time::sleep(Duration::from_millis(1200)),
        )
        .await
        .unwrap();
        let lines = std::fs::read_to_string(&count).unwrap().lines().count() as u32;
        assert!(r.starts >= 4, "{r:?}");
        assert_eq!(lines, r.starts);

        // A long-running process: stop ends it (SIGTERM) and it is not restarted.
        let t = Instant::now();
        let r = supervise(
            sh("steady", "exec sleep 30"),
            Logs::Null,
            policy,
            tokio::time::sleep(Duration::from_millis(300)),
        )
        .await
        .unwrap();
        assert_eq!(r.starts, 1);
        assert!(t.elapsed() < Duration::from_secs(2));
    }
}
