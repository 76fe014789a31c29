//! `echoctl record` writes what the mock perception publishes to MCAP with receive times; an
//! independent reader (PyPI `mcap`) reads the same messages; `echoctl replay` plays them back
//! at the requested rate onto the bus.

use std::path::PathBuf;
use std::process::Command;
use std::time::Duration;

use echo_bus::topics;
use echo_system_tests::Harness;

fn python_mcap_dir() -> PathBuf {
    std::env::var_os("ECHO_CACHE")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../.cache"))
        .join("python")
}

/// Per-topic message counts of `file` as read by the Python `mcap` package, or None when the
/// package is not installed (scripts/setup installs it).
fn python_counts(file: &std::path::Path) -> Option<Vec<(String, u64)>> {
    let dir = python_mcap_dir();
    if !dir.join("mcap/reader.py").is_file() {
        return None;
    }
    let script = r#"
import sys, collections
from mcap.reader import make_reader
counts = collections.Counter()
with open(sys.argv[1], "rb") as f:
    r = make_reader(f)
    last = 0
    for schema, channel, message in r.iter_messages(log_time_order=True):
        assert message.log_time >= last
        last = message.log_time
        assert channel.message_encoding == "json"
        counts[channel.topic] += 1
for k, v in sorted(counts.items()):
    print(k, v)
"#;
    let out = Command::new("python3")
        .env("PYTHONPATH", &dir)
        .arg("-c")
        .arg(script)
        .arg(file)
        .output()
        .ok()?;
    assert!(
        out.status.success(),
        "python mcap reader failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some(
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .filter_map(|l| {
                let (k, v) = l.rsplit_once(' ')?;
                Some((k.to_string(), v.parse().ok()?))
            })
            .collect(),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn record_then_replay_through_mcap() -> anyhow::Result<()> {
    let mut h = Harness::new("sys-record", 4)?;
    let scratch = tempfile::tempdir()?;
    let dir = scratch.path().to_path_buf();
    let file = dir.join("session.mcap");
    let bus = h.bus("system-test").await?;
    let robot = bus.robot().clone();
    // The mock camera needs the robot's joint state to place itself.
    h.spawn_services("single", &["mock-robot"])?;
    h.spawn(
        "mock-perception",
        "echoctl",
        &["mock-perception", "--seed", "5"],
    )?;
    h.wait_alive(
        &bus,
        &["mock-robot", "mock-perception"],
        Duration::from_secs(30),
    )
    .await?;
    h.spawn(
        "recorder",
        "echoctl",
        &["record", "--seconds", "3", "--out", file.to_str().unwrap()],
    )?;
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    while h.is_running("recorder") && tokio::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(!h.is_running("recorder"), "the recorder did not stop");
    h.stop("mock-perception", Duration::from_secs(3));

    let records = echo_record::read_recording(&file)?;
    let raw_key = topics::perception_raw(&robot).key.clone();
    let raw: Vec<_> = records.iter().filter(|r| r.key == raw_key).collect();
    assert!(
        raw.len() >= 25,
        "3 s at 15 Hz should give ≥ 25 frames, got {} ({})",
        raw.len(),
        h.log_tail("recorder")
    );
    let mut gaps: Vec<f64> = raw
        .windows(2)
        .map(|w| (w[1].log_time_ns - w[0].log_time_ns) as f64 / 1e6)
        .collect();
    gaps.sort_by(f64::total_cmp);
    let median = gaps[gaps.len() / 2];
    assert!(
        (50.0..85.0).contains(&median),
        "median spacing {median:.1} ms"
    );
    for r in &raw {
        serde_json::from_slice::<echo_msgs::KeypointFrame>(&r.payload)?;
    }

    match python_counts(&file) {
        Some(counts) => {
            let py = counts
                .iter()
                .find(|(k, _)| *k == raw_key)
                .map(|(_, n)| *n)
                .unwrap_or(0);
            assert_eq!(py, raw.len() as u64, "python mcap: {counts:?}");
            let total: u64 = counts.iter().map(|(_, n)| n).sum();
            assert_eq!(total, records.len() as u64);
        }
        None if std::env::var_os("ECHO_REQUIRE_ASSETS").is_some() => {
            panic!("the python mcap package is missing: run scripts/setup")
        }
        None => eprintln!("skipping the independent MCAP check: run scripts/setup"),
    }

    // Replay at twice the original rate into a fresh subscriber.
    let inbox = bus.subscribe(&topics::perception_raw(&robot)).await?;
    let span_s = (raw.last().unwrap().log_time_ns - raw[0].log_time_ns) as f64 / 1e9;
    h.spawn(
        "replay",
        "echoctl",
        &[
            "replay",
            file.to_str().unwrap(),
            "--speed",
            "2",
            "--only",
            "perception/raw",
        ],
    )?;
    let mut got = vec![];
    let deadline = tokio::time::Instant::now() + Duration::from_secs(20);
    while got.len() < raw.len() && tokio::time::Instant::now() < deadline {
        if let Ok(Some(m)) = tokio::time::timeout(Duration::from_millis(200), inbox.recv()).await {
            got.push(m);
        }
    }
    assert_eq!(got.len(), raw.len(), "{}", h.log_tail("replay"));
    let played_s = got.last().unwrap().at - got[0].at;
    let played_s = played_s.as_secs_f64();
    assert!(
        played_s > 0.35 * span_s && played_s < 0.75 * span_s,
        "played {played_s:.2} s of a {span_s:.2} s recording at speed 2"
    );
    // Restamped: fresh stamps, original sequence numbers.
    let first: echo_msgs::KeypointFrame = serde_json::from_slice(&raw[0].payload)?;
    assert_eq!(got[0].msg.header.seq, first.header.seq);
    assert!(got[0].msg.header.stamp_ns > raw.last().unwrap().log_time_ns);
    Ok(())
}
