//! The whole pipeline under attack, as separate processes over Zenoh: a hostile client floods
//! every input key of every service (JSON and ROS 2 CDR) with malformed, oversized, non-finite,
//! out-of-range, reordered, far-future, wrong-robot, forged-source and wildcard messages
//! (`echo_system_tests::attack`). Asserted: every service stays alive, memory stays bounded, no
//! command (JSON or ROS 2) leaves the hard limits or jumps between cycles, forecasts continue
//! (also within one second of a message stamped 2^64−1), and rejections are counted by reason.
//!
//! Short in CI (8 s); long as a command: `scripts/attack [seconds]`
//! (`ECHO_ATTACK_SECONDS`, and `ECHO_ATTACK_REPORT=<file>` for the JSON report).

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use echo_bus::stats::process_rss_mib;
use echo_bus::{keys, topics, RobotId};
use echo_msgs::{RobotCommand, SafetyStatus, ServiceStatus};
use echo_robot::RobotModel;
use echo_system_tests::attack::{self, Sent, Templates};
use echo_system_tests::Harness;

const ROBOT: &str = "sys-attack";
const NS: &str = "/attack";
const RSS_GROWTH_BOUND_MIB: f64 = 64.0;
/// The safety service's control period (default config), s.
const DT: f64 = 0.02;

/// Every command seen, judged against the URDF's hard limits.
#[derive(Debug, Default)]
struct CommandCheck {
    json_commands: u64,
    ros2_trajectories: u64,
    points: u64,
    violations: Vec<String>,
    /// Previous JSON command: seq and first point per joint.
    prev: Option<(u64, BTreeMap<String, f64>)>,
}

struct Limits(BTreeMap<String, (f64, f64, f64)>);

impl Limits {
    fn tiago() -> Limits {
        let m = RobotModel::tiago_dual();
        Limits(
            m.actuated_joints()
                .iter()
                .filter_map(|j| {
                    m.limits(j)
                        .map(|l| (j.clone(), (l.lower, l.upper, l.velocity)))
                })
                .collect(),
        )
    }

    fn check_point(&self, c: &mut CommandCheck, what: &str, names: &[String], q: &[f64]) {
        c.points += 1;
        if names.len() != q.len() {
            c.violations.push(format!(
                "{what}: {} names, {} positions",
                names.len(),
                q.len()
            ));
            return;
        }
        for (n, x) in names.iter().zip(q) {
            match self.0.get(n) {
                None => c.violations.push(format!("{what}: unknown joint {n}")),
                Some((lo, hi, _)) if !(x.is_finite() && *x >= lo - 1e-9 && *x <= hi + 1e-9) => c
                    .violations
                    .push(format!("{what}: {n} = {x} outside [{lo}, {hi}]")),
                _ => {}
            }
        }
    }

    fn check_command(&self, c: &mut CommandCheck, cmd: &RobotCommand) {
        c.json_commands += 1;
        let mut first = BTreeMap::new();
        for tr in &cmd.trajectories {
            for p in &tr.points {
                self.check_point(c, "command", &tr.joint_names, &p.positions);
            }
            if let Some(p0) = tr.points.first() {
                for (n, x) in tr.joint_names.iter().zip(&p0.positions) {
                    first.insert(n.clone(), *x);
                }
            }
        }
        // Consecutive commands: the first points move no faster than the velocity limits over
        // the cycles between them (sequence numbers count cycles; a lost command spans two).
        if let Some((seq0, prev)) = &c.prev {
            let cycles = cmd.header.seq.saturating_sub(*seq0).max(1) as f64;
            for (n, x) in &first {
                if let (Some(x0), Some((_, _, v))) = (prev.get(n), self.0.get(n)) {
                    if (x - x0).abs() > v * DT * cycles * (1.0 + 1e-6) + 1e-9 {
                        c.violations.push(format!(
                            "command {}: {n} moved {:.4} in {cycles} cycle(s) (limit {v})",
                            cmd.header.seq,
                            (x - x0).abs()
                        ));
                    }
                }
            }
        }
        c.prev = Some((cmd.header.seq, first));
    }
}

