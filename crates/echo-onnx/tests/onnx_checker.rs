//! An independent check of the exporter: the reference ONNX implementation (PyPI `onnx`, which
//! `scripts/setup` unpacks into `.cache/python-onnx` with its dependencies) loads the exported
//! models and its checker accepts them with the full check (strict shape and type inference).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use echo_onnx::export::build;
use prost::Message;

fn python_onnx_dir() -> PathBuf {
    std::env::var_os("ECHO_CACHE")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../.cache"))
        .join("python-onnx")
}

/// The directory holding the `onnx` package, or None (after saying so) when it is not
/// installed; scripts/test (CI) runs scripts/setup first and sets ECHO_REQUIRE_ASSETS=1, and
/// then a missing package is a failure.
fn python_onnx() -> Option<PathBuf> {
    let dir = python_onnx_dir();
    if dir.join("onnx/checker.py").is_file() {
        return Some(dir);
    }
    assert!(
        std::env::var_os("ECHO_REQUIRE_ASSETS").is_none(),
        "the python onnx package is missing from {}: run scripts/setup",
        dir.display()
    );
    eprintln!("skipping the ONNX checker: run scripts/setup");
    None
}

/// Runs `onnx.checker.check_model(onnx.load(f), full_check=True)` on each file; panics with
/// the checker's message when one is rejected.
fn check(dir: &Path, files: &[PathBuf]) {
    let script = r#"
import sys
import onnx
for path in sys.argv[1:]:
    m = onnx.load(path)
    onnx.checker.check_model(m, full_check=True)
    g = m.graph
    names = [t.name for t in g.initializer]
    assert len(names) == len(set(names)), "duplicate initializer names"
    print(f"{path}: ok ({len(g.node)} nodes, {len(names)} initializers, onnx {onnx.__version__})")
"#;
    // Only the pinned packages: no user or system site-packages (-s, -S).
    let out = Command::new("python3")
        .args(["-s", "-S", "-c", script])
        .args(files)
        .env("PYTHONPATH", dir)
        .env_remove("PYTHONHOME")
        .output()
        .expect("python3 runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    eprint!("{stdout}");
    assert!(
        out.status.success(),
        "the ONNX checker rejects the export:\n{stdout}{stderr}"
    );
    assert_eq!(stdout.lines().count(), files.len(), "{stdout}{stderr}");
}

#[test]
fn onnx_checker_accepts_shipped_export() {
    let Some(dir) = python_onnx() else {
        return;
    };
    let scratch = tempfile::tempdir().unwrap();
    let mut files = vec![];
    for name in ["forecaster", "hri"] {
        let stem = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../models")
            .join(name);
        let out = scratch.path().join(format!("{name}.onnx"));
        echo_onnx::export_checkpoint(&stem, &out).unwrap();
        files.push(out);
    }
    check(&dir, &files);
}

#[test]
fn onnx_checker_accepts_every_variant() {
    let Some(dir) = python_onnx() else {
        return;
    };
    let variants = common::variants();
    let scratch = tempfile::tempdir().unwrap();
    let mut files = vec![];
    for (i, cfg) in variants.iter().enumerate() {
        let weights = common::random_weights(cfg);
        let path = scratch.path().join(format!("v{i}.onnx"));
        std::fs::write(&path, build(weights, cfg).unwrap().encode_to_vec()).unwrap();
        files.push(path);
    }
    check(&dir, &files);
}
