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
fn demo_from_pictures_needs_a_folder_of_them_and_no_scenario() {
    let err = |out: &std::process::Output| String::from_utf8_lossy(&out.stderr).into_owned();
    let out = echoctl(&["demo", "--camera", "/nonexistent/pictures"]);
    assert!(!out.status.success());
    assert!(
        err(&out).contains("--camera /nonexistent/pictures"),
        "{}",
        err(&out)
    );
    let empty = tempfile::tempdir().unwrap();
    let dir = empty.path().to_str().unwrap();
    let out = echoctl(&["demo", "--camera", dir]);
    assert!(!out.status.success());
    assert!(err(&out).contains("no PNG or JPEG images"), "{}", err(&out));
    let out = echoctl(&["demo", "--camera", dir, "--scenario", "wave"]);
    assert!(!out.status.success());
    assert!(err(&out).contains("cannot be used with"), "{}", err(&out));
}

#[test]
fn a_human_robot_checkpoint_in_the_human_table_is_a_clear_error() {
    let out = echoctl(&[
        "eval",
        "--split",
        "test",
        "--clips-per-kind",
        "1",
        "--model",
        "models/hri",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("evaluate it with --hri"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn a_scenario_file_of_ones_own_is_checked() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("mine.json");
    std::fs::write(
        &file,
        r#"{"description": "d", "interactions": [{"interaction": "wave", "clip": "standing", "hold": 1}]}"#,
    )
    .unwrap();
    let out = echoctl(&["demo", "--scenario", file.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("unknown field `hold`"), "{err}");
    let out = echoctl(&["demo", "--scenario", "dance"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("unknown scenario 'dance'") && err.contains("walk-up"),
        "{err}"
    );
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

fn ok(out: &std::process::Output) -> String {
    assert!(
        out.status.success(),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The dataset layer from the command line: a dataset in the InterGen layout trains a
/// forecaster for two epochs and evaluates it on its own test split; statistics compare two
/// specs; a real two-person BVH capture evaluates with --bvh-pair; a wrong spec is named.
#[test]
fn data_specs_train_and_evaluate_end_to_end() {
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path().to_path_buf();
    let ig = dir.join("ig");
    ok(&echoctl(&[
        "data",
        "export",
        "--format",
        "intergen",
        "--split",
        "train",
        "--clips",
        "14",
        "--out",
        ig.to_str().unwrap(),
    ]));
    let ids = |r: std::ops::Range<usize>| r.map(|i| i.to_string()).collect::<Vec<_>>().join("\n");
    std::fs::write(ig.join("split/train.txt"), ids(0..10)).unwrap();
    std::fs::write(ig.join("split/val.txt"), ids(10..12)).unwrap();
    std::fs::write(ig.join("split/test.txt"), ids(12..14)).unwrap();
    let spec = format!("intergen:{}", ig.display());
    let stem = dir.join("m");
    let text = ok(&echoctl(&[
        "train",
        "forecaster",
        "--data",
        &spec,
        "--variant",
        "no-text",
        "--d-model",
        "16",
        "--epochs",
        "2",
        "--max-minutes",
        "3",
        "--out",
        stem.to_str().unwrap(),
    ]));
    assert!(text.contains("training windows"), "{text}");
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(stem.with_extension("json")).unwrap()).unwrap();
    assert_eq!(meta["training"]["data"], spec.as_str());
    let json = dir.join("eval.json");
    let text = ok(&echoctl(&[
        "eval",
        "--data",
        &spec,
        "--model",
        stem.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]));
    assert!(text.contains("| m |"), "{text}");
    let reports: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(reports.as_array().unwrap().len(), 3);
    assert!(reports[2]["overall"]["jpe"][0]
        .as_f64()
        .unwrap()
        .is_finite());
    // Statistics of two specs side by side.
    let text = ok(&echoctl(&[
        "data",
        "stats",
        "--data",
        "synthetic:26",
        "--vs",
        &spec,
    ]));
    assert!(
        text.contains("| root speed m/s") && text.contains(&spec),
        "{text}"
    );
    // A wrong spec is named.
    let out = echoctl(&["eval", "--data", "mocap:x"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown source 'mocap'"));
    // A real capture, when the shared data is beside the repository.
    let cmu = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/cmu");
    if cmu.join("18_01.bvh").is_file() {
        let json = dir.join("real.json");
        let text = ok(&echoctl(&[
            "eval",
            "--bvh-pair",
            cmu.join("18_01.bvh").to_str().unwrap(),
            cmu.join("19_01.bvh").to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ]));
        assert!(text.contains("calibration"), "{text}");
        let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        assert_eq!(r[0]["overall"]["windows"], 8);
        // Zero velocity 1.0 s ahead on this capture, as measured independently: 135.9 mm.
        let zv = r[0]["overall"]["jpe"][2].as_f64().unwrap();
        assert!((zv - 135.9).abs() < 0.5, "{zv}");
    }
    // The repository's own real capture: a take that starts mid-squat still loads.
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/cmu");
    let json = dir.join("squats.json");
    ok(&echoctl(&[
        "eval",
        "--bvh-pair",
        data.join("22_14.bvh").to_str().unwrap(),
        data.join("23_14.bvh").to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]));
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(r[0]["overall"]["windows"], 59);
}

#[test]
fn shipped_models_are_found_outside_the_repository() {
    // From an unrelated directory, `models/forecaster` resolves to the checkout's models (the
    // binary lives in its target/); with ECHO_MODELS pointing nowhere useful it still does,
    // and a name that exists nowhere is an error that says where it looked.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("f.onnx");
    let run = |model: &str| {
        Command::new(env!("CARGO_BIN_EXE_echoctl"))
            .args(["export", "onnx", "--model", model, "--out"])
            .arg(&out)
            .current_dir(dir.path())
            .env("ECHO_MODELS", dir.path())
            .output()
            .expect("run echoctl")
    };
    let ok = run("models/forecaster");
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    assert!(out.is_file());
    let missing = run("models/no-such-model");
    assert!(!missing.status.success());
    let err = String::from_utf8_lossy(&missing.stderr);
    assert!(
        err.contains("not found") && err.contains("ECHO_MODELS"),
        "{err}"
    );
}
