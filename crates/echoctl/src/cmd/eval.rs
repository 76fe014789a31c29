//! `echoctl eval`: score predictors on a split the way the paper does.

use std::path::PathBuf;

use anyhow::{anyhow, Result};
use echo_eval::harness::{markdown_per_kind, markdown_responder, markdown_table};
use echo_eval::window::{horizon_frame, windows, ConstantVelocity, ZeroVelocity, HORIZONS_S};
use echo_eval::{evaluate, Predictor, Report, Symmetrized};
use echo_motion::synth::{generate_split, Split, KINDS};
use echo_train::CheckpointPredictor;

use super::data::progress;

/// Options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Split: test or held-out (or train, val).
    #[arg(long, default_value = "test")]
    pub split: String,
    /// Clips per interaction type.
    #[arg(long, default_value_t = 40)]
    pub clips_per_kind: u64,
    /// Predictor: zero-velocity, constant-velocity or all.
    #[arg(long, default_value = "all")]
    pub baseline: String,
    /// Window stride, frames at 15 Hz (default: 8 for generated clips, 1 for real captures,
    /// which are few).
    #[arg(long)]
    pub stride: Option<usize>,
    /// Also score trained forecaster checkpoints (stems of .safetensors/.json; repeatable;
    /// named by the file stem in the tables).
    #[arg(long)]
    pub model: Vec<PathBuf>,
    /// Write the reports as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Evaluate a retargeter checkpoint instead (limb-direction angles on the split's poses).
    #[arg(long)]
    pub retargeter: Option<PathBuf>,
    /// With --retargeter: also evaluate on the poses of this BVH file.
    #[arg(long)]
    pub bvh: Option<PathBuf>,
    /// BVH joint map: cmu (31-joint CMU skeleton) or echo (Echo's own export).
    #[arg(long, default_value = "cmu")]
    pub bvh_map: String,
    /// BVH units in metres (CMU: 0.0564; Echo's export: 1).
    #[arg(long, default_value_t = 0.0564)]
    pub bvh_scale: f64,
    /// With --retargeter: draw human and retargeted robot side by side (PNG).
    #[arg(long)]
    pub render: Option<PathBuf>,
    /// Evaluate human–robot (HRI) forecaster checkpoints (repeatable) on the split's
    /// interactions with person B retargeted onto the robot (the paper's Table 4).
    #[arg(long)]
    pub hri: Vec<PathBuf>,
    /// Retargeter for --hri.
    #[arg(long, default_value = "models/retargeter")]
    pub with_retargeter: PathBuf,
    /// Evaluate on a data spec's test split instead of the generator's (docs/DATA.md), e.g.
    /// `cmu:data/cmu` or `bvh:A.bvh+B.bvh@TEXT`; a `bvh:` item is evaluated whole.
    #[arg(long, conflicts_with = "bvh_pair")]
    pub data: Option<String>,
    /// Evaluate on one real two-person capture: person A's and person B's BVH files (CMU
    /// skeleton; one capture volume and clock). Windows at stride 1 unless --stride is given.
    #[arg(long, num_args = 2, value_names = ["A_BVH", "B_BVH"])]
    pub bvh_pair: Option<Vec<PathBuf>>,
    /// The description given to text-conditioned models with --bvh-pair.
    #[arg(long)]
    pub prompt: Option<String>,
    /// Also score each --model symmetrized: its forecasts of the scene, its mirror image and
    /// with the roles exchanged, averaged (`echo_eval::symmetry`; for descriptions that name no
    /// role or side, such as real captures' prompts).
    #[arg(long)]
    pub symmetric: bool,
    /// Also score damped-velocity extrapolation with this time constant, s (repeatable).
    #[arg(long)]
    pub damped_tau: Vec<f64>,
}

