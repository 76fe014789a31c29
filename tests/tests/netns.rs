//! Robot, edge and router as three hosts (Linux network namespaces joined by veth pairs): the
//! perception bridge, safety service, simulated robot and mock perception on the robot host, the
//! HRI forecaster on the edge host, a Zenoh router between them. Faults:
//!
//! 1. the forecaster is killed → the safety service stops the robot within its plan deadline;
//!    restarted → the pipeline resumes;
//! 2. the edge link goes down → the same stop (on the safety's own clock, not the Zenoh lease);
//!    back up → the pipeline resumes;
//! 3. a hot standby forecaster (rank 1) runs next to the primary, the primary is killed → the
//!    standby publishes within a few ticks.
//!
//! Everything on the robot host is recorded to MCAP and judged from the recording afterwards.
//! Needs root (network namespaces); skips with a message where that is not permitted.

use std::path::PathBuf;
use std::time::Duration;

use echo_bus::stats::latency_summary;
use echo_msgs::{now_ns, Forecast, JointState, SafetyState, SafetyStatus};
use echo_system_tests::netns::{self, Topology};
use echo_system_tests::Harness;

const ROBOT: &str = "nsbot";
/// The safety service's plan deadline (its default).
const PLAN_DEADLINE_MS: f64 = 200.0;
/// Longest acceptable time from a fault to the first stopping/holding status: the deadline
/// plus one 50 Hz control cycle and scheduling slack.
const STOP_STATUS_BOUND_MS: f64 = PLAN_DEADLINE_MS + 100.0;
/// Longest acceptable time from a fault to a robot at rest (the jerk-bounded stop included).
const AT_REST_BOUND_MS: f64 = 1500.0;

