//! `echoctl train forecaster`: train the dual-agent forecaster (or one of its ablations) on
//! generated interactions; writes the checkpoint, the loss curve (CSV and PNG) and a resumable
//! state after every epoch.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use echo_eval::render::{chart, Curve, Panel};
use echo_models::model::ForecasterConfig;
use echo_models::{Checkpoint, CheckpointMeta};
use echo_text::SentenceEncoder;
use echo_train::train::{train, EpochLog, Progress, Run, TrainConfig};

use super::data::progress;

/// The paper's Table 3 rows, plus the single-agent variant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Variant {
    /// The full model.
    Full,
    /// Without the text token.
    NoText,
    /// Without the displacement baseline: the decoder outputs the future frames.
    NoBaseline,
    /// Tokens are DCT coefficients.
    Dct,
    /// Without the temporal MLP blocks.
    NoTempmlp,
    /// Sequential instead of interleaved cross-attention.
    Sequential,
    /// Without the individual loss L_self.
    NoIndLoss,
    /// No cross-attention at all: each agent forecast alone.
    SingleAgent,
}

impl Variant {
    /// Apply to the default architecture and training settings.
    pub fn apply(self, m: &mut ForecasterConfig, t: &mut TrainConfig) {
        match self {
            Variant::Full => {}
            Variant::NoText => m.text_dim = 0,
            Variant::NoBaseline => m.displacement = false,
            Variant::Dct => m.dct = true,
            Variant::NoTempmlp => m.temp_mlp = 0,
            Variant::Sequential => m.interleaved = false,
            Variant::NoIndLoss => t.w_self = 0.0,
            Variant::SingleAgent => {
                m.rounds = 0;
                // No cross-attention blocks to initialise.
                m.social_identity_init = false;
                t.w_interaction = 0.0;
            }
        }
    }
}

/// How the forecaster's cross-attention blocks are initialised.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SocialInit {
    /// Output layers at zero: each block starts as the identity.
    Identity,
    /// Random, like every other layer.
    Random,
}

/// Options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// What to train.
    #[arg(value_enum)]
    pub what: Trainable,
    /// HRI: how the interaction and imitation losses enter (none, fixed, adaptive).
    #[arg(long, default_value = "adaptive")]
    pub social: String,
    /// HRI: wrap the robot agent in the retargeter's frozen encoder and decoder.
    #[arg(long)]
    pub freeze_retargeter: bool,
    /// HRI: share of training windows (0–1) in which the robot's observed frames are held at
    /// the last one (a robot that stood still; the future is unchanged).
    #[arg(long, default_value_t = 0.0)]
    pub still_robot: f64,
    /// HRI: retargeter checkpoint that turns person B into the robot.
    #[arg(long, default_value = "models/retargeter")]
    pub retargeter: PathBuf,
    /// Retargeter: optimiser steps.
    #[arg(long, default_value_t = 3000)]
    pub steps: usize,
    /// Retargeter: weight of the limb-direction (FK) loss; 0 trains with the paper's losses only.
    #[arg(long, default_value_t = 1.0)]
    pub w_direction: f64,
    /// Output stem: writes <out>.safetensors, <out>.json, <out>.loss.csv, <out>.loss.png and
    /// the resumable state <out>.resume/.
    #[arg(long, default_value = "models/forecaster")]
    pub out: PathBuf,
    /// Model variant (ablations of the paper's Table 3).
    #[arg(long, value_enum, default_value_t = Variant::Full)]
    pub variant: Variant,
    /// Continue an interrupted run from <out>.resume/.
    #[arg(long)]
    pub resume: bool,
    /// Forecaster: fine-tune — start from this checkpoint's weights (stem of
    /// `<stem>.safetensors` + `<stem>.json`) with a fresh optimiser; its architecture replaces
    /// the architecture flags.
    #[arg(long, conflicts_with = "resume")]
    pub init: Option<PathBuf>,
    /// Forecaster: peak learning rate (after warm-up).
    #[arg(long, default_value_t = 1e-3)]
    pub lr: f64,
    /// Only redraw <out>.loss.png from <out>.loss.csv.
    #[arg(long)]
    pub replot: bool,
    /// Training clips.
    #[arg(long, default_value_t = 2600)]
    pub train_clips: u64,
    /// Wall-clock budget of this run, minutes.
    #[arg(long, default_value_t = 15.0)]
    pub max_minutes: f64,
    /// Epochs at most.
    #[arg(long, default_value_t = 30)]
    pub epochs: usize,
    /// Model width.
    #[arg(long, default_value_t = 64)]
    pub d_model: usize,
    /// Cross-attention rounds.
    #[arg(long, default_value_t = 2)]
    pub rounds: usize,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Forecaster: how the cross-attention (social) blocks start — identity (the model starts
    /// as the single-agent one and learns the partner's influence as a correction) or random.
    #[arg(long, value_enum, default_value_t = SocialInit::Identity)]
    pub social_init: SocialInit,
    /// Forecaster: weight of the interaction (distance-matrix) loss. Off by default: at the
    /// paper's 0.1 it costs the local pose more than it gives (docs/RESULTS.md, ablations).
    #[arg(long, default_value_t = 0.0)]
    pub w_interaction: f64,
    /// Forecaster: device, cpu or cuda (needs echoctl built with `--features cuda`).
    #[arg(long, default_value = "cpu")]
    pub device: String,
    /// Forecaster: training data as a spec (docs/DATA.md): e.g. `cmu:data/cmu`,
    /// `cmu:data/cmu*0.6,synthetic:1300*0.4`, `intergen:/data/InterHuman`. Train and validation
    /// windows come from each source's own split. Default: the generator (`--train-clips`).
    #[arg(long)]
    pub data: Option<String>,
    /// Forecaster with --data: augment real captures (role swap, mirror, speed, proportions).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub augment: bool,
    /// Forecaster: time constant of the damped-velocity prior the decoded displacement is
    /// added to, s (0: the last observed frame, as in the paper).
    #[arg(long, default_value_t = 0.0)]
    pub velocity_prior_s: f64,
    /// Forecaster with --velocity-prior-s: extrapolate each person's root (position and
    /// heading) only and hold the local pose.
    #[arg(long)]
    pub velocity_prior_root_only: bool,
    /// Forecaster with --data: window stride of real captures, frames at 15 Hz (synthetic
    /// sources use 3).
    #[arg(long, default_value_t = 1)]
    pub real_stride: usize,
}