fn seconds() -> f64 {
    std::env::var("ECHO_ATTACK_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(8.0)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hostile_input_on_every_key_never_reaches_the_robot() -> anyhow::Result<()> {
    // The pipeline `echoctl up --profile single` runs, the safety service also on ROS 2.
    let mut h = Harness::new(ROBOT, 6)?;
    let vars = echo_system_tests::profile_vars();
    for s in [
        "mock-robot",
        "perception-bridge",
        "safety",
        "forecaster",
        "retargeter",
        "mock-perception",
    ] {
        let extra: &[&str] = match s {
            "safety" => &["--ros2-namespace", NS],
            _ => &[],
        };
        h.spawn_service("single", s, &vars, extra)?;
    }
    let bus = h.bus("attacker").await?;
    let robot: RobotId = bus.robot().clone();
    let services = [
        "perception-bridge",
        "safety",
        "forecaster",
        "retargeter",
        "mock-robot",
    ];
    h.wait_alive(
        &bus,
        &[&services[..], &["mock-perception"]].concat(),
        Duration::from_secs(60),
    )
    .await?;

    // Watchers: every JSON command and ROS 2 trajectory, every forecast's arrival.
    let limits = Arc::new(Limits::tiago());
    let check = Arc::new(Mutex::new(CommandCheck::default()));
    let s = bus.session();
    let (l2, c2) = (limits.clone(), check.clone());
    let _commands = s
        .declare_subscriber(keys::command(&robot))
        .callback(move |sample| {
            let mut c = c2.lock().unwrap_or_else(|e| e.into_inner());
            match echo_msgs::decode::<RobotCommand>(&sample.payload().to_bytes()) {
                Ok(cmd) => l2.check_command(&mut c, &cmd),
                Err(e) => c.violations.push(format!("undecodable command: {e}")),
            }
        })
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut ros_subs = vec![];
    for g in echo_robot::groups::motion_groups() {
        let (l2, c2) = (limits.clone(), check.clone());
        let key = echo_ros2::ros_key(NS, &echo_ros2::trajectory_topic(g.controller));
        ros_subs.push(
            s.declare_subscriber(key)
                .callback(move |sample| {
                    let mut c = c2.lock().unwrap_or_else(|e| e.into_inner());
                    c.ros2_trajectories += 1;
                    match echo_ros2::decode::<echo_ros2::RosJointTrajectory>(
                        &sample.payload().to_bytes(),
                    ) {
                        Ok(t) => {
                            for p in &t.points {
                                l2.check_point(
                                    &mut c,
                                    "ROS 2 trajectory",
                                    &t.joint_names,
                                    &p.positions,
                                );
                            }
                        }
                        Err(e) => c.violations.push(format!("undecodable trajectory: {e}")),
                    }
                })
                .await
                .map_err(|e| anyhow::anyhow!("{e}"))?,
        );
    }
    // The forecaster's own forecasts: its source, increasing sequence numbers, stamps not from
    // the future (the attacker replays and forges forecasts under the same key and name).
    let forecasts: Arc<Mutex<Vec<Instant>>> = Arc::default();
    let f2 = forecasts.clone();
    let last_real: Arc<Mutex<Option<(String, u64)>>> = Arc::default();
    let _forecasts = s
        .declare_subscriber(keys::forecast(&robot))
        .callback(move |sample| {
            let Ok(f) = echo_msgs::decode::<echo_msgs::Forecast>(&sample.payload().to_bytes())
            else {
                return;
            };
            let h = &f.header;
            if !h.source.starts_with("forecaster-")
                || h.stamp_ns > echo_msgs::now_ns() + 1_000_000_000
            {
                return;
            }
            let mut last = last_real.lock().unwrap_or_else(|e| e.into_inner());
            let real = match &*last {
                None => true,
                Some((src, seq)) => *src == h.source && h.seq > *seq && h.seq - seq < 10_000,
            };
            if real {
                *last = Some((h.source.clone(), h.seq));
                f2.lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .push(Instant::now());
            }
        })
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let safety_status = bus.subscribe(&topics::safety_status(&robot)).await?;
    let status = bus.subscribe(&topics::service_status_all(&robot)).await?;

    // Real traffic as the templates of well-formed hostile messages.
    let input_keys = [
        keys::perception_raw(&robot),
        keys::humans(&robot),
        keys::robot_state(&robot),
        keys::forecast(&robot),
    ];
    let mut templates = Templates::capture(&bus, &input_keys, Duration::from_secs(10)).await?;
    templates.add_operator_keys(&robot);
    if let Some(plan) = templates
        .by_key
        .get(&keys::forecast(&robot))
        .and_then(|f| f.get("robot"))
        .filter(|p| !p.is_null())
        .cloned()
    {
        let mut plan = plan;
        plan["mode"] = "imitation".into();
        templates.by_key.insert(keys::retarget(&robot), plan);
    }
    for k in &input_keys {
        assert!(templates.by_key.contains_key(k), "no traffic seen on {k}");
    }
    let raw_keys = vec![keys::retarget(&robot), keys::retarget_batch(&robot)];
    let state = templates.by_key[&keys::robot_state(&robot)].clone();
    let names: Vec<String> = serde_json::from_value(state["name"].clone())?;
    let q: Vec<f64> = serde_json::from_value(state["position"].clone())?;
    let ros_states = attack::ros2_joint_states(&names, &q);
    let ros_key = echo_ros2::ros_key(NS, echo_ros2::JOINT_STATES_TOPIC);

    let rss = |h: &Harness| -> BTreeMap<String, f64> {
        services
            .iter()
            .map(|s| {
                (
                    s.to_string(),
                    h.pid(s).and_then(process_rss_mib).unwrap_or(0.0),
                )
            })
            .collect()
    };
    let rss_before = rss(&h);

    // 1. One humans message stamped 2^64−1 must not stop the forecasts.
    let mut probe = templates.by_key[&keys::humans(&robot)].clone();
    probe["header"]["stamp_ns"] = u64::MAX.into();
    probe["header"]["source"] = "far-future-probe".into();
    probe["header"]["seq"] = 1.into();
    let sent_at = Instant::now();
    s.put(keys::humans(&robot), serde_json::to_vec(&probe)?)
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let after_probe = forecasts
        .lock()
        .unwrap()
        .iter()
        .filter(|t| **t > sent_at)
        .min()
        .map(|t| t.duration_since(sent_at));
    eprintln!("first forecast after the 2^64−1 message: {after_probe:?}");
    assert!(
        matches!(after_probe, Some(d) if d < Duration::from_secs(1)),
        "forecasts stopped after one far-future message: {after_probe:?}"
    );

    // 2. The flood: every class on every key; forecasts must keep coming. Then its last
    // quarter (at least 2 s) adds a second publisher posing as the robot with out-of-range
    // joint states: the safety service must name a sensor fault and stop the robot.
    let secs = seconds();
    let impersonation_s = (secs / 4.0).max(2.0);
    let mut sent = Sent::default();
    let started = Instant::now();
    let mut impersonation_start = None;
    let mut n = 0u64;
    let mut sensor_fault_named = false;
    while started.elapsed().as_secs_f64() < secs + impersonation_s {
        let impersonate = started.elapsed().as_secs_f64() >= secs;
        if impersonate && impersonation_start.is_none() {
            impersonation_start = Some(Instant::now());
        }
        attack::round(
            &bus,
            &templates,
            &raw_keys,
            Some((&ros_key, &ros_states)),
            &robot,
            n,
            impersonate,
            &mut sent,
        )
        .await;
        n += 1;
        for st in safety_status.drain() {
            sensor_fault_named |= st.msg.reasons.iter().any(|r| r.contains("sensor fault"));
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let impersonation_start = impersonation_start.unwrap_or(started);
    let flood_end = Instant::now();
    // Recovery: an impersonator that outran a real sender's sequence numbers locks that sender
    // out until its entry expires (SeqTracker::EXPIRY after the last forged message).
    let recovery_bound = echo_msgs::SeqTracker::EXPIRY + Duration::from_secs(3);
    let mut recovered = None;
    while flood_end.elapsed() < recovery_bound {
        if let Some(t) = forecasts.lock().unwrap().iter().find(|t| **t > flood_end) {
            recovered = Some(t.duration_since(flood_end));
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    tokio::time::sleep(Duration::from_secs(2)).await;

    // 3. Judge.
    let rss_after = rss(&h);
    let mut alive = BTreeMap::new();
    for s in services {
        alive.insert(s.to_string(), h.is_running(s));
    }
    let mut last: BTreeMap<String, ServiceStatus> = BTreeMap::new();
    let mut last_safety: Option<SafetyStatus> = None;
    let end = Instant::now() + Duration::from_secs(5);
    while Instant::now() < end && !services.iter().all(|s| last.contains_key(*s)) {
        if let Ok(Some(m)) = tokio::time::timeout(Duration::from_millis(200), status.recv()).await {
            last.insert(m.msg.service.clone(), m.msg);
        }
    }
    if let Some(m) = safety_status.drain().pop() {
        last_safety = Some(m.msg);
    }
    let c = check.lock().unwrap();
    let f = forecasts.lock().unwrap();
    let during = f
        .iter()
        .filter(|t| **t > started && **t <= impersonation_start)
        .count();
    let after = f.iter().filter(|t| **t > flood_end).count();
    let report = serde_json::json!({
        "seconds": secs,
        "impersonation_seconds": impersonation_s,
        "rounds": n,
        "sent_per_class": sent.per_class,
        "sent_total": sent.total(),
        "put_errors": sent.put_errors,
        "json_commands_checked": c.json_commands,
        "ros2_trajectories_checked": c.ros2_trajectories,
        "points_checked": c.points,
        "violations": c.violations.len(),
        "first_forecast_after_far_future_ms": after_probe.map(|d| d.as_secs_f64() * 1e3),
        "forecasts_during": during,
        "forecasts_after": after,
        "forecasts_resumed_after_ms": recovered.map(|d| d.as_secs_f64() * 1e3),
        "alive": alive,
        "rss_mib_before": rss_before,
        "rss_mib_after": rss_after,
        "rejected": last.iter().map(|(k, v)| (k.clone(), v.rejected.clone())).collect::<BTreeMap<_, _>>(),
        "safety_counters": last_safety.as_ref().map(|s| s.counters.clone()),
        "sensor_fault_named": sensor_fault_named,
    });
    eprintln!("{}", serde_json::to_string_pretty(&report)?);
    if let Ok(p) = std::env::var("ECHO_ATTACK_REPORT") {
        std::fs::write(p, serde_json::to_vec_pretty(&report)?)?;
    }

    for s in services {
        assert!(alive[s], "{s} died:\n{}", h.log_tail(s));
        let growth = rss_after[s] - rss_before[s];
        assert!(growth < RSS_GROWTH_BOUND_MIB, "{s} grew {growth:.0} MiB");
    }
    assert!(
        c.violations.is_empty(),
        "{} commands outside the limits, e.g. {:?}",
        c.violations.len(),
        &c.violations[..c.violations.len().min(5)]
    );
    assert!(
        c.json_commands > 50 && c.ros2_trajectories > 50,
        "commands kept coming"
    );
    for class in attack::CLASSES {
        assert!(
            sent.per_class.get(*class).copied().unwrap_or(0) > 0,
            "class {class} was never sent"
        );
    }
    assert!(
        during > 0 && after > 0,
        "forecasts continue: {during} during, {after} after"
    );
    assert!(
        sensor_fault_named,
        "out-of-range joint states are named as a sensor fault"
    );
    // Rejections counted by reason, per service.
    for s in ["perception-bridge", "safety", "forecaster", "retargeter"] {
        let st = last.get(s).unwrap_or_else(|| panic!("no status from {s}"));
        for reason in ["malformed", "too_large"] {
            assert!(
                st.rejected
                    .keys()
                    .any(|k| k.ends_with(&format!("/{reason}"))),
                "{s} has no {reason} count: {:?}",
                st.rejected
            );
        }
    }
    let safety = &last["safety"].rejected;
    for reason in ["robot_state/wrong_robot", "robot_state/foreign_source"] {
        assert!(
            safety.get(reason).copied().unwrap_or(0) > 0,
            "{reason}: {safety:?}"
        );
    }
    assert!(
        safety
            .get("ros2_joint_states/foreign_source")
            .copied()
            .unwrap_or(0)
            + safety
                .get("ros2_joint_states/invalid")
                .copied()
                .unwrap_or(0)
            > 0,
        "ROS 2 joint states refused: {safety:?}"
    );
    let counters = last_safety.map(|s| s.counters).unwrap_or_default();
    assert!(
        counters.get("state/out_of_limits").copied().unwrap_or(0)
            + counters.get("state/jump").copied().unwrap_or(0)
            > 0,
        "{counters:?}"
    );
    Ok(())
}
