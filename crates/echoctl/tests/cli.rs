//! The command line: verbs are listed, and mistakes get errors that name the flag.

use std::process::Command;

fn echoctl(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_echoctl"))
        .args(args)
        .output()
        .expect("run echoctl")
}

#[test]
fn help_lists_every_verb() {
    let out = echoctl(&["--help"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for verb in [
        "demo",
        "monitor",
        "list",
        "mock-perception",
        "mock-robot",
        "data",
        "eval",
        "bench",
        "router",
    ] {
        assert!(text.contains(verb), "{verb} missing from:\n{text}");
    }
}

#[test]
fn bad_values_are_named() {
    let out = echoctl(&[
        "mock-perception",
        "--format",
        "halpe26",
        "--robot",
        "t",
        "--no-multicast-scouting",
        "--listen",
        "tcp/127.0.0.1:0",
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("halpe26"));
    let out = echoctl(&["list", "--robot", "a/b"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--robot"));
    let out = echoctl(&["list", "--mode", "boss"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("boss"));
}

#[test]
fn data_and_eval_verbs_work_end_to_end() {
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path().to_path_buf();
    // gen → Echo's format, then stats read it back.
    let out = echoctl(&[
        "data",
        "gen",
        "--split",
        "val",
        "--clips",
        "13",
        "--out",
        dir.join("ds").to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = echoctl(&["data", "stats", "--dir", dir.join("ds").to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert_eq!(
        text.lines()
            .filter(|l| l.starts_with("| ") && !l.starts_with("| type"))
            .count(),
        13,
        "{text}"
    );
    // export to the InterGen layout and BVH.
    assert!(echoctl(&[
        "data",
        "export",
        "--format",
        "intergen",
        "--clips",
        "2",
        "--out",
        dir.join("ig").to_str().unwrap()
    ])
    .status
    .success());
    assert!(dir.join("ig/motions_processed/person2/1.npy").is_file());
    assert!(echoctl(&[
        "data",
        "export",
        "--format",
        "bvh",
        "--clips",
        "1",
        "--out",
        dir.join("bvh").to_str().unwrap()
    ])
    .status
    .success());
    assert!(dir.join("bvh/00000_person1.bvh").is_file());
    // render a strip.
    let png = dir.join("wave.png");
    assert!(echoctl(&[
        "data",
        "render",
        "--kind",
        "wave",
        "--strip",
        "3",
        "--out",
        png.to_str().unwrap()
    ])
    .status
    .success());
    assert!(std::fs::metadata(&png).unwrap().len() > 1000);
    // eval prints the table and writes JSON with both baselines.
    let json = dir.join("eval.json");
    let out = echoctl(&[
        "eval",
        "--split",
        "test",
        "--clips-per-kind",
        "2",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("| zero-velocity |"));
    let reports: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(reports.as_array().unwrap().len(), 2);
    // mistakes are named.
    let out = echoctl(&[
        "data",
        "render",
        "--kind",
        "tango",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("tango"));
    let out = echoctl(&["eval", "--baseline", "oracle"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("oracle"));
}