fn wait_for_log(h: &Harness, label: &str, text: &str, timeout: Duration) -> bool {
    let end = std::time::Instant::now() + timeout;
    while std::time::Instant::now() < end {
        let log =
            std::fs::read_to_string(h.log_dir().join(format!("{label}.log"))).unwrap_or_default();
        if log.contains(text) {
            return true;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    false
}

struct Timeline {
    status: Vec<(u64, SafetyStatus)>,
    forecasts: Vec<u64>,
    raw: Vec<u64>,
    speed: Vec<(u64, f64)>,
}

impl Timeline {
    fn read(file: &std::path::Path) -> anyhow::Result<Timeline> {
        let mut t = Timeline {
            status: vec![],
            forecasts: vec![],
            raw: vec![],
            speed: vec![],
        };
        for r in echo_record::read_recording(file)? {
            if r.key.ends_with("/safety/status") {
                t.status
                    .push((r.log_time_ns, serde_json::from_slice(&r.payload)?));
            } else if r.key.ends_with("/forecast") {
                serde_json::from_slice::<Forecast>(&r.payload)?;
                t.forecasts.push(r.log_time_ns);
            } else if r.key.ends_with("/perception/raw") {
                t.raw.push(r.log_time_ns);
            } else if r.key.ends_with("/robot/state") {
                let js: JointState = serde_json::from_slice(&r.payload)?;
                let v = js.velocity.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                t.speed.push((r.log_time_ns, v));
            }
        }
        Ok(t)
    }

    /// ms from `at` to the first stopping/holding status.
    fn stop_status_after(&self, at: u64) -> Option<f64> {
        self.status
            .iter()
            .find(|(t, s)| {
                *t >= at && matches!(s.state, SafetyState::Stopping | SafetyState::Holding)
            })
            .map(|(t, _)| (t - at) as f64 / 1e6)
    }

    /// ms from `at` to the first joint state at rest that stays at rest until `until`.
    fn at_rest_after(&self, at: u64, until: u64) -> Option<f64> {
        let window: Vec<_> = self
            .speed
            .iter()
            .filter(|(t, _)| *t >= at && *t < until)
            .collect();
        let last_moving = window.iter().rposition(|(_, v)| *v > 1e-3);
        let rest = match last_moving {
            Some(i) => window.get(i + 1)?,
            None => window.first()?,
        };
        Some((rest.0 - at) as f64 / 1e6)
    }

    /// ms from `at` to the first following/limiting status (the robot driven by plans again).
    fn resumed_after(&self, at: u64) -> Option<f64> {
        self.status
            .iter()
            .find(|(t, s)| {
                *t >= at && matches!(s.state, SafetyState::Following | SafetyState::Limiting)
            })
            .map(|(t, _)| (t - at) as f64 / 1e6)
    }

    /// Whether plans drove the robot in the `ms` before `at`.
    fn driven_before(&self, at: u64, ms: u64) -> bool {
        let from = at.saturating_sub(ms * 1_000_000);
        self.status.iter().any(|(t, s)| {
            *t >= from
                && *t < at
                && matches!(s.state, SafetyState::Following | SafetyState::Limiting)
        }) && self.forecasts.iter().any(|t| *t >= from && *t < at)
    }

    /// Median and p99 (ms) from the latest perception frame seen on the robot host to each
    /// forecast arriving back from the edge host, between `from` and `to`.
    fn round_trip_ms(&self, from: u64, to: u64) -> (f64, f64) {
        let d = self
            .forecasts
            .iter()
            .filter(|t| **t >= from && **t < to)
            .filter_map(|t| {
                let k = self.raw.partition_point(|r| r <= t);
                (k > 0).then(|| (t - self.raw[k - 1]) as f64 / 1e6)
            });
        latency_summary(d).map_or((f64::NAN, f64::NAN), |s| (s.median_ms, s.p99_ms))
    }

    fn max_speed(&self, from: u64, to: u64) -> f64 {
        self.speed
            .iter()
            .filter(|(t, _)| *t >= from && *t < to)
            .fold(0.0, |m, (_, v)| m.max(*v))
    }
}

#[test]
fn faults_across_hosts_stop_the_robot_and_recover() -> anyhow::Result<()> {
    if let Err(why) = netns::available() {
        eprintln!("skipping the multi-host fault test: {why}");
        return Ok(());
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let hri = root.join("models/hri");
    let topo = Topology::create(&format!("e{}", std::process::id() % 100_000), 61)?;
    let mut h = Harness::new(ROBOT, 0)?;
    let file = h.log_dir().join("robot-host.mcap");

    h.spawn_in(
        "router",
        &topo.router,
        "echoctl",
        &[
            "router",
            "--listen",
            "tcp/0.0.0.0:7447",
            "--no-multicast-scouting",
        ],
    )?;
    let robot_net = format!("tcp/{}:7447", topo.router_on_robot_link);
    let edge_net = format!("tcp/{}:7447", topo.router_on_edge_link);
    let net = |endpoint: &str| -> Vec<String> {
        [
            "--robot",
            ROBOT,
            "--mode",
            "client",
            "--connect",
            endpoint,
            "--no-multicast-scouting",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect()
    };
    let spawn = |h: &mut Harness, label: &str, ns: &str, endpoint: &str, args: &[&str]| {
        let mut all: Vec<String> = args.iter().map(|s| s.to_string()).collect();
        all.extend(net(endpoint));
        let all: Vec<&str> = all.iter().map(String::as_str).collect();
        let prog = if ["perception-bridge", "safety", "forecaster"]
            .contains(&label.split('#').next().unwrap())
        {
            label.split('#').next().unwrap()
        } else {
            "echoctl"
        };
        h.spawn_in(label, ns, prog, &all)
    };
    // Clients retry until the router listens.
    std::thread::sleep(Duration::from_millis(500));
    spawn(
        &mut h,
        "recorder",
        &topo.robot,
        &robot_net,
        &["record", "--out", file.to_str().unwrap()],
    )?;
    spawn(
        &mut h,
        "mock-robot",
        &topo.robot,
        &robot_net,
        &["mock-robot"],
    )?;
    spawn(&mut h, "perception-bridge", &topo.robot, &robot_net, &[])?;
    spawn(
        &mut h,
        "safety",
        &topo.robot,
        &robot_net,
        &["--require", "mock-robot"],
    )?;
    spawn(
        &mut h,
        "mock-perception",
        &topo.robot,
        &robot_net,
        &["mock-perception", "--clip", "test:1", "--robot-plays-b"],
    )?;
    spawn(
        &mut h,
        "prompt",
        &topo.robot,
        &robot_net,
        &["prompt", "--clip", "test:1", "--every", "0.5"],
    )?;
    // A forecaster on the edge host, started and loaded.
    let start_forecaster = |h: &mut Harness, label: &str, args: &[&str]| -> anyhow::Result<()> {
        spawn(h, label, &topo.edge, &edge_net, args)?;
        anyhow::ensure!(
            wait_for_log(h, label, "forecaster running", Duration::from_secs(90)),
            "{label} did not start:\n{}",
            h.log_tail(label)
        );
        Ok(())
    };
    let fc_args = ["--model", hri.to_str().unwrap()];
    start_forecaster(&mut h, "forecaster", &fc_args)?;
    std::thread::sleep(Duration::from_secs(6));

    // Fault 1: the forecaster dies.
    let kill_at = now_ns();
    h.kill("forecaster");
    std::thread::sleep(Duration::from_secs(4));
    let restart_at = now_ns();
    start_forecaster(&mut h, "forecaster#2", &fc_args)?;
    std::thread::sleep(Duration::from_secs(6));

    // Fault 2: the edge link goes down.
    let down_at = now_ns();
    topo.set_edge_link(false)?;
    std::thread::sleep(Duration::from_secs(4));
    let up_at = now_ns();
    topo.set_edge_link(true)?;
    std::thread::sleep(Duration::from_secs(8));

    // Fault 3: with a hot standby running (rank 1), the primary dies: the standby takes over.
    let standby_at = now_ns();
    let standby_args = ["--model", hri.to_str().unwrap(), "--rank", "1"];
    start_forecaster(&mut h, "forecaster#standby", &standby_args)?;
    std::thread::sleep(Duration::from_secs(4));
    let failover_at = now_ns();
    h.kill("forecaster#2");
    std::thread::sleep(Duration::from_secs(5));
    let end = now_ns();
    h.stop("recorder", Duration::from_secs(10));

    let t = Timeline::read(&file)?;
    assert!(
        t.status.len() > 50 && !t.forecasts.is_empty(),
        "recorded {} statuses, {} forecasts",
        t.status.len(),
        t.forecasts.len()
    );
    let mut report = vec![];
    for (name, fault, recover, next) in [
        ("forecaster killed", kill_at, restart_at, down_at),
        ("edge link down", down_at, up_at, standby_at),
    ] {
        assert!(
            t.driven_before(fault, 2000),
            "{name}: plans were not driving the robot before the fault"
        );
        let moving = t.max_speed(fault - 2_000_000_000, fault);
        let stop = t.stop_status_after(fault).unwrap_or(f64::INFINITY);
        let rest = t.at_rest_after(fault, recover).unwrap_or(f64::INFINITY);
        let resumed = t.resumed_after(recover).unwrap_or(f64::INFINITY);
        let no_forecast_during = !t
            .forecasts
            .iter()
            .any(|x| *x > fault + 50_000_000 && *x < recover);
        report.push(format!(
            "{name}: robot speed before {moving:.3} rad/s; stopping status after {stop:.0} ms; at rest after {rest:.0} ms; resumed {resumed:.0} ms after recovery"
        ));
        assert!(
            no_forecast_during,
            "{name}: forecasts kept arriving during the fault"
        );
        assert!(
            stop <= STOP_STATUS_BOUND_MS,
            "{name}: stop status after {stop:.0} ms"
        );
        assert!(
            rest <= AT_REST_BOUND_MS,
            "{name}: at rest after {rest:.0} ms"
        );
        assert!(
            resumed < (next - recover) as f64 / 1e6,
            "{name}: the pipeline did not resume"
        );
    }
    // The standby: the longest gap between forecasts around the takeover, and whether the safety
    // service had to stop the robot.
    let around: Vec<u64> = t
        .forecasts
        .iter()
        .copied()
        .filter(|x| *x >= failover_at - 1_000_000_000 && *x < end)
        .collect();
    let gap = around
        .windows(2)
        .map(|w| (w[1] - w[0]) as f64 / 1e6)
        .fold(0.0, f64::max);
    let after = around
        .iter()
        .filter(|x| **x > failover_at + 500_000_000)
        .count();
    let stopped = t.status.iter().any(|(x, st)| {
        *x > failover_at
            && *x < failover_at + 2_000_000_000
            && st.reasons.iter().any(|r| r.contains("no valid plan"))
    });
    report.push(format!(
        "primary killed with a standby running: longest forecast gap {gap:.0} ms; {after} forecasts from the standby in the next 4.5 s; safety stop: {stopped}"
    ));
    assert!(after > 30, "the standby did not take over");
    assert!(gap < 400.0, "takeover gap {gap:.0} ms");
    let (med, p99) = t.round_trip_ms(restart_at + 3_000_000_000, down_at);
    report.push(format!(
        "perception frame → forecast back on the robot host, across namespaces: median {med:.2} ms, p99 {p99:.2} ms"
    ));
    eprintln!("{}", report.join("\n"));
    drop(h);
    drop(topo);
    Ok(())
}
