//! The short soak (CI): three robots at 15 Hz through bridges, one forecaster and three safety
//! services, as separate processes, for 20 s. `echoctl soak` itself judges memory growth
//! (≤ 32 MiB per process) and missed plan deadlines; the debug build on a shared CI machine gets
//! a 5 % bound, the long release soak (scripts/soak, 10 min) the default 1 %.

use std::process::Command;

#[test]
fn short_soak_keeps_memory_and_deadlines() -> anyhow::Result<()> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let scratch = tempfile::tempdir()?;
    let json = scratch.path().join("soak.json");
    let out = Command::new(echo_system_tests::binary("echoctl")?)
        .current_dir(&root)
        .args([
            "soak",
            "--robots",
            "3",
            "--seconds",
            "20",
            "--max-missed-rate",
            "0.05",
            "--json",
            json.to_str().unwrap(),
        ])
        .env("RUST_LOG", "error")
        .output()?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!("{text}");
    assert!(out.status.success(), "soak failed:\n{text}");
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json)?)?;
    // 3 robots × 15 Hz × 20 s, most of them forecast.
    assert!(v["frames_sent"].as_u64().unwrap() > 800);
    assert!(v["forecasts"].as_u64().unwrap() > 600);
    assert_eq!(v["rss_mib"].as_object().unwrap().len(), 7);
    Ok(())
}
