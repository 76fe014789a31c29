//! The retargeter's robot encoder and decoder, frozen, as the first stage of the robot agent's
//! embedding and the last stage of its decoder (the paper's option to reuse ImitationNet): the
//! forecaster sees and predicts the 14 arm joints as ImitationNet latents (its displacement is
//! added in latent space), the decoder maps them back inside the joint limits by construction;
//! torso, head and base pass through unchanged. The retargeter's weights are constants here, so
//! training moves only the forecaster.

use candle_core::{Result, Tensor, D};
use echo_retarget::Retargeter;

use crate::data::ROBOT_FEATURES;

/// Arm joints at the front of the robot features.
pub const ARM: usize = 14;

/// The frozen codec of one retargeter.
pub struct RobotCodec<'a> {
    r: &'a Retargeter,
}

impl<'a> RobotCodec<'a> {
    /// The codec of `r`.
    pub fn new(r: &'a Retargeter) -> Self {
        RobotCodec { r }
    }

    /// Latent size.
    pub fn latent(&self) -> usize {
        self.r.net().config().latent
    }

    /// Features per frame the forecaster sees for the robot: latent + torso, head, base, heading.
    pub fn model_features(&self) -> usize {
        self.latent() + ROBOT_FEATURES - ARM
    }

    /// Robot features (b, t, 24) → model features (b, t, latent + 10).
    pub fn to_model(&self, x: &Tensor) -> Result<Tensor> {
        let (b, t, _) = x.dims3()?;
        let arm = x.narrow(D::Minus1, 0, ARM)?.reshape((b * t, ARM))?;
        let z = self
            .r
            .net()
            .encode_robot(&arm)?
            .reshape((b, t, self.latent()))?;
        Tensor::cat(
            &[z, x.narrow(D::Minus1, ARM, ROBOT_FEATURES - ARM)?],
            D::Minus1,
        )
    }

    /// Model features (b, t, latent + 10) → robot features (b, t, 24).
    pub fn from_model(&self, y: &Tensor) -> Result<Tensor> {
        let (b, t, _) = y.dims3()?;
        let l = self.latent();
        let z = y.narrow(D::Minus1, 0, l)?.reshape((b * t, l))?;
        let q = self.r.net().decode(&z)?.reshape((b, t, ARM))?;
        Tensor::cat(
            &[q, y.narrow(D::Minus1, l, ROBOT_FEATURES - ARM)?],
            D::Minus1,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;

    #[test]
    fn round_trip_keeps_the_rest_and_arm_joints_stay_in_limits() {
        let model = echo_robot::RobotModel::tiago_dual();
        let stem = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/retargeter");
        let r = Retargeter::load(&stem, model.clone()).expect("models/retargeter");
        let c = RobotCodec::new(&r);
        let mut v = vec![0f32; 2 * 3 * ROBOT_FEATURES];
        for (k, x) in v.iter_mut().enumerate() {
            *x = ((k as f32) * 0.37).sin() * 0.5;
        }
        let x = Tensor::from_vec(v, (2, 3, ROBOT_FEATURES), &Device::Cpu).unwrap();
        let m = c.to_model(&x).unwrap();
        assert_eq!(m.dims3().unwrap(), (2, 3, c.model_features()));
        let back = c.from_model(&m).unwrap();
        let (xb, bb) = (x.to_vec3::<f32>().unwrap(), back.to_vec3::<f32>().unwrap());
        let limits = echo_retarget::net::arm_limits(&model);
        for (fx, fb) in xb.iter().flatten().zip(bb.iter().flatten()) {
            assert_eq!(fx[ARM..], fb[ARM..], "torso, head, base pass through");
            for (q, (lo, hi)) in fb[..ARM].iter().zip(&limits) {
                assert!(*q as f64 >= lo - 1e-5 && *q as f64 <= hi + 1e-5);
            }
        }
    }
}