/// Windows of `--data` / `--bvh-pair` (test split, no augmentation), with a description line.
fn spec_windows(args: &Args) -> Result<Option<(Vec<echo_eval::window::Window>, String)>> {
    let spec = match (&args.data, &args.bvh_pair) {
        (Some(d), _) => d.clone(),
        (None, Some(files)) => format!(
            "bvh:{}+{}{}",
            files[0].display(),
            files[1].display(),
            args.prompt
                .as_ref()
                .map(|p| format!("@{p}"))
                .unwrap_or_default()
        ),
        (None, None) => return Ok(None),
    };
    let parsed = echo_data::Spec::parse(&spec)?;
    let per = echo_data::captures(
        &parsed,
        echo_motion::synth::Split::Test,
        args.clips_per_kind * KINDS.len() as u64 * 20,
    )?;
    let real_stride = args.stride.unwrap_or(1);
    let per: Vec<_> = per
        .into_iter()
        .map(|(mut it, c)| {
            it.weight = None;
            (it, c)
        })
        .collect();
    let w = echo_data::windows(
        &per,
        &echo_data::Cut {
            stride: args.stride.unwrap_or(8),
            real_stride,
            augment: echo_data::augment::Augment::NONE,
            seed: 0,
        },
    );
    let mut desc = vec![];
    for (_, caps) in &per {
        for c in caps {
            let r = c
                .report
                .as_ref()
                .map(|r| format!(" ({})", r.notes.join("; ")))
                .unwrap_or_default();
            desc.push(format!(
                "{} [{}] {:.1} s{r}",
                c.name,
                c.source,
                c.clip.frames.len() as f64 / echo_motion::synth::FPS
            ));
        }
    }
    anyhow::ensure!(
        !w.is_empty(),
        "{spec}: no evaluation windows (a capture needs at least 2.07 s of motion)"
    );
    Ok(Some((w, format!("data {spec}: {}", desc.join(", ")))))
}

fn hri(args: &Args, split: Split) -> Result<()> {
    use echo_hri::eval::{
        evaluate as score, human_baselines, human_forecast, markdown, markdown_human,
        model_forecasts, reference, zero_velocity,
    };
    let model = echo_robot::RobotModel::tiago_dual();
    let body = echo_robot::collision::RobotBody::tiago(&model)?;
    let r = echo_retarget::Retargeter::load(&args.with_retargeter, model.clone())?;
    let n = args.clips_per_kind * KINDS.len() as u64;
    let ws = super::train::hri_windows(split, n, args.stride.unwrap_or(8), &r)?;
    let refs: Vec<&echo_hri::data::HriWindow> = ws.iter().collect();
    let mut reports = vec![
        score(
            "retargeted reference",
            &refs,
            &reference(&refs),
            &r,
            &model,
            &body,
        )?,
        score(
            "zero-velocity",
            &refs,
            &zero_velocity(&refs),
            &r,
            &model,
            &body,
        )?,
    ];
    let mut humans = vec![];
    for stem in &args.hri {
        let ck = echo_models::Checkpoint::load(stem, &candle_core::Device::Cpu)?;
        let frozen = ck
            .meta
            .hri_training
            .clone()
            .and_then(|t| serde_json::from_value::<echo_hri::train::HriTrainConfig>(t).ok())
            .is_some_and(|t| t.frozen_retargeter);
        let codec = frozen.then(|| echo_hri::codec::RobotCodec::new(&r));
        let mut fc = vec![];
        for chunk in refs.chunks(64) {
            fc.extend(model_forecasts(
                &ck.model,
                ck.text.as_ref(),
                chunk,
                codec.as_ref(),
            )?);
        }
        let name = stem
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        reports.push(score(&name, &refs, &fc, &r, &model, &body)?);
        humans.push(human_forecast(
            &name,
            &refs,
            &ck.model,
            ck.text.as_ref(),
            codec.as_ref(),
        )?);
    }
    println!(
        "split {} — {} HRI windows (observe 0.53 s, predict 1.0 s at 15 Hz); robot errors in mm against the retargeted reference, F1 against the original human pair\n",
        args.split,
        ws.len()
    );
    println!("{}", markdown(&reports));
    // The model's other agent: the partner's forecast, against the two baselines.
    if !humans.is_empty() {
        humans.splice(0..0, human_baselines(&refs));
        println!("the partner (human agent), errors in mm against what the person did\n");
        println!("{}", markdown_human(&humans));
    }
    if let Some(p) = &args.json {
        let v = serde_json::json!({ "robot": reports, "human": humans });
        std::fs::write(p, serde_json::to_vec_pretty(&v)?)?;
    }
    Ok(())
}