/// Training and validation windows of a data spec.
pub fn spec_windows(
    spec: &str,
    synthetic_clips: u64,
    augment: bool,
    real_stride: usize,
    seed: u64,
) -> Result<(
    Vec<echo_eval::window::Window>,
    Vec<echo_eval::window::Window>,
)> {
    use echo_data::augment::Augment;
    use echo_motion::synth::Split;
    let spec = echo_data::Spec::parse(spec)?;
    let train = echo_data::captures(&spec, Split::Train, synthetic_clips)?;
    let val = echo_data::captures(&spec, Split::Val, synthetic_clips)?;
    let cut = |stride_real: usize, aug: Augment| echo_data::Cut {
        stride: 3,
        real_stride: stride_real,
        augment: aug,
        seed,
    };
    let tw = echo_data::windows(
        &train,
        &cut(
            real_stride,
            if augment { Augment::ALL } else { Augment::NONE },
        ),
    );
    // Validation: no augmentation, no mixing weights (every window once).
    let val: Vec<_> = val
        .into_iter()
        .map(|(mut it, c)| {
            it.weight = None;
            (it, c)
        })
        .collect();
    let vw = echo_data::windows(&val, &cut(2, Augment::NONE));
    for (it, caps) in &train {
        println!(
            "train: {:?}: {} captures{}",
            it.source,
            caps.len(),
            it.weight
                .map(|w| format!(", weight {w}"))
                .unwrap_or_default()
        );
    }
    println!(
        "{} training windows, {} validation windows",
        tw.len(),
        vw.len()
    );
    Ok((tw, vw))
}

/// The device named by `--device`.
pub fn device(name: &str) -> Result<candle_core::Device> {
    match name {
        "cpu" => Ok(candle_core::Device::Cpu),
        "cuda" => Ok(candle_core::Device::new_cuda(0).map_err(|e| {
            anyhow::anyhow!("CUDA device 0: {e} (build echoctl with --features cuda)")
        })?),
        other => anyhow::bail!("--device must be cpu or cuda, not '{other}'"),
    }
}

struct Bar {
    pb: indicatif::ProgressBar,
    csv: std::fs::File,
    log: Vec<EpochLog>,
}

