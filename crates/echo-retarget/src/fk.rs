//! Differentiable, batched forward kinematics in candle, built from the same robot description
//! (URDF) as the nalgebra FK: for joint values (b, n) of chosen joints, the positions of chosen
//! frames (b, frames, 3) in the root frame. Joints that are not variables keep fixed values.

use std::collections::HashMap;

use candle_core::{DType, Device, Result, Tensor};
use echo_robot::{JointKind, RobotModel};
use nalgebra::Matrix3;

/// One step along a chain: a constant transform, then the joint's motion.
#[derive(Debug, Clone)]
struct Step {
    rot: [f32; 9],
    trans: [f32; 3],
    kind: JointKind,
    /// Rodrigues terms of the axis: K and K².
    k: [f32; 9],
    k2: [f32; 9],
    axis: [f32; 3],
    /// Column of the variable in q, or the fixed value.
    var: JointValue,
    link: usize,
}

#[derive(Debug, Clone, Copy)]
enum JointValue {
    Var(usize),
    Fixed(f64),
}

/// FK of selected frames as a function of selected joints.
#[derive(Debug, Clone)]
pub struct BatchFk {
    chains: Vec<Vec<Step>>,
    variables: Vec<String>,
    frames: Vec<String>,
}

fn mat(m: &Matrix3<f64>) -> [f32; 9] {
    std::array::from_fn(|i| m[(i / 3, i % 3)] as f32)
}

