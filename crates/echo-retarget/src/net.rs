//! ImitationNet: a human encoder, a robot encoder and a robot decoder (MLPs) sharing one latent
//! space. The decoder's output goes through a sigmoid onto each joint's soft-limit range, so
//! every retargeted pose is inside the limits by construction.

use candle_core::{Result, Tensor};
use candle_nn::{linear, Linear, Module, VarBuilder};
use echo_robot::RobotModel;
use serde::{Deserialize, Serialize};

use crate::human::HUMAN_FEATURES;

pub use echo_robot::arm_joints;

/// The arm joints' values in the robot's home pose (the constant baseline of the evaluation).
pub fn home_arms() -> Vec<f64> {
    let home = echo_robot::home_pose();
    arm_joints()
        .iter()
        .map(|j| {
            home.iter()
                .find(|(k, _)| k == j)
                .map(|(_, v)| *v)
                .unwrap_or(0.0)
        })
        .collect()
}

/// Robot frames whose positions give the limb directions: shoulder, elbow, wrist per arm.
pub const LIMB_FRAMES: [&str; 6] = [
    "arm_left_3_link",
    "arm_left_4_link",
    "arm_left_6_link",
    "arm_right_3_link",
    "arm_right_4_link",
    "arm_right_6_link",
];

/// Sizes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NetConfig {
    /// Hidden width.
    pub hidden: usize,
    /// Hidden layers per MLP.
    pub layers: usize,
    /// Latent size.
    pub latent: usize,
}

impl Default for NetConfig {
    fn default() -> Self {
        NetConfig {
            hidden: 128,
            layers: 4,
            latent: 32,
        }
    }
}

struct Mlp(Vec<Linear>);

impl Mlp {
    fn new(i: usize, h: usize, o: usize, layers: usize, vb: VarBuilder) -> Result<Mlp> {
        let mut v = vec![];
        let mut d = i;
        for k in 0..layers {
            v.push(linear(d, h, vb.pp(format!("l{k}")))?);
            d = h;
        }
        v.push(linear(d, o, vb.pp("out"))?);
        Ok(Mlp(v))
    }

    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let mut h = x.clone();
        let n = self.0.len();
        for (k, l) in self.0.iter().enumerate() {
            h = l.forward(&h)?;
            if k + 1 < n {
                h = h.relu()?;
            }
        }
        Ok(h)
    }
}

/// The three networks and the joint ranges.
pub struct ImitationNet {
    human_enc: Mlp,
    robot_enc: Mlp,
    robot_dec: Mlp,
    lower: Tensor,
    range: Tensor,
    cfg: NetConfig,
}

/// Soft limits (lower, upper) of the arm joints.
pub fn arm_limits(model: &RobotModel) -> Vec<(f64, f64)> {
    arm_joints()
        .iter()
        .map(|n| {
            model
                .limits(n)
                .map(|l| (l.soft_lower, l.soft_upper))
                .unwrap_or((-1.0, 1.0))
        })
        .collect()
}

impl ImitationNet {
    /// Build over `vb`; the ranges come from the robot's soft limits.
    pub fn new(cfg: NetConfig, model: &RobotModel, vb: VarBuilder) -> Result<ImitationNet> {
        let lim = arm_limits(model);
        let n = lim.len();
        let dev = vb.device().clone();
        let lower: Vec<f32> = lim.iter().map(|l| l.0 as f32).collect();
        let range: Vec<f32> = lim.iter().map(|l| (l.1 - l.0) as f32).collect();
        Ok(ImitationNet {
            human_enc: Mlp::new(
                HUMAN_FEATURES,
                cfg.hidden,
                cfg.latent,
                cfg.layers,
                vb.pp("human_enc"),
            )?,
            robot_enc: Mlp::new(n, cfg.hidden, cfg.latent, cfg.layers, vb.pp("robot_enc"))?,
            robot_dec: Mlp::new(cfg.latent, cfg.hidden, n, cfg.layers, vb.pp("robot_dec"))?,
            lower: Tensor::from_vec(lower, n, &dev)?,
            range: Tensor::from_vec(range, n, &dev)?,
            cfg,
        })
    }

    /// Sizes.
    pub fn config(&self) -> &NetConfig {
        &self.cfg
    }

    /// Joint values → [0, 1] per joint.
    pub fn normalise(&self, q: &Tensor) -> Result<Tensor> {
        q.broadcast_sub(&self.lower)?.broadcast_div(&self.range)
    }

    /// Human features (b, 16) → latent.
    pub fn encode_human(&self, h: &Tensor) -> Result<Tensor> {
        self.human_enc.forward(h)
    }

    /// Robot joints (b, 14) → latent.
    pub fn encode_robot(&self, q: &Tensor) -> Result<Tensor> {
        self.robot_enc
            .forward(&((self.normalise(q)? * 2.0)? - 1.0)?)
    }

    /// Latent → robot joints (b, 14), inside the soft limits.
    pub fn decode(&self, z: &Tensor) -> Result<Tensor> {
        let s = candle_nn::ops::sigmoid(&self.robot_dec.forward(z)?)?;
        s.broadcast_mul(&self.range)?.broadcast_add(&self.lower)
    }

    /// Human features → robot joints.
    pub fn retarget(&self, h: &Tensor) -> Result<Tensor> {
        self.decode(&self.encode_human(h)?)
    }
}
