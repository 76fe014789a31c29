//! Human–human → human–robot data (the paper's HRI dataset): person B of each pair becomes the
//! robot — arms by the retargeter (copied side for side: the robot does what B does), torso and
//! head by the rules, base on the floor under B's pelvis with B's heading — and the original pair
//! is kept for the social metrics.

use std::path::Path;

use anyhow::{Context, Result};
use candle_core::{Device, Tensor};
use echo_eval::metrics::Confusion;
use echo_motion::sensors::{body_capsules, contact_and_proximity, part_distances, BodyPart};
use echo_motion::skeleton::{heading, j, NUM_JOINTS};
use echo_motion::synth::Clip;
use echo_robot::collision::RobotBody;
use echo_robot::RobotModel;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::retargeter::Retargeter;

/// One interaction with B as the robot.
#[derive(Debug, Clone)]
pub struct HriClip {
    /// Interaction type.
    pub kind: String,
    /// Descriptions.
    pub texts: Vec<String>,
    /// Frames per second.
    pub fps: f64,
    /// Person A (the human partner), world frame.
    pub human: Vec<[Vector3<f64>; NUM_JOINTS]>,
    /// Person B as performed (the reference the robot stands in for).
    pub reference: Vec<[Vector3<f64>; NUM_JOINTS]>,
    /// Robot joint values per frame, in [`Retargeter::joint_names`] order.
    pub robot: Vec<Vec<f64>>,
    /// Robot base per frame: x, y, yaw (world).
    pub base: Vec<[f64; 3]>,
}

impl HriClip {
    /// The robot's joint values at frame `f` (columns named by the retargeter `r`).
    pub fn robot_values(
        &self,
        f: usize,
        r: &Retargeter,
        model: &RobotModel,
    ) -> Result<echo_robot::JointValues> {
        let row = self
            .robot
            .get(f)
            .with_context(|| format!("frame {f} of {}", self.robot.len()))?;
        Ok(model.values_from(
            r.joint_names()
                .iter()
                .map(|n| n.as_str())
                .zip(row.iter().copied()),
        )?)
    }

    /// World pose of the robot base at frame `f`.
    pub fn base_pose(&self, f: usize) -> Isometry3<f64> {
        let [x, y, yaw] = self.base[f];
        Isometry3::from_parts(
            Translation3::new(x, y, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
        )
    }
}

/// Convert one clip (every frame); a frame whose pose cannot be retargeted repeats the last one.
pub fn convert(clip: &Clip, r: &Retargeter) -> Result<HriClip> {
    let n = clip.frames.len();
    let human: Vec<_> = (0..n).map(|f| clip.joints(f, 0)).collect();
    let reference: Vec<_> = (0..n).map(|f| clip.joints(f, 1)).collect();
    let poses = r.retarget(&reference)?;
    let mut robot: Vec<Vec<f64>> = Vec::with_capacity(n);
    let mut last: Option<Vec<f64>> = None;
    for p in poses {
        let v = match (p, &last) {
            (Some(p), _) => p.positions,
            (None, Some(l)) => l.clone(),
            (None, None) => anyhow::bail!(
                "clip {}: first pose of B cannot be retargeted",
                clip.params.seed
            ),
        };
        last = Some(v.clone());
        robot.push(v);
    }
    let base = reference
        .iter()
        .map(|p| {
            let (_, _, yaw) = heading(p).euler_angles();
            [p[j::PELVIS].x, p[j::PELVIS].y, yaw]
        })
        .collect();
    Ok(HriClip {
        kind: format!("{:?}", clip.params.kind),
        texts: clip.texts.clone(),
        fps: echo_motion::synth::FPS,
        human,
        reference,
        robot,
        base,
    })
}

/// A point of the robot's base frame in the world.
fn world(t: &Isometry3<f64>, p: &Vector3<f64>) -> Vector3<f64> {
    t.transform_point(&nalgebra::Point3::from(*p)).coords
}

/// Social agreement of the HRI pair with the original HHI pair.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct SocialScores {
    /// Contact (surfaces touch): HRI frame-level prediction against HHI truth.
    pub contact: Confusion,
    /// Proximity (within 5 cm).
    pub proximity: Confusion,
    /// Mean distance from each gripper to the reference person's wrist on the same side, m.
    pub hand_error_m: f64,
    /// Frames scored.
    pub frames: usize,
}

/// Score every `stride`-th frame: robot capsules (in the world) against A's capsules, versus B's.
pub fn social_scores(
    hri: &HriClip,
    r: &Retargeter,
    model: &RobotModel,
    body: &RobotBody,
    stride: usize,
) -> Result<SocialScores> {
    let mut s = SocialScores::default();
    let mut hand = 0.0;
    for f in (0..hri.human.len()).step_by(stride.max(1)) {
        let q = hri.robot_values(f, r, model)?;
        let t = hri.base_pose(f);
        let robot = body.at_pose(model, &q, &t);
        let d = part_distances(&body_capsules(&hri.human[f]), &robot);
        let min = d.iter().flatten().fold(f64::INFINITY, |m, x| m.min(*x));
        let (c_hh, p_hh) = contact_and_proximity(&hri.human[f], &hri.reference[f]);
        s.contact.add(min <= 0.0, c_hh);
        s.proximity.add(min <= 0.05, p_hh);
        for (g, w) in GRASPING_FRAMES.into_iter().zip([j::L_WRIST, j::R_WRIST]) {
            let e = world(&t, &model.fk(&q, g)?.translation.vector);
            hand += (e - hri.reference[f][w]).norm() / 2.0;
        }
        s.frames += 1;
    }
    s.hand_error_m = hand / s.frames.max(1) as f64;
    Ok(s)
}