impl BatchFk {
    /// `variables`: joint names in the columns of q; `fixed`: values of other moving joints
    /// (absent ones are 0); `frames`: link names whose positions are returned.
    pub fn new(
        model: &RobotModel,
        variables: &[&str],
        fixed: &[(&str, f64)],
        frames: &[&str],
    ) -> std::result::Result<BatchFk, echo_robot::RobotError> {
        let fixed: HashMap<&str, f64> = fixed.iter().copied().collect();
        let mut chains = vec![];
        for f in frames {
            let mut steps = vec![];
            for j in model.chain(f)? {
                let r = j.origin.rotation.to_rotation_matrix().into_inner();
                let t = j.origin.translation.vector;
                let a = j.axis.into_inner();
                let k = Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0);
                let var = match variables.iter().position(|v| *v == j.name) {
                    Some(i) => JointValue::Var(i),
                    None => JointValue::Fixed(fixed.get(j.name.as_str()).copied().unwrap_or(0.0)),
                };
                steps.push(Step {
                    rot: mat(&r),
                    trans: [t.x as f32, t.y as f32, t.z as f32],
                    kind: j.kind,
                    k: mat(&k),
                    k2: mat(&(k * k)),
                    axis: [a.x as f32, a.y as f32, a.z as f32],
                    var,
                    link: j.child,
                });
            }
            chains.push(steps);
        }
        for v in variables {
            if model.joint_index(v).is_none() {
                return Err(echo_robot::RobotError::UnknownJoint(v.to_string()));
            }
        }
        Ok(BatchFk {
            chains,
            variables: variables.iter().map(|s| s.to_string()).collect(),
            frames: frames.iter().map(|s| s.to_string()).collect(),
        })
    }

    /// Variable joint names (columns of q).
    pub fn variables(&self) -> &[String] {
        &self.variables
    }

    /// Frame names (rows of the output).
    pub fn frames(&self) -> &[String] {
        &self.frames
    }

    /// Positions (b, frames, 3) for joint values `q` (b, variables).
    pub fn forward(&self, q: &Tensor) -> Result<Tensor> {
        let (b, _) = q.dims2()?;
        let dev = q.device();
        let c = |v: &[f32], shape: (usize, usize)| Tensor::from_slice(v, shape, dev);
        let mut memo: HashMap<usize, (Tensor, Tensor)> = HashMap::new();
        let eye = Tensor::eye(3, DType::F32, dev)?;
        let mut out = vec![];
        for chain in &self.chains {
            let mut r = eye.unsqueeze(0)?.broadcast_as((b, 3, 3))?.contiguous()?;
            let mut p = Tensor::zeros((b, 3, 1), DType::F32, dev)?;
            for s in chain {
                if let Some((mr, mp)) = memo.get(&s.link) {
                    r = mr.clone();
                    p = mp.clone();
                    continue;
                }
                // Constant origin.
                p = (p + r.broadcast_matmul(&c(&s.trans, (3, 1))?)?)?;
                r = r.broadcast_matmul(&c(&s.rot, (3, 3))?)?;
                let value = |dev: &Device| -> Result<Tensor> {
                    match s.var {
                        JointValue::Var(i) => q.narrow(1, i, 1)?.reshape((b, 1, 1)),
                        JointValue::Fixed(v) => Tensor::full(v as f32, (b, 1, 1), dev),
                    }
                };
                match s.kind {
                    JointKind::Revolute | JointKind::Continuous => {
                        let th = value(dev)?;
                        // R(axis, θ) = I + sin θ K + (1 − cos θ) K²
                        let rot = (eye.unsqueeze(0)?.broadcast_as((b, 3, 3))?
                            + th.sin()?.broadcast_mul(&c(&s.k, (3, 3))?.unsqueeze(0)?)?)?;
                        let rot = (rot
                            + (1.0 - th.cos()?)?
                                .broadcast_mul(&c(&s.k2, (3, 3))?.unsqueeze(0)?)?)?;
                        r = r.matmul(&rot)?;
                    }
                    JointKind::Prismatic => {
                        let d = value(dev)?;
                        let t = d.broadcast_mul(&c(&s.axis, (3, 1))?.unsqueeze(0)?)?;
                        p = (p + r.matmul(&t)?)?;
                    }
                    JointKind::Fixed => {}
                }
                memo.insert(s.link, (r.clone(), p.clone()));
            }
            out.push(p.squeeze(2)?.unsqueeze(1)?);
        }
        Tensor::cat(&out, 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn matches_the_nalgebra_fk_within_1e5_m() {
        let model = RobotModel::tiago_dual();
        let vars: Vec<String> = ["left", "right"]
            .iter()
            .flat_map(|s| (1..=7).map(move |i| format!("arm_{s}_{i}_joint")))
            .chain([
                "torso_lift_joint".to_string(),
                "head_1_joint".into(),
                "head_2_joint".into(),
            ])
            .collect();
        let vref: Vec<&str> = vars.iter().map(|s| s.as_str()).collect();
        let frames = [
            "arm_left_1_link",
            "arm_left_4_link",
            "arm_left_7_link",
            "gripper_left_grasping_frame",
            "arm_right_4_link",
            "gripper_right_grasping_frame",
            "head_2_link",
        ];
        let fk = BatchFk::new(&model, &vref, &[], &frames).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(4);
        let b = 16;
        let mut qs = vec![];
        for _ in 0..b {
            for v in &vars {
                let l = model.limits(v).unwrap();
                qs.push(rng.random_range(l.lower..l.upper) as f32);
            }
        }
        let q = Tensor::from_vec(qs.clone(), (b, vars.len()), &Device::Cpu).unwrap();
        let p = fk.forward(&q).unwrap().to_vec3::<f32>().unwrap();
        let mut worst = 0f64;
        for i in 0..b {
            let values = model
                .values_from(
                    vref.iter()
                        .enumerate()
                        .map(|(k, n)| (*n, qs[i * vars.len() + k] as f64)),
                )
                .unwrap();
            for (fi, f) in frames.iter().enumerate() {
                let want = model.fk(&values, f).unwrap().translation.vector;
                let got = &p[i][fi];
                for d in 0..3 {
                    worst = worst.max((got[d] as f64 - want[d]).abs());
                }
            }
        }
        assert!(worst < 1e-5, "worst difference {worst} m");
    }

    #[test]
    fn gradients_flow_to_the_joints() {
        let model = RobotModel::tiago_dual();
        let fk = BatchFk::new(&model, &["arm_right_2_joint"], &[], &["arm_right_7_link"]).unwrap();
        let q = candle_core::Var::zeros((1, 1), DType::F32, &Device::Cpu).unwrap();
        let z = fk
            .forward(q.as_tensor())
            .unwrap()
            .narrow(2, 2, 1)
            .unwrap()
            .sum_all()
            .unwrap();
        let g = z.backward().unwrap();
        let dz = g.get(&q).unwrap().to_vec2::<f32>().unwrap()[0][0];
        assert!(dz.abs() > 1e-3, "d(height)/d(shoulder) = {dz}");
    }
}