fn retargeter(args: &Args, stem: &std::path::Path, split: Split) -> Result<()> {
    use echo_retarget::eval::{evaluate_constant, Evaluation};
    use echo_retarget::train::HumanSet;
    let model = echo_robot::RobotModel::tiago_dual();
    let r = echo_retarget::Retargeter::load(stem, model.clone())?;
    let n = args.clips_per_kind * KINDS.len() as u64;
    let set = HumanSet::from_split(split, 0..n, 3);
    let home = echo_retarget::net::home_arms();
    let mut rows: Vec<(String, Evaluation)> = vec![
        (
            "robot home pose (constant)".into(),
            evaluate_constant(&model, &set, &home)?,
        ),
        (
            format!("retargeter ({})", stem.display()),
            echo_retarget::eval::evaluate(r.net(), &model, &set)?,
        ),
    ];
    if let Some(b) = &args.bvh {
        let map = match args.bvh_map.as_str() {
            "cmu" => echo_motion::bvh::cmu_map(),
            "echo" => echo_motion::bvh::echo_map(),
            other => anyhow::bail!("--bvh-map must be cmu or echo, not '{other}'"),
        };
        let bvh = echo_motion::bvh::Bvh::read(b)?;
        let frames =
            echo_motion::bvh::to_smpl(&bvh, &map, args.bvh_scale, 15.0, &b.display().to_string())?;
        let mut bset = HumanSet {
            features: vec![],
            directions: vec![],
            n: 0,
        };
        for f in &frames {
            bset.push(f);
        }
        rows.push((
            format!("retargeter on {}", b.display()),
            echo_retarget::eval::evaluate(r.net(), &model, &bset)?,
        ));
    }
    println!(
        "split {} — {} poses (every 3rd frame of both people), limb-direction angle in degrees\n",
        args.split, set.n
    );
    println!("| method | poses | L upper arm | L forearm | R upper arm | R forearm | mean | median pose | within limits | poses/s |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (name, e) in &rows {
        println!(
            "| {name} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} % | {:.0} |",
            e.poses,
            e.limb_deg[0],
            e.limb_deg[1],
            e.limb_deg[2],
            e.limb_deg[3],
            e.mean_deg,
            e.median_deg,
            e.within_limits * 100.0,
            e.poses_per_s
        );
    }
    if let Some(png) = &args.render {
        render_retarget(&r, &model, split, png)?;
        println!("\nrendered {}", png.display());
    }
    Ok(())
}

/// Human (blue, in its body frame) and the retargeted robot (orange), front view, for poses of
/// a wave, a handshake, a handover, the imitation game and a hug.
fn render_retarget(
    r: &echo_retarget::Retargeter,
    model: &echo_robot::RobotModel,
    split: Split,
    png: &std::path::Path,
) -> Result<()> {
    use echo_eval::render::{front_views, skeleton_segments, Figure};
    use echo_motion::synth::generate;
    use nalgebra::Vector3;
    let mut panels = vec![];
    // (clip index in the split: types cycle through KINDS, frame as a share of the clip)
    for (i, at) in [(1u64, 0.55), (0, 0.6), (3, 0.55), (9, 0.5), (4, 0.6)] {
        let clip = generate(&split.clip(i));
        let f = ((clip.frames.len() as f64) * at) as usize;
        let who = if i == 9 { 0 } else { 1 };
        let p = clip.joints(f.min(clip.frames.len() - 1), who);
        let Some(rot) = echo_retarget::human::body_frame(&p) else {
            continue;
        };
        let o = Vector3::new(p[0].x, p[0].y, 0.0);
        let human: [Vector3<f64>; 22] =
            std::array::from_fn(|k| rot * (p[k] - o) + Vector3::new(0.0, 0.55, 0.0));
        let Some(pose) = r.retarget(&[p])?.pop().flatten() else {
            continue;
        };
        let q = model.values_from(
            pose.names
                .iter()
                .map(|s| s.as_str())
                .zip(pose.positions.iter().copied()),
        )?;
        let at = |f: &str| -> Result<Vector3<f64>> {
            Ok(model.fk(&q, f)?.translation.vector + Vector3::new(0.0, -0.55, 0.0))
        };
        let mut robot = vec![];
        for chain in [
            vec!["base_footprint", "torso_lift_link", "head_2_link"],
            vec![
                "torso_lift_link",
                "arm_left_1_link",
                "arm_left_3_link",
                "arm_left_4_link",
                "arm_left_6_link",
                "gripper_left_grasping_frame",
            ],
            vec![
                "torso_lift_link",
                "arm_right_1_link",
                "arm_right_3_link",
                "arm_right_4_link",
                "arm_right_6_link",
                "gripper_right_grasping_frame",
            ],
        ] {
            for w in chain.windows(2) {
                robot.push((at(w[0])?, at(w[1])?));
            }
        }
        panels.push(vec![
            Figure {
                segments: skeleton_segments(&human),
                rgb: [30, 90, 200],
            },
            Figure {
                segments: robot,
                rgb: [220, 110, 20],
            },
        ]);
    }
    front_views(png, &panels, 110.0).map_err(anyhow::Error::msg)
}