impl Progress for Bar {
    fn step(&mut self, k: usize, n: usize, loss: f64) {
        self.pb.set_length(n as u64);
        self.pb.set_position(k as u64);
        self.pb.set_message(format!("loss {loss:.4}"));
    }

    fn epoch(&mut self, e: &EpochLog) {
        // Printed, not drawn: the epoch summary must also reach logs (no terminal).
        self.pb.suspend(|| {
            println!(
                "epoch {}: train loss {:.4}, validation JPE {} mm ({:.0} s)",
                e.epoch,
                e.train_loss,
                e.val_jpe
                    .iter()
                    .map(|x| format!("{x:.1}"))
                    .collect::<Vec<_>>()
                    .join(" / "),
                e.elapsed_s
            )
        });
        let _ = writeln!(
            self.csv,
            "{},{:.6},{},{:.1}",
            e.epoch,
            e.train_loss,
            e.val_jpe
                .iter()
                .map(|x| format!("{x:.2}"))
                .collect::<Vec<_>>()
                .join(","),
            e.elapsed_s
        );
        self.log.push(e.clone());
    }
}

/// Loss curves as a PNG: training loss (left); validation JPE at 0.2/0.5/1.0/1.5 s (right).
pub fn loss_png(path: &std::path::Path, log: &[EpochLog]) -> Result<()> {
    let loss = Curve {
        points: log.iter().map(|e| (e.epoch as f64, e.train_loss)).collect(),
        rgb: [30, 30, 30],
    };
    let colours = [[40, 120, 220], [40, 170, 80], [230, 140, 20], [200, 40, 40]];
    let jpe = (0..4)
        .map(|h| Curve {
            points: log
                .iter()
                .filter_map(|e| e.val_jpe.get(h).map(|v| (e.epoch as f64, *v)))
                .collect(),
            rgb: colours[h],
        })
        .collect();
    chart(path, &[Panel { curves: vec![loss] }, Panel { curves: jpe }]).map_err(anyhow::Error::msg)
}

/// Train the retargeter on generated human poses and robot poses sampled within limits;
/// evaluate on held-out (test-split) poses; save.
fn retargeter(args: &Args) -> Result<()> {
    use echo_motion::synth::Split;
    use echo_retarget::train::{train as train_r, HumanSet, TrainConfig as RTrain};
    let out = if args.out == std::path::Path::new("models/forecaster") {
        PathBuf::from("models/retargeter")
    } else {
        args.out.clone()
    };
    let t = RTrain {
        steps: args.steps,
        w_direction: args.w_direction,
        seed: args.seed,
        ..Default::default()
    };
    let model = echo_robot::RobotModel::tiago_dual();
    let humans = HumanSet::from_split(Split::Train, 0..t.clips, 3);
    let held_out = HumanSet::from_split(Split::Test, 0..130, 5);
    println!("{} training poses, {} held-out poses", humans.n, held_out.n);
    let pb = progress(t.steps as u64, "training");
    let net_cfg = echo_retarget::net::NetConfig::default();
    let csv_path = out.with_extension("loss.csv");
    if let Some(d) = csv_path.parent() {
        std::fs::create_dir_all(d)?;
    }
    let mut csv = std::fs::File::create(&csv_path)?;
    writeln!(csv, "step,total,triplet,recon,latent,direction")?;
    let (vm, _) = train_r(&net_cfg, &t, &model, &humans, |l| {
        pb.set_position(l.step as u64);
        pb.set_message(format!("loss {:.4}", l.total));
        let _ = writeln!(
            csv,
            "{},{:.6},{:.6},{:.6},{:.6},{:.6}",
            l.step, l.total, l.triplet, l.recon, l.latent, l.direction
        );
    })?;
    pb.finish_and_clear();
    let vb =
        candle_nn::VarBuilder::from_varmap(&vm, candle_core::DType::F32, &candle_core::Device::Cpu);
    let net = echo_retarget::net::ImitationNet::new(net_cfg.clone(), &model, vb)?;
    let ev = echo_retarget::eval::evaluate(&net, &model, &held_out)?;
    println!(
        "held-out limb angle error: mean {:.1}° (L upper {:.1}, L fore {:.1}, R upper {:.1}, R fore {:.1}), median pose {:.1}°, {:.2}% within limits, {:.0} poses/s",
        ev.mean_deg, ev.limb_deg[0], ev.limb_deg[1], ev.limb_deg[2], ev.limb_deg[3], ev.median_deg,
        ev.within_limits * 100.0, ev.poses_per_s
    );
    let meta = echo_retarget::RetargeterMeta {
        net: net_cfg,
        training: t,
        command: std::env::args().collect::<Vec<_>>().join(" "),
        evaluation: Some(ev),
    };
    echo_retarget::Retargeter::save(&vm, &meta, &out)?;
    println!(
        "saved {}.safetensors/.json, loss curve {}",
        out.display(),
        csv_path.display()
    );
    Ok(())
}

