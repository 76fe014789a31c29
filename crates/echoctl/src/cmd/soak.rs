//! `echoctl soak`: several robots at 15 Hz through the whole pipeline for a long time; fails when
//! memory grows or deadlines are missed beyond the stated bounds, and reports latency percentiles.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Result;

use super::fleet::{med_p99, run, FleetOptions, FleetReport};

/// Options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Robots served by one forecaster (each with its own bridge and safety service).
    #[arg(long, default_value_t = 4)]
    pub robots: usize,
    /// Measured seconds (≥ 600 for the long test).
    #[arg(long, default_value_t = 600.0)]
    pub seconds: f64,
    /// Forecaster checkpoint.
    #[arg(long, default_value = "models/hri")]
    pub model: PathBuf,
    /// Forecaster backend.
    #[arg(long, value_enum, default_value_t = forecaster::BackendKind::Candle)]
    pub backend: forecaster::BackendKind,
    /// Largest resident-memory growth allowed per process, MiB.
    #[arg(long, default_value_t = 32.0)]
    pub max_rss_growth_mib: f64,
    /// Largest share of forecasts followed by a gap beyond the plan deadline.
    #[arg(long, default_value_t = 0.01)]
    pub max_missed_rate: f64,
    /// Write the full report as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the services' logs here and keep them (default: a temporary directory, removed
    /// after a run that succeeded).
    #[arg(long)]
    pub log_dir: Option<PathBuf>,
}

/// Growth of a memory series: mean of the last third minus mean of the first third.
pub fn growth(series: &[(f64, f64)]) -> f64 {
    if series.len() < 3 {
        return 0.0;
    }
    let k = series.len() / 3;
    let mean = |s: &[(f64, f64)]| s.iter().map(|(_, m)| m).sum::<f64>() / s.len() as f64;
    mean(&series[series.len() - k..]) - mean(&series[..k])
}

/// Run the soak and judge it.
pub async fn run_soak(args: Args) -> Result<()> {
    let every = Duration::from_secs_f64((args.seconds / 30.0).clamp(0.5, 20.0));
    let log_dir = args
        .log_dir
        .clone()
        .unwrap_or_else(|| std::env::temp_dir().join(format!("echo-soak-{}", std::process::id())));
    let r: FleetReport = run(&FleetOptions {
        robots: args.robots.max(1),
        with_safety: args.robots.max(1),
        seconds: args.seconds,
        model: args.model.clone(),
        backend: args.backend,
        log_dir: log_dir.clone(),
        rss_every: Some(every),
    })
    .await?;
    let missed_rate = r.missed_deadlines as f64 / (r.forecasts.max(1) as f64);
    println!(
        "soak: {} robots, {:.0} s, {} frames, {} forecasts",
        r.robots, args.seconds, r.frames_sent, r.forecasts
    );
    println!(
        "latency median / p99 ms: perception→skeletons {}, perception→forecast {}, inference {}, perception→command {}",
        med_p99(&r.to_humans_ms),
        med_p99(&r.to_forecast_ms),
        med_p99(&r.inference_ms),
        med_p99(&r.to_command_ms)
    );
    println!(
        "missed deadlines (a robot > 200 ms without a forecast): {} ({:.3} % of forecasts, bound {:.3} %)",
        r.missed_deadlines,
        missed_rate * 100.0,
        args.max_missed_rate * 100.0
    );
    let mut worst = (String::new(), f64::NEG_INFINITY);
    for (p, s) in &r.rss_mib {
        // Memory after warm-up only.
        let after: Vec<(f64, f64)> = s.iter().copied().filter(|(t, _)| *t >= 5.0).collect();
        let g = growth(&after);
        println!(
            "  {p:<24} RSS {:.1} → {:.1} MiB (growth {g:+.1})",
            after.first().map(|x| x.1).unwrap_or(0.0),
            after.last().map(|x| x.1).unwrap_or(0.0)
        );
        if g > worst.1 {
            worst = (p.clone(), g);
        }
    }
    if let Some(p) = &args.json {
        let mut v = serde_json::to_value(&r)?;
        v["missed_rate"] = missed_rate.into();
        v["seconds"] = args.seconds.into();
        std::fs::write(p, serde_json::to_vec(&v)?)?;
    }
    if let Err(e) = judge(&args, &r, missed_rate, &worst) {
        anyhow::bail!("{e} (logs in {})", log_dir.display());
    }
    if args.log_dir.is_none() {
        let _ = std::fs::remove_dir_all(&log_dir);
    }
    println!("soak passed");
    Ok(())
}

/// The soak's bounds: memory growth of the worst process, missed deadlines, any forecast at all.
fn judge(args: &Args, r: &FleetReport, missed_rate: f64, worst: &(String, f64)) -> Result<()> {
    anyhow::ensure!(
        worst.1 <= args.max_rss_growth_mib,
        "{} grew {:.1} MiB (bound {:.1})",
        worst.0,
        worst.1,
        args.max_rss_growth_mib
    );
    anyhow::ensure!(
        missed_rate <= args.max_missed_rate,
        "missed-deadline rate {:.3} % above the bound {:.3} %",
        missed_rate * 100.0,
        args.max_missed_rate * 100.0
    );
    anyhow::ensure!(r.forecasts > 0, "no forecasts at all");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::growth;

    #[test]
    fn growth_compares_the_last_third_with_the_first() {
        let flat: Vec<(f64, f64)> = (0..9).map(|i| (i as f64, 100.0)).collect();
        assert_eq!(growth(&flat), 0.0);
        let leak: Vec<(f64, f64)> = (0..9)
            .map(|i| (i as f64, 100.0 + 10.0 * i as f64))
            .collect();
        assert!((growth(&leak) - 60.0).abs() < 1e-9);
        assert_eq!(growth(&[(0.0, 1.0)]), 0.0);
    }
}
