//! The built-in browser viewer in a real headless browser: `echoctl view` follows a live bus
//! (mock perception playing two people walking past each other → perception bridge, simulated
//! robot) as a separate process, and Debian's
//! chromium loads its page (three.js from `scripts/setup`'s `.cache/web`, WebGL through
//! SwiftShader). The page's status line must show scenes arriving and updating, the robot's
//! capsules and the people's skeletons drawn, and a person moving. Without chromium or
//! three.js the test says what is missing and skips (`scripts/setup` installs both where it can).
//! `ECHO_VIEWER_SCREENSHOT=file.png` also saves a screenshot of the page.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use echo_system_tests::Harness;

fn chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("ECHO_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    let path = std::env::var_os("PATH")?;
    ["chromium", "chromium-browser"].iter().find_map(|name| {
        std::env::split_paths(&path)
            .map(|d| d.join(name))
            .find(|p| p.is_file())
    })
}

/// Headless chromium with the flags a closed network and a container need.
fn browser(exe: &Path, profile: &Path) -> Command {
    let mut c = Command::new(exe);
    c.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--window-size=1280,720",
    ])
    .arg(format!("--user-data-dir={}", profile.display()));
    c
}

/// The page's status line (`<pre id="status" …>…</pre>`) from a DOM dump.
fn status(dom: &str) -> Option<String> {
    let tag = dom.find("<pre id=\"status\"")?;
    let start = dom[tag..].find('>')? + tag + 1;
    let end = dom[start..].find("</pre>")? + start;
    Some(dom[start..end].to_string())
}

/// `name=value` from the status line.
fn field(status: &str, name: &str) -> Option<f64> {
    let key = format!("{name}=");
    let start = status.find(&key)? + key.len();
    status[start..]
        .split(|c: char| c.is_whitespace())
        .next()?
        .parse()
        .ok()
}

/// The most primitives an entity kind had in any update, from the status line's
/// `most primitives seen: kind n, …` (people who walked out of view are gone by the end).
fn peak(status: &str, kind: &str) -> u32 {
    let Some(line) = status
        .lines()
        .find_map(|l| l.strip_prefix("most primitives seen: "))
    else {
        return 0;
    };
    line.split(", ")
        .find_map(|item| item.strip_prefix(&format!("{kind} ")))
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or(0)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_browser_viewer_draws_the_robot_and_the_person_and_follows_the_bus() -> Result<()> {
    let Some(exe) = chromium() else {
        eprintln!("SKIPPED: no chromium (scripts/setup installs Debian's chromium where apt can; or set ECHO_CHROMIUM)");
        return Ok(());
    };
    let Some(assets) = echo_scene::web::locate_assets() else {
        eprintln!("SKIPPED: three.js not in .cache/web (run scripts/setup)");
        return Ok(());
    };

    let mut h = Harness::new("sys-viewer", 4)?;
    h.spawn("mock-robot", "echoctl", &["mock-robot"])?;
    h.spawn("perception-bridge", "perception-bridge", &[])?;
    let assets_arg = assets.to_string_lossy().to_string();
    h.spawn(
        "view",
        "echoctl",
        &["view", "--port", "0", "--hz", "10", "--assets", &assets_arg],
    )?;
    let bus = h.bus("system-test").await?;
    h.wait_alive(
        &bus,
        &["mock-robot", "perception-bridge"],
        Duration::from_secs(60),
    )
    .await?;
    h.spawn(
        "mock-perception",
        "echoctl",
        &["mock-perception", "--clip", "test:11"],
    )?;

    // The viewer prints its address once it serves.
    let started = Instant::now();
    let url = loop {
        let log = std::fs::read_to_string(h.log_dir().join("view.log")).unwrap_or_default();
        if let Some(line) = log.lines().find(|l| l.starts_with("viewer: open ")) {
            let url = line["viewer: open ".len()..]
                .split_whitespace()
                .next()
                .unwrap_or_default()
                .to_string();
            break url;
        }
        if started.elapsed() > Duration::from_secs(60) {
            bail!("the viewer did not start:\n{}", h.log_tail("view"));
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    };
    // Let people and joint states reach the viewer.
    tokio::time::sleep(Duration::from_secs(3)).await;

    let profile = tempfile::tempdir()?;
    let out = tokio::task::spawn_blocking({
        let exe = exe.clone();
        let url = url.clone();
        let profile = profile.path().to_path_buf();
        move || {
            browser(&exe, &profile)
                .args(["--virtual-time-budget=8000", "--dump-dom"])
                .arg(&url)
                .output()
        }
    })
    .await?
    .context("running chromium")?;
    let dom = String::from_utf8_lossy(&out.stdout);
    let Some(st) = status(&dom) else {
        bail!(
            "no status line in the page (chromium exit {:?}):\n{}\n{}",
            out.status.code(),
            &dom[..dom.len().min(2000)],
            String::from_utf8_lossy(&out.stderr)
        );
    };
    eprintln!("viewer status: {st}");
    assert!(
        dom.contains("<div id=\"error\"></div>"),
        "the page reports an error: {st}"
    );
    assert_eq!(field(&st, "webgl"), Some(1.0), "no WebGL context: {st}");
    let updates = field(&st, "updates").unwrap_or(0.0);
    // A poll may fail while the machine is loaded; the page goes on polling.
    let errors = field(&st, "errors").unwrap_or(f64::MAX);
    assert!(errors <= updates / 4.0, "fetch errors: {st}");
    assert!(updates >= 5.0, "the page must keep updating: {st}");
    assert!(peak(&st, "robot") >= 10, "the robot's capsules: {st}");
    // People: the partner once an interaction is announced, until then "person" entities; a
    // capsule per bone and a ball for the head, 22 primitives each.
    assert!(
        peak(&st, "partner").max(peak(&st, "person")) >= 20,
        "the people's skeletons: {st}"
    );
    let moved = field(&st, "person_moved_m").unwrap_or(0.0);
    assert!(moved > 0.02, "the person must move on the page: {st}");

    if let Some(shot) = std::env::var_os("ECHO_VIEWER_SCREENSHOT") {
        let shot = PathBuf::from(shot);
        let profile = tempfile::tempdir()?;
        let ok = browser(&exe, profile.path())
            .args(["--virtual-time-budget=6000", "--hide-scrollbars"])
            .arg(format!("--screenshot={}", shot.display()))
            .arg(&url)
            .output()?
            .status
            .success();
        assert!(ok && shot.is_file(), "screenshot {}", shot.display());
    }
    assert!(h.is_running("view"), "the viewer must keep running");
    Ok(())
}