/// Evaluate and print the table.
pub fn run(args: Args) -> Result<()> {
    let split = Split::parse(&args.split)
        .ok_or_else(|| anyhow!("--split must be train, val, test or held-out"))?;
    if let Some(stem) = &args.retargeter {
        return retargeter(&args, stem, split);
    }
    if !args.hri.is_empty() {
        return hri(&args, split);
    }
    let mut predictors: Vec<Box<dyn Predictor>> = match args.baseline.as_str() {
        "zero-velocity" => vec![Box::new(ZeroVelocity)],
        "constant-velocity" => vec![Box::new(ConstantVelocity)],
        "all" => vec![Box::new(ZeroVelocity), Box::new(ConstantVelocity)],
        other => anyhow::bail!(
            "--baseline must be zero-velocity, constant-velocity or all, not '{other}'"
        ),
    };
    for &tau_s in &args.damped_tau {
        predictors.push(Box::new(echo_eval::DampedVelocity { tau_s }));
    }
    let (w, what) = match spec_windows(&args)? {
        Some(x) => x,
        None => {
            let n = args.clips_per_kind * KINDS.len() as u64;
            let pb = progress(n, "generating");
            let clips = generate_split(split, 0..n, 2, &|| pb.inc(1));
            pb.finish_and_clear();
            let w: Vec<_> = clips
                .iter()
                .flat_map(|c| windows(c, args.stride.unwrap_or(8)))
                .collect();
            (w, format!("split {} — {} clips", args.split, clips.len()))
        }
    };
    let mut reports: Vec<Report> = predictors
        .iter_mut()
        .map(|p| evaluate(p.as_mut(), &w, 64))
        .collect();
    for stem in &args.model {
        let ck = echo_models::Checkpoint::load(stem, &candle_core::Device::Cpu)?;
        // The table's horizons need 1.5 s of two people; a human–robot model forecasts a robot.
        if ck.meta.hri_training.is_some() {
            anyhow::bail!(
                "{}: a human–robot checkpoint (agent B is the robot); evaluate it with --hri",
                stem.display()
            );
        }
        let need = horizon_frame(HORIZONS_S[HORIZONS_S.len() - 1]);
        if ck.meta.model.pred < need {
            anyhow::bail!(
                "{}: predicts {} frames; this table needs {need} (1.5 s at 15 Hz)",
                stem.display(),
                ck.meta.model.pred
            );
        }
        let name = stem
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| stem.display().to_string());
        reports.push(evaluate(&mut ck.predictor(&name), &w, 64));
        if args.symmetric {
            reports.push(evaluate(&mut Symmetrized(ck.predictor(&name)), &w, 16));
        }
    }
    println!(
        "{what}; {} windows (observe 0.53 s, predict 1.53 s at 15 Hz), errors in mm\n",
        w.len()
    );
    println!("{}", markdown_table(&reports));
    println!(
        "{}",
        markdown_per_kind(
            &reports,
            &["wave", "bow", "imitation", "handover", "handshake"]
        )
    );
    println!(
        "{}",
        markdown_responder(&reports, &["wave", "bow", "imitation", "handover"])
    );
    for r in &reports {
        println!("{}: {:.0} windows/s", r.predictor, r.windows_per_s);
    }
    if let Some(p) = &args.json {
        std::fs::write(p, serde_json::to_vec_pretty(&reports)?)?;
    }
    Ok(())
}