/// The robot's grasping frames.
pub use echo_robot::GRASPING_FRAMES;

/// How close the robot's grippers are to the partner's hands.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Reach {
    /// Smallest distance from a grasping frame to a wrist joint, m.
    pub grasp_to_wrist_m: f64,
    /// Smallest surface distance between a gripper capsule and a hand capsule, m (≤ 0: the
    /// surfaces touch, the contact sensor `S_0`).
    pub surface_m: f64,
}

impl Reach {
    /// Nothing measured yet.
    pub const NONE: Reach = Reach {
        grasp_to_wrist_m: f64::INFINITY,
        surface_m: f64::INFINITY,
    };

    /// The closer of the two on each measure.
    pub fn min(self, o: Reach) -> Reach {
        Reach {
            grasp_to_wrist_m: self.grasp_to_wrist_m.min(o.grasp_to_wrist_m),
            surface_m: self.surface_m.min(o.surface_m),
        }
    }

    /// The surfaces touched.
    pub fn contact(&self) -> bool {
        self.surface_m <= echo_motion::sensors::CONTACT_MARGIN
    }
}

/// How close the robot (joint values `q`, base at `base` in the world) brings its grippers to
/// the partner's hands (`partner`: SMPL-22 joints in the world).
pub fn gripper_reach(
    model: &RobotModel,
    body: &RobotBody,
    q: &echo_robot::JointValues,
    base: &Isometry3<f64>,
    partner: &[Vector3<f64>],
) -> Result<Reach> {
    let mut r = Reach::NONE;
    for g in GRASPING_FRAMES {
        let e = world(base, &model.fk(q, g)?.translation.vector);
        for w in [j::L_WRIST, j::R_WRIST] {
            if let Some(p) = partner.get(w) {
                r.grasp_to_wrist_m = r.grasp_to_wrist_m.min((e - p).norm());
            }
        }
    }
    let hands: Vec<_> = body_capsules(partner)
        .into_iter()
        .filter(|(p, _)| matches!(p, BodyPart::Hand(_)))
        .collect();
    for (part, c) in body.at_pose(model, q, base) {
        if matches!(part, echo_robot::collision::Part::Gripper(_)) {
            for (_, h) in &hands {
                r.surface_m = r.surface_m.min(c.distance(h));
            }
        }
    }
    Ok(r)
}

/// How close the retargeted reference alone brings the grippers to the partner's hands when
/// the robot stands still at `base` (world) and plays the reference joints frame by frame.
pub fn reference_reach(
    hri: &HriClip,
    r: &Retargeter,
    model: &RobotModel,
    body: &RobotBody,
    base: &Isometry3<f64>,
) -> Result<Reach> {
    let mut best = Reach::NONE;
    for f in 0..hri.human.len().min(hri.robot.len()) {
        let q = hri.robot_values(f, r, model)?;
        best = best.min(gripper_reach(model, body, &q, base, &hri.human[f])?);
    }
    Ok(best)
}

/// Metadata of a written HRI dataset.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct HriMeta {
    /// Robot joint names (columns of `robot`).
    pub joint_names: Vec<String>,
    /// Per clip: type, descriptions, frames.
    pub clips: Vec<(String, Vec<String>, usize)>,
    /// Frames per second.
    pub fps: f64,
    /// Retargeter that made it.
    pub retargeter: String,
}

/// Write clips as `hri.safetensors` (per clip `i`: `i.human` (T, 22, 3), `i.reference`,
/// `i.robot` (T, 17), `i.base` (T, 3)) and `meta.json`.
pub fn write(dir: &Path, clips: &[HriClip], r: &Retargeter, retargeter: &str) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let dev = Device::Cpu;
    let mut map = std::collections::HashMap::new();
    let joints = |v: &[[Vector3<f64>; NUM_JOINTS]]| -> Result<Tensor> {
        let flat: Vec<f32> = v
            .iter()
            .flatten()
            .flat_map(|p| [p.x as f32, p.y as f32, p.z as f32])
            .collect();
        Ok(Tensor::from_vec(flat, (v.len(), NUM_JOINTS, 3), &dev)?)
    };
    for (i, c) in clips.iter().enumerate() {
        map.insert(format!("{i}.human"), joints(&c.human)?);
        map.insert(format!("{i}.reference"), joints(&c.reference)?);
        let q: Vec<f32> = c.robot.iter().flatten().map(|v| *v as f32).collect();
        map.insert(
            format!("{i}.robot"),
            Tensor::from_vec(q, (c.robot.len(), r.joint_names().len()), &dev)?,
        );
        let b: Vec<f32> = c.base.iter().flatten().map(|v| *v as f32).collect();
        map.insert(
            format!("{i}.base"),
            Tensor::from_vec(b, (c.base.len(), 3), &dev)?,
        );
    }
    candle_core::safetensors::save(&map, dir.join("hri.safetensors"))?;
    let meta = HriMeta {
        joint_names: r.joint_names().to_vec(),
        clips: clips
            .iter()
            .map(|c| (c.kind.clone(), c.texts.clone(), c.human.len()))
            .collect(),
        fps: clips
            .first()
            .map(|c| c.fps)
            .unwrap_or(echo_motion::synth::FPS),
        retargeter: retargeter.to_string(),
    };
    std::fs::write(dir.join("meta.json"), serde_json::to_vec_pretty(&meta)?)?;
    Ok(())
}
