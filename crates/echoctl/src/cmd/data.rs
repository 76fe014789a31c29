//! `echoctl data`: generate, describe and export interaction datasets.

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{anyhow, Result};
use clap::Subcommand;
use echo_eval::Predictor;
use echo_motion::sensors::contact_and_proximity;
use echo_motion::skeleton::{j, NUM_JOINTS, PARENTS};
use echo_motion::synth::{generate_split, Clip, Split, FPS};
use echo_train::CheckpointPredictor;
use indicatif::{ProgressBar, ProgressStyle};

/// Data verbs.
#[derive(Debug, Clone, Subcommand)]
pub enum Verb {
    /// Generate synthetic interactions in Echo's format.
    Gen {
        /// Split: train, val, test, held-out.
        #[arg(long, default_value = "train")]
        split: String,
        /// Number of clips (types cycle through all 13).
        #[arg(long, default_value_t = 20_000)]
        clips: u64,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// Worker threads.
        #[arg(long, default_value_t = 2)]
        threads: usize,
    },
    /// Draw an interaction (both people; with --predict, ground truth vs prediction) as an
    /// animated GIF, numbered PNGs, or a strip of frames.
    Render {
        /// Interaction type, e.g. handshake, wave, hug (snake_case).
        #[arg(long, required_unless_present = "data", default_value = "")]
        kind: String,
        /// Draw the first capture of this data spec instead of a generated clip (docs/DATA.md),
        /// e.g. a real pair `bvh:A.bvh+B.bvh@TEXT`.
        #[arg(long)]
        data: Option<String>,
        /// Split to draw the clip from.
        #[arg(long, default_value = "test")]
        split: String,
        /// Which clip of that type (0, 1, …).
        #[arg(long, default_value_t = 0)]
        index: u64,
        /// Output: `x.gif` (animation), `x.png` with --strip (one image), else `x_NNN.png` frames.
        #[arg(long)]
        out: PathBuf,
        /// One image with this many frames side by side.
        #[arg(long)]
        strip: Option<usize>,
        /// Overlay a forecast (zero-velocity, constant-velocity, or a forecaster checkpoint stem
        /// such as models/forecaster) for the window
        /// starting at --at.
        #[arg(long)]
        predict: Option<String>,
        /// Window start for --predict, frames at 15 Hz.
        #[arg(long, default_value_t = 16)]
        at: usize,
    },
    /// Export generated clips to the InterGen layout or to BVH files (one per person).
    Export {
        /// intergen or bvh.
        #[arg(long)]
        format: String,
        /// Split to generate.
        #[arg(long, default_value = "test")]
        split: String,
        /// Number of clips.
        #[arg(long, default_value_t = 26)]
        clips: u64,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
    },
    /// Per-type statistics of a split (generated on the fly) or of a dataset directory.
    Stats {
        /// Split to generate and describe.
        #[arg(long, default_value = "test")]
        split: String,
        /// Clips per interaction type.
        #[arg(long, default_value_t = 20)]
        clips_per_kind: u64,
        /// Describe this dataset directory instead.
        #[arg(long)]
        dir: Option<PathBuf>,
        /// Motion statistics of a data spec (docs/DATA.md; all of its splits), side by side
        /// with every --vs spec: root speed and acceleration, joint speed, arm swing,
        /// inter-person distance, contact rate.
        #[arg(long)]
        data: Option<String>,
        /// A spec to compare with --data (repeatable).
        #[arg(long)]
        vs: Vec<String>,
        /// With --data: write the statistics as JSON here.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Turn human–human interactions into human–robot ones (person B becomes TIAGo++ through
    /// the retargeter), report their social agreement with the original pairs, and optionally
    /// write them.
    Hri {
        /// Split to convert.
        #[arg(long, default_value = "test")]
        split: String,
        /// Clips per interaction type.
        #[arg(long, default_value_t = 10)]
        clips_per_kind: u64,
        /// Retargeter checkpoint.
        #[arg(long, default_value = "models/retargeter")]
        retargeter: PathBuf,
        /// Write the HRI dataset here (hri.safetensors + meta.json).
        #[arg(long)]
        out: Option<PathBuf>,
    },
}

fn hri(
    split: &str,
    per_kind: u64,
    stem: &std::path::Path,
    out: Option<&std::path::Path>,
) -> Result<()> {
    use echo_retarget::hri::{convert, social_scores, write, SocialScores};
    let split = Split::parse(split)
        .ok_or_else(|| anyhow!("--split must be train, val, test or held-out"))?;
    let model = echo_robot::RobotModel::tiago_dual();
    let body = echo_robot::collision::RobotBody::tiago(&model)?;
    let r = echo_retarget::Retargeter::load(stem, model.clone())?;
    let n = per_kind * echo_motion::synth::KINDS.len() as u64;
    let pb = progress(n, "converting");
    let clips = generate_split(split, 0..n, 2, &|| {});
    let mut by_kind: std::collections::BTreeMap<String, SocialScores> = Default::default();
    let mut all = vec![];
    for c in &clips {
        let h = convert(c, &r)?;
        let s = social_scores(&h, &r, &model, &body, 3)?;
        let e = by_kind.entry(h.kind.clone()).or_default();
        for (a, b) in [(&mut e.contact, s.contact), (&mut e.proximity, s.proximity)] {
            a.tp += b.tp;
            a.fp += b.fp;
            a.fn_ += b.fn_;
            a.tn += b.tn;
        }
        e.hand_error_m += s.hand_error_m * s.frames as f64;
        e.frames += s.frames;
        all.push(h);
        pb.inc(1);
    }
    pb.finish_and_clear();
    println!("| type | frames | F1 contact | F1 proximity | gripper–reference wrist m |");
    println!("|---|---|---|---|---|");
    let f = |x: Option<f64>| x.map(|v| format!("{v:.2}")).unwrap_or_else(|| "–".into());
    for (k, s) in &by_kind {
        println!(
            "| {k} | {} | {} | {} | {:.3} |",
            s.frames,
            f(s.contact.f1()),
            f(s.proximity.f1()),
            s.hand_error_m / s.frames.max(1) as f64
        );
    }
    if let Some(dir) = out {
        write(dir, &all, &r, &stem.display().to_string())?;
        println!("wrote {} clips to {}", all.len(), dir.display());
    }
    Ok(())
}

/// A progress bar with rate and ETA.
pub fn progress(n: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(n);
    pb.set_style(
        ProgressStyle::with_template(&format!(
            "{what} {{bar:40}} {{pos}}/{{len}} {{per_sec}} eta {{eta}}"
        ))
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb
}

/// Run a data verb.
pub fn run(verb: Verb) -> Result<()> {
    match verb {
        Verb::Hri {
            split,
            clips_per_kind,
            retargeter,
            out,
        } => hri(&split, clips_per_kind, &retargeter, out.as_deref()),
        Verb::Gen {
            split,
            clips,
            out,
            threads,
        } => {
            let split = Split::parse(&split)
                .ok_or_else(|| anyhow!("--split must be train, val, test or held-out"))?;
            let pb = progress(clips, "generating");
            let started = std::time::Instant::now();
            let data = generate_split(split, 0..clips, threads, &|| pb.inc(1));
            pb.finish();
            let secs = started.elapsed().as_secs_f64();
            echo_motion::dataset::write(&out, &data)?;
            println!(
                "{} clips ({:.1} s of motion each on average) in {secs:.1} s: {:.0} clips/s on {threads} threads → {}",
                data.len(),
                data.iter().map(Clip::duration).sum::<f64>() / data.len().max(1) as f64,
                data.len() as f64 / secs.max(1e-9),
                out.display()
            );
            Ok(())
        }
        Verb::Export {
            format,
            split,
            clips,
            out,
        } => {
            let split_v = Split::parse(&split)
                .ok_or_else(|| anyhow!("--split must be train, val, test or held-out"))?;
            let pb = progress(clips, "generating");
            let data = generate_split(split_v, 0..clips, 2, &|| pb.inc(1));
            pb.finish_and_clear();
            match format.as_str() {
                "intergen" => {
                    let ids: Vec<usize> = (0..data.len()).collect();
                    echo_motion::intergen::export(&out, &data, &[(split.as_str(), ids)])?;
                }
                "bvh" => {
                    std::fs::create_dir_all(&out)?;
                    for (i, c) in data.iter().enumerate() {
                        for p in 0..2 {
                            let frames: Vec<_> =
                                (0..c.frames.len()).map(|f| c.joints(f, p)).collect();
                            std::fs::write(
                                out.join(format!("{i:05}_person{}.bvh", p + 1)),
                                echo_motion::bvh::write(&frames, FPS),
                            )?;
                        }
                    }
                }
                other => anyhow::bail!("--format must be intergen or bvh, not '{other}'"),
            }
            println!("exported {} clips to {}", data.len(), out.display());
            Ok(())
        }
        Verb::Render {
            kind,
            split,
            index,
            data,
            out,
            strip,
            predict,
            at,
        } => render(
            &kind,
            &split,
            index,
            data.as_deref(),
            &out,
            strip,
            predict.as_deref(),
            at,
        ),
        Verb::Stats {
            data: Some(spec),
            vs,
            json,
            clips_per_kind,
            ..
        } => {
            let mut sets = vec![];
            for text in std::iter::once(&spec).chain(&vs) {
                let parsed = echo_data::Spec::parse(text)?;
                let mut caps = vec![];
                for item in &parsed.items {
                    // A named BVH pair is the same capture in every split: count it once.
                    let splits: &[Split] = match item.source {
                        echo_data::Source::BvhPair { .. } => &[Split::Train],
                        _ => &[Split::Train, Split::Val, Split::Test],
                    };
                    for &split in splits {
                        caps.extend(echo_data::source::load(
                            &item.source,
                            split,
                            clips_per_kind * echo_motion::synth::KINDS.len() as u64,
                        )?);
                    }
                }
                sets.push((text.clone(), echo_data::stats::motion_stats(&caps)));
            }
            println!("{}", echo_data::stats::markdown(&sets));
            if let Some(p) = json {
                std::fs::write(&p, serde_json::to_vec_pretty(&sets)?)?;
            }
            Ok(())
        }
        Verb::Stats {
            split,
            clips_per_kind,
            dir,
            ..
        } => {
            let clips: Vec<Clip> = match dir {
                Some(d) => {
                    let ds = echo_motion::dataset::read(&d)?;
                    (0..ds.meta.clips.len())
                        .filter_map(|i| ds.clip(i))
                        .collect()
                }
                None => {
                    let split = Split::parse(&split)
                        .ok_or_else(|| anyhow!("--split must be train, val, test or held-out"))?;
                    let n = clips_per_kind * echo_motion::synth::KINDS.len() as u64;
                    let pb = progress(n, "generating");
                    let c = generate_split(split, 0..n, 2, &|| pb.inc(1));
                    pb.finish_and_clear();
                    c
                }
            };
            println!("{}", stats_table(&clips));
            Ok(())
        }
    }
}

#[derive(Default)]
struct KindStats {
    clips: usize,
    seconds: f64,
    speed_sum: f64,
    frames: usize,
    contact: usize,
    proximity: usize,
    skate: Vec<f64>,
    bone_dev: f64,
    delay_sum: f64,
}

/// Markdown table of per-type statistics.
pub fn stats_table(clips: &[Clip]) -> String {
    let mut per: BTreeMap<String, KindStats> = BTreeMap::new();
    for c in clips {
        let kind = serde_json::to_value(c.params.kind)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default();
        let s = per.entry(kind).or_default();
        s.clips += 1;
        s.seconds += c.duration();
        s.delay_sum += c.params.delay;
        let n = c.frames.len();
        let bones0: Vec<Vec<f64>> = (0..2)
            .map(|p| {
                let x = c.joints(0, p);
                (1..NUM_JOINTS)
                    .map(|k| (x[k] - x[PARENTS[k] as usize]).norm())
                    .collect()
            })
            .collect();
        for f in 0..n {
            let (a, b) = (c.joints(f, 0), c.joints(f, 1));
            let (ct, pr) = contact_and_proximity(&a, &b);
            s.contact += usize::from(ct);
            s.proximity += usize::from(pr);
            s.frames += 1;
            for (p, x) in [a, b].iter().enumerate() {
                for k in 1..NUM_JOINTS {
                    let l = (x[k] - x[PARENTS[k] as usize]).norm();
                    s.bone_dev = s.bone_dev.max((l - bones0[p][k - 1]).abs());
                }
            }
            if f > 0 {
                for p in 0..2 {
                    let (x0, x1) = (c.joints(f - 1, p), c.joints(f, p));
                    s.speed_sum += (x1[0] - x0[0]).xy().norm() * FPS;
                    // Foot skating: horizontal speed of the lower (stance) foot.
                    let foot = if x1[j::L_FOOT].z < x1[j::R_FOOT].z {
                        j::L_FOOT
                    } else {
                        j::R_FOOT
                    };
                    s.skate.push((x1[foot] - x0[foot]).xy().norm() * FPS);
                }
            }
        }
    }
    let mut out = String::from("| type | clips | mean s | mean root speed m/s | contact frames | proximity frames | mean reaction delay s | stance-foot speed p50 / p95 m/s | max bone-length change mm |\n|---|---|---|---|---|---|---|---|---|\n");
    for (k, s) in &mut per {
        s.skate.sort_by(f64::total_cmp);
        let q = |p: f64| {
            s.skate
                .get(((s.skate.len() as f64 - 1.0) * p) as usize)
                .copied()
                .unwrap_or(0.0)
        };
        out.push_str(&format!(
            "| {k} | {} | {:.1} | {:.2} | {:.0} % | {:.0} % | {:.2} | {:.2} / {:.2} | {:.3} |\n",
            s.clips,
            s.seconds / s.clips as f64,
            s.speed_sum / (2.0 * s.frames.max(1) as f64),
            100.0 * s.contact as f64 / s.frames.max(1) as f64,
            100.0 * s.proximity as f64 / s.frames.max(1) as f64,
            s.delay_sum / s.clips as f64,
            q(0.5),
            q(0.95),
            s.bone_dev * 1000.0,
        ));
    }
    out
}

#[allow(clippy::too_many_arguments)]
fn render(
    kind: &str,
    split: &str,
    index: u64,
    data: Option<&str>,
    out: &std::path::Path,
    strip: Option<usize>,
    predict: Option<&str>,
    at: usize,
) -> Result<()> {
    let split = Split::parse(split)
        .ok_or_else(|| anyhow!("--split must be train, val, test or held-out"))?;
    let clip = match data {
        Some(spec) => {
            let parsed = echo_data::Spec::parse(spec)?;
            echo_data::captures(&parsed, split, 26)?
                .into_iter()
                .flat_map(|(_, c)| c)
                .next()
                .ok_or_else(|| anyhow!("{spec}: no capture in the {split:?} split"))?
                .clip
        }
        None => {
            let kinds = echo_motion::synth::KINDS;
            let k = kinds
                .iter()
                .position(|x| {
                    serde_json::to_value(x)
                        .ok()
                        .and_then(|v| v.as_str().map(str::to_string))
                        .as_deref()
                        == Some(kind)
                })
                .ok_or_else(|| anyhow!("unknown --kind '{kind}'"))? as u64;
            echo_motion::synth::generate(&split.clip(k + index * kinds.len() as u64))
        }
    };
    println!("{}", clip.texts.join("\n"));
    let view = echo_eval::render::View::default();
    let (truth, pred) = match predict {
        None => {
            let frames: Vec<echo_eval::metrics::Frame> = (0..clip.frames.len())
                .step_by(2)
                .map(|f| vec![clip.joints(f, 0), clip.joints(f, 1)])
                .collect();
            (frames, None)
        }
        Some(name) => {
            let w = echo_eval::window::windows(&clip, 1);
            let w = w
                .get(at)
                .ok_or_else(|| anyhow!("--at {at}: the clip has {} windows", w.len()))?;
            let forecast = match name {
                "zero-velocity" => echo_eval::window::ZeroVelocity.predict(&[w]).remove(0),
                "constant-velocity" => echo_eval::window::ConstantVelocity.predict(&[w]).remove(0),
                // Any other name is a forecaster checkpoint stem.
                stem => {
                    let ck = echo_models::Checkpoint::load(
                        std::path::Path::new(stem),
                        &candle_core::Device::Cpu,
                    )
                    .map_err(|e| anyhow!("--predict {stem}: not a baseline, and {e}"))?;
                    ck.predictor("forecaster").predict(&[w]).remove(0)
                }
            };
            let mut truth = w.obs.clone();
            truth.extend(w.future.clone());
            let mut pr = w.obs.clone();
            pr.extend(forecast);
            (truth, Some(pr))
        }
    };
    match strip {
        Some(n) => echo_eval::render::strip(out, &truth, pred.as_deref(), 15.0, n, view)
            .map_err(anyhow::Error::msg)?,
        None => {
            let files = echo_eval::render::render(out, &truth, pred.as_deref(), 15.0, view)
                .map_err(anyhow::Error::msg)?;
            println!("wrote {} file(s)", files.len());
        }
    }
    Ok(())
}
