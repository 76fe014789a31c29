//! The retargeter at run time: a trained [`ImitationNet`] for the 14 arm joints, plus two
//! documented rules — the head from the human's neck→head direction, the torso from posture —
//! every output inside the robot's soft limits. Checkpoints are safetensors + JSON.

use std::path::Path;

use anyhow::{Context, Result};
use candle_core::{DType, Device, Tensor};
use candle_nn::{VarBuilder, VarMap};
use echo_motion::skeleton::{j, NUM_JOINTS};
use echo_robot::RobotModel;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::eval::Evaluation;
use crate::human::{body_frame, features, HUMAN_FEATURES};
use crate::net::{arm_joints, ImitationNet, NetConfig};
use crate::train::TrainConfig;

/// What is stored next to the weights.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RetargeterMeta {
    /// Network sizes.
    pub net: NetConfig,
    /// How it was trained.
    pub training: TrainConfig,
    /// The command that produced it.
    pub command: String,
    /// Held-out evaluation at training time.
    pub evaluation: Option<Evaluation>,
}

/// A robot pose by joint name.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotPose {
    /// Joint names: 14 arm joints, torso_lift_joint, head_1_joint, head_2_joint.
    pub names: Vec<String>,
    /// Values, inside the soft limits.
    pub positions: Vec<f64>,
}

/// Trained retargeter.
pub struct Retargeter {
    net: ImitationNet,
    model: RobotModel,
    /// Metadata.
    pub meta: RetargeterMeta,
    names: Vec<String>,
}

fn clamp_to(model: &RobotModel, name: &str, v: f64) -> f64 {
    match model.limits(name) {
        Some(l) => v.clamp(l.soft_lower, l.soft_upper),
        None => v,
    }
}

/// Head rule: tilt from how far the neck→head direction leans forward of vertical (a nod or a
/// bow looks down), minus a person's usual forward lean (0.15 rad); pan 0 — a 22-joint
/// skeleton has no face direction. Clamped to the head's soft limits.
pub fn head_rule(model: &RobotModel, p: &[Vector3<f64>; NUM_JOINTS]) -> (f64, f64) {
    let tilt = body_frame(p)
        .map(|r| {
            let v = r * (p[j::HEAD] - p[j::NECK]);
            v.x.atan2(v.z.max(1e-6)) - 0.15
        })
        .unwrap_or(0.0);
    (
        clamp_to(model, "head_1_joint", 0.0),
        clamp_to(model, "head_2_joint", tilt),
    )
}

/// Torso rule: the lift follows how upright and how tall the person stands — full height when
/// the trunk is vertical and the pelvis is at leg length above the floor, lower when bowing or
/// crouching. Clamped to the torso's soft limits.
pub fn torso_rule(model: &RobotModel, p: &[Vector3<f64>; NUM_JOINTS]) -> f64 {
    let trunk = p[j::NECK] - p[j::PELVIS];
    let upright = (trunk.z / trunk.norm().max(1e-6)).clamp(0.0, 1.0);
    let leg = (p[j::L_HIP] - p[j::L_KNEE]).norm() + (p[j::L_KNEE] - p[j::L_ANKLE]).norm();
    let stand = ((p[j::PELVIS].z / leg.max(1e-6) - 0.6) / 0.4).clamp(0.0, 1.0);
    let (lo, hi) = model
        .limits("torso_lift_joint")
        .map(|l| (l.soft_lower, l.soft_upper))
        .unwrap_or((0.0, 0.35));
    lo + (hi - lo) * upright.powi(2) * stand
}

impl Retargeter {
    /// Save weights and metadata as `<stem>.safetensors` and `<stem>.json`.
    pub fn save(vm: &VarMap, meta: &RetargeterMeta, stem: &Path) -> Result<()> {
        if let Some(d) = stem.parent() {
            std::fs::create_dir_all(d)?;
        }
        vm.save(stem.with_extension("safetensors"))?;
        std::fs::write(
            stem.with_extension("json"),
            serde_json::to_vec_pretty(meta)?,
        )?;
        Ok(())
    }

    /// Load `<stem>.safetensors` + `<stem>.json` for `model`.
    pub fn load(stem: &Path, model: RobotModel) -> Result<Retargeter> {
        let stem = &echo_assets::resolve_model(stem)?;
        let jp = stem.with_extension("json");
        let meta: RetargeterMeta = serde_json::from_slice(
            &std::fs::read(&jp).with_context(|| format!("reading {}", jp.display()))?,
        )
        .with_context(|| format!("parsing {}", jp.display()))?;
        let wp = stem.with_extension("safetensors");
        let bytes = std::fs::read(&wp).with_context(|| format!("reading {}", wp.display()))?;
        let vb = VarBuilder::from_buffered_safetensors(bytes, DType::F32, &Device::Cpu)?;
        let net = ImitationNet::new(meta.net.clone(), &model, vb)
            .with_context(|| format!("{}", wp.display()))?;
        Ok(Retargeter::from_net(net, model, meta))
    }

    /// Wrap a network (e.g. fresh from training).
    pub fn from_net(net: ImitationNet, model: RobotModel, meta: RetargeterMeta) -> Retargeter {
        let mut names = arm_joints();
        names.extend(["torso_lift_joint", "head_1_joint", "head_2_joint"].map(String::from));
        Retargeter {
            net,
            model,
            meta,
            names,
        }
    }

    /// The network.
    pub fn net(&self) -> &ImitationNet {
        &self.net
    }

    /// Joint names of [`RobotPose`]s.
    pub fn joint_names(&self) -> &[String] {
        &self.names
    }

    /// Retarget a batch of skeletons; `None` where a pose is degenerate (shoulders coincide).
    pub fn retarget(&self, poses: &[[Vector3<f64>; NUM_JOINTS]]) -> Result<Vec<Option<RobotPose>>> {
        let feats: Vec<Option<[f32; HUMAN_FEATURES]>> = poses.iter().map(features).collect();
        let ok: Vec<f32> = feats
            .iter()
            .flatten()
            .flat_map(|f| f.iter().copied())
            .collect();
        let n = ok.len() / HUMAN_FEATURES;
        let arms = if n > 0 {
            self.net
                .retarget(&Tensor::from_vec(ok, (n, HUMAN_FEATURES), &Device::Cpu)?)?
                .to_vec2::<f32>()?
        } else {
            vec![]
        };
        let mut arms = arms.into_iter();
        Ok(poses
            .iter()
            .zip(&feats)
            .map(|(p, f)| {
                f.as_ref()?;
                let a = arms.next()?;
                let (pan, tilt) = head_rule(&self.model, p);
                let mut positions: Vec<f64> = a.iter().map(|v| *v as f64).collect();
                positions.extend([torso_rule(&self.model, p), pan, tilt]);
                Some(RobotPose {
                    names: self.names.clone(),
                    positions,
                })
            })
            .collect())
    }
}
