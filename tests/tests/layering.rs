//! Serving apart from training: the service binaries link no training or evaluation code.
//! Read from the manifests themselves (`[dependencies]` of each crate, followed through the
//! workspace's path dependencies), so a new dependency that drags training into a service
//! fails here.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Workspace crates by name → their folder, from `[workspace.dependencies]` and the services.
fn workspace_crates() -> BTreeMap<String, PathBuf> {
    let text = std::fs::read_to_string(root().join("Cargo.toml")).unwrap();
    let mut map = BTreeMap::new();
    for line in text.lines() {
        let Some((name, rest)) = line.split_once('=') else {
            continue;
        };
        let Some(p) = rest.split("path = \"").nth(1) else {
            continue;
        };
        let dir = p.split('"').next().unwrap();
        map.insert(name.trim().to_string(), root().join(dir));
    }
    for s in std::fs::read_dir(root().join("services")).unwrap() {
        let dir = s.unwrap().path();
        map.insert(dir.file_name().unwrap().to_string_lossy().into_owned(), dir);
    }
    map
}

/// The workspace crates named in a manifest's `[dependencies]` (not dev or build).
fn direct(dir: &Path, known: &BTreeMap<String, PathBuf>) -> BTreeSet<String> {
    let text = std::fs::read_to_string(dir.join("Cargo.toml")).unwrap();
    let mut in_deps = false;
    let mut out = BTreeSet::new();
    for line in text.lines().map(str::trim) {
        if line.starts_with('[') {
            in_deps = line == "[dependencies]";
            continue;
        }
        if !in_deps {
            continue;
        }
        let name = line
            .split(['.', '=', ' '])
            .next()
            .unwrap_or_default()
            .trim();
        if known.contains_key(name) {
            out.insert(name.to_string());
        }
    }
    out
}

/// Every workspace crate `krate` links, itself excluded.
fn closure(krate: &str) -> BTreeSet<String> {
    let known = workspace_crates();
    let mut seen = BTreeSet::new();
    let mut todo = vec![krate.to_string()];
    while let Some(k) = todo.pop() {
        for d in direct(&known[&k], &known) {
            if seen.insert(d.clone()) {
                todo.push(d);
            }
        }
    }
    seen
}

#[test]
fn the_forecaster_links_no_training_or_evaluation_code() {
    let deps = closure("forecaster");
    assert!(
        deps.contains("echo-models") && deps.contains("echo-forecast"),
        "the walk found the model crates: {deps:?}"
    );
    for training in [
        "echo-train",
        "echo-eval",
        "echo-hri",
        "echo-retarget",
        "echo-data",
    ] {
        assert!(
            !deps.contains(training),
            "forecaster links {training}: {deps:?}"
        );
    }
}

#[test]
fn no_service_links_the_training_crates() {
    for service in [
        "forecaster",
        "safety",
        "perception-bridge",
        "pose-estimator",
        "retargeter",
    ] {
        let deps = closure(service);
        // echo-retarget keeps ImitationNet's small training loop and its HRI scores (which use
        // echo-eval's confusion counts) beside the network; every other service links no
        // evaluation code either.
        let mut training = vec!["echo-train", "echo-hri", "echo-data"];
        if service != "retargeter" {
            training.push("echo-eval");
        }
        for t in training {
            assert!(!deps.contains(t), "{service} links {t}: {deps:?}");
        }
    }
}
