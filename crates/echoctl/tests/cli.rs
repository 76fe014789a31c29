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
    for verb in ["demo", "monitor", "list", "mock-perception", "mock-robot"] {
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
