//! What the retargeter reads from a human skeleton, in the body frame built from the shoulders
//! (x forward, y left, z up — the robot torso's axes).
//!
//! - Input features: local rotations of the four arm joints as swing quaternions — the
//!   shoulder's rotation from the rest direction (straight down) to the upper arm, the elbow's
//!   rotation from the upper arm to the forearm — 4 × 4 values. Joint positions carry no twist
//!   about a bone, so none is claimed.
//! - Limb directions (upper arms, forearms) for the direction loss and the evaluation.

use echo_motion::skeleton::{j, NUM_JOINTS};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// Input features per pose.
pub const HUMAN_FEATURES: usize = 16;

/// Limbs in order: left upper arm, left forearm, right upper arm, right forearm.
pub const LIMBS: [&str; 4] = [
    "left upper arm",
    "left forearm",
    "right upper arm",
    "right forearm",
];

/// World → body rotation from the shoulders (`None` for a degenerate pose).
pub fn body_frame(p: &[Vector3<f64>; NUM_JOINTS]) -> Option<Rotation3<f64>> {
    let across = p[j::L_SHOULDER] - p[j::R_SHOULDER];
    let y = Vector3::new(across.x, across.y, 0.0);
    if y.norm() < 1e-6 {
        return None;
    }
    let y = y.normalize();
    let z = Vector3::z();
    let x = y.cross(&z);
    // Rows are the body axes: multiplying maps world vectors into the body frame.
    Some(Rotation3::from_matrix_unchecked(Matrix3::from_rows(&[
        x.transpose(),
        y.transpose(),
        z.transpose(),
    ])))
}

/// Unit limb directions in the body frame: `[L upper, L fore, R upper, R fore]`.
pub fn limb_directions(p: &[Vector3<f64>; NUM_JOINTS]) -> Option<[Vector3<f64>; 4]> {
    let r = body_frame(p)?;
    let d = |a: usize, b: usize| -> Option<Vector3<f64>> {
        let v = r * (p[b] - p[a]);
        (v.norm() > 1e-6).then(|| v.normalize())
    };
    Some([
        d(j::L_SHOULDER, j::L_ELBOW)?,
        d(j::L_ELBOW, j::L_WRIST)?,
        d(j::R_SHOULDER, j::R_ELBOW)?,
        d(j::R_ELBOW, j::R_WRIST)?,
    ])
}

fn swing(from: &Vector3<f64>, to: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between(from, to).unwrap_or_else(|| {
        // Opposite vectors: half a turn about any perpendicular axis.
        let axis = from
            .cross(&Vector3::x())
            .try_normalize(1e-9)
            .unwrap_or(Vector3::y());
        UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), std::f64::consts::PI)
    })
}

/// The retargeter's input: swing quaternions `[x, y, z, w]` of L shoulder, L elbow, R shoulder,
/// R elbow (w ≥ 0).
pub fn features(p: &[Vector3<f64>; NUM_JOINTS]) -> Option<[f32; HUMAN_FEATURES]> {
    let d = limb_directions(p)?;
    let down = -Vector3::z();
    let qs = [
        swing(&down, &d[0]),
        swing(&d[0], &d[1]),
        swing(&down, &d[2]),
        swing(&d[2], &d[3]),
    ];
    let mut f = [0f32; HUMAN_FEATURES];
    for (k, q) in qs.iter().enumerate() {
        let s = if q.w < 0.0 { -1.0 } else { 1.0 };
        f[4 * k] = (s * q.i) as f32;
        f[4 * k + 1] = (s * q.j) as f32;
        f[4 * k + 2] = (s * q.k) as f32;
        f[4 * k + 3] = (s * q.w) as f32;
    }
    Some(f)
}

/// Angle between two unit vectors, degrees.
pub fn angle_deg(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    a.dot(b).clamp(-1.0, 1.0).acos().to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;
    use echo_motion::synth::{generate, Split};

    #[test]
    fn directions_and_features_of_a_generated_pose() {
        let clip = generate(&Split::Test.clip(0));
        let p = clip.joints(10, 0);
        let d = limb_directions(&p).unwrap();
        for v in &d {
            assert!((v.norm() - 1.0).abs() < 1e-9);
        }
        let f = features(&p).unwrap();
        for k in 0..4 {
            let n: f32 = f[4 * k..4 * k + 4].iter().map(|x| x * x).sum();
            assert!((n - 1.0).abs() < 1e-5 && f[4 * k + 3] >= 0.0);
        }
        // The body frame does not depend on where the person stands or faces.
        let rot = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), 1.1);
        let moved: [Vector3<f64>; NUM_JOINTS] =
            std::array::from_fn(|k| rot * p[k] + Vector3::new(3.0, -2.0, 0.0));
        let f2 = features(&moved).unwrap();
        for (a, b) in f.iter().zip(&f2) {
            assert!((a - b).abs() < 1e-5);
        }
    }
}