/// HRI windows of `n` clips of a split, B retargeted onto the robot.
pub fn hri_windows(
    split: echo_motion::synth::Split,
    n: u64,
    stride: usize,
    r: &echo_retarget::Retargeter,
) -> Result<Vec<echo_hri::data::HriWindow>> {
    let clips = echo_motion::synth::generate_split(split, 0..n, 2, &|| {});
    let mut out = vec![];
    for c in &clips {
        let h = echo_retarget::hri::convert(c, r)?;
        out.extend(echo_hri::data::windows(&h, stride));
    }
    Ok(out)
}

/// Train the human–robot forecaster, evaluate it on test windows, save.
fn hri(args: &Args) -> Result<()> {
    use echo_hri::train::{
        gripper_fk, hri_model_config, train as train_hri, HriTrainConfig, Social,
    };
    let social = match args.social.as_str() {
        "none" => Social::None,
        "fixed" => Social::Fixed,
        "adaptive" => Social::Adaptive,
        other => anyhow::bail!("--social must be none, fixed or adaptive, not '{other}'"),
    };
    let out = if args.out == std::path::Path::new("models/forecaster") {
        PathBuf::from("models/hri")
    } else {
        args.out.clone()
    };
    let model = echo_robot::RobotModel::tiago_dual();
    let r = echo_retarget::Retargeter::load(&args.retargeter, model.clone())?;
    let t = HriTrainConfig {
        clips: args.train_clips,
        epochs: args.epochs,
        max_minutes: args.max_minutes,
        social,
        seed: args.seed,
        frozen_retargeter: args.freeze_retargeter,
        still_robot: args.still_robot,
        ..Default::default()
    };
    anyhow::ensure!(
        (0.0..=1.0).contains(&t.still_robot),
        "--still-robot must be within 0–1, not {}",
        t.still_robot
    );
    let dev = candle_core::Device::Cpu;
    let text = SentenceEncoder::load_default(&dev)?;
    let codec = args
        .freeze_retargeter
        .then(|| echo_hri::codec::RobotCodec::new(&r));
    let cfg = hri_model_config(text.dim(), codec.as_ref());
    let windows = hri_windows(echo_motion::synth::Split::Train, t.clips, t.stride, &r)?;
    println!(
        "{} HRI training windows from {} clips",
        windows.len(),
        t.clips
    );
    let fk = gripper_fk(&model, &r)?;
    let pb = progress(0, "training");
    let (vm, log) = train_hri(
        &cfg,
        &t,
        &windows,
        Some(&text),
        &fk,
        codec.as_ref(),
        |k, n, l| {
            pb.set_length(n as u64);
            pb.set_position(k as u64);
            pb.set_message(format!("loss {:.4}", l.total));
        },
    )?;
    pb.finish_and_clear();
    for (e, l) in log.iter().enumerate() {
        println!(
            "epoch {e}: total {:.4} self {:.4} soc {:.4} int {:.4} imit {:.4}",
            l.total, l.self_, l.soc, l.int, l.imit
        );
    }
    let meta = CheckpointMeta {
        model: cfg.clone(),
        training: TrainConfig::default(),
        command: std::env::args().collect::<Vec<_>>().join(" "),
        text_encoder: text.id().to_string(),
        features: format!("agent A (human): 22 pelvis-relative joints in the heading frame, pelvis xyz, heading quaternion (73); agent B (robot): {}, torso, head pan and tilt, base xyz, heading quaternion ({}); window frame at the human's last observed pelvis and heading", if args.freeze_retargeter { format!("the 14 arm joints as the frozen retargeter's {}-d latent ({})", codec.as_ref().map_or(0, |c| c.latent()), args.retargeter.display()) } else { "14 arm joints".to_string() }, cfg.agent_features[1]),
        hri_training: Some(serde_json::to_value(&t)?),
    };
    Checkpoint::save(&vm, &meta, &out)?;
    println!("saved {}.safetensors/.json", out.display());
    Ok(())
}

/// What `echoctl train` trains.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Trainable {
    /// The dual-agent forecaster on human–human data.
    Forecaster,
    /// The human→robot retargeter (ImitationNet).
    Retargeter,
    /// The human–robot forecaster (HRI losses through the robot's FK).
    Hri,
}

/// Train and save.
pub fn run(args: Args) -> Result<()> {
    match args.what {
        Trainable::Retargeter => return retargeter(&args),
        Trainable::Hri => return hri(&args),
        Trainable::Forecaster => {}
    }
    if args.replot {
        let csv = args.out.with_extension("loss.csv");
        let text = std::fs::read_to_string(&csv)?;
        let log: Vec<EpochLog> = text
            .lines()
            .skip(1)
            .filter_map(|l| {
                let v: Vec<f64> = l.split(',').filter_map(|x| x.parse().ok()).collect();
                (v.len() == 7).then(|| EpochLog {
                    epoch: v[0] as usize,
                    train_loss: v[1],
                    val_jpe: v[2..6].to_vec(),
                    elapsed_s: v[6],
                })
            })
            .collect();
        anyhow::ensure!(!log.is_empty(), "{}: no epochs", csv.display());
        let png = args.out.with_extension("loss.png");
        loss_png(&png, &log)?;
        println!("wrote {}", png.display());
        return Ok(());
    }
    let dev = device(&args.device)?;
    let mut model = ForecasterConfig {
        d_model: args.d_model,
        rounds: args.rounds,
        text_dim: echo_text::MINILM_DIM,
        social_identity_init: args.social_init == SocialInit::Identity,
        velocity_prior_s: args.velocity_prior_s,
        velocity_prior_root_only: args.velocity_prior_root_only,
        ..Default::default()
    };
    if let Some(init) = &args.init {
        model = CheckpointMeta::load(init)?.model;
    }
    let mut t = TrainConfig {
        lr: args.lr,
        train_clips: args.train_clips,
        max_minutes: args.max_minutes,
        epochs: args.epochs,
        seed: args.seed,
        w_interaction: args.w_interaction,
        ..Default::default()
    };
    args.variant.apply(&mut model, &mut t);
    t.data = args.data.clone();
    let data = match &args.data {
        Some(spec) => Some(spec_windows(
            spec,
            args.train_clips,
            args.augment,
            args.real_stride,
            args.seed,
        )?),
        None => None,
    };
    let text = if model.text_dim > 0 {
        Some(SentenceEncoder::load_default(&dev)?)
    } else {
        None
    };
    let csv_path = args.out.with_extension("loss.csv");
    if let Some(d) = csv_path.parent() {
        std::fs::create_dir_all(d)?;
    }
    let mut csv = if args.resume {
        std::fs::OpenOptions::new().append(true).open(&csv_path)?
    } else {
        std::fs::File::create(&csv_path)?
    };
    if !args.resume {
        writeln!(
            csv,
            "epoch,train_loss,val_jpe_0.2,val_jpe_0.5,val_jpe_1.0,val_jpe_1.5,elapsed_s"
        )?;
    }
    let mut bar = Bar {
        pb: progress(0, "training"),
        csv,
        log: vec![],
    };
    let run = Run {
        dev: dev.clone(),
        text: text.as_ref(),
        state: Some(args.out.clone()),
        resume: args.resume,
        init: args
            .init
            .as_ref()
            .map(|s| echo_assets::resolve_model(s).map(|p| p.with_extension("safetensors")))
            .transpose()?,
        data,
    };
    let (varmap, log) = train(&model, &t, &run, &mut bar)?;
    bar.pb.finish_and_clear();
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    let meta = CheckpointMeta {
        model,
        training: t,
        command,
        text_encoder: text
            .as_ref()
            .map(|e| e.id().to_string())
            .unwrap_or_else(|| "none".into()),
        features: "per agent and frame: 22 joints relative to the pelvis in the heading frame (66), pelvis xyz (3), heading quaternion xyzw (4); window frame at A's last observed pelvis and heading".into(),
        hri_training: None,
    };
    Checkpoint::save(&varmap, &meta, &args.out)?;
    let png = args.out.with_extension("loss.png");
    loss_png(&png, &log)?;
    println!(
        "{} epochs; saved {}.safetensors/.json, loss curve {} and {}",
        log.len(),
        args.out.display(),
        csv_path.display(),
        png.display()
    );
    Ok(())
}
