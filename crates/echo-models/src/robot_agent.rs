//! The robot agent's features, shared by training (echo-hri) and serving (echo-forecast): per
//! frame the 17 joint values of [`echo_robot::robot_agent_joints`], then the base position
//! (z = 0) and heading quaternion in the window frame — 24 features.

use nalgebra::{UnitQuaternion, Vector3};

use crate::features::{quaternion, Canonical};

/// Robot joint values per frame (14 arm joints, torso, head pan, head tilt).
pub const ROBOT_JOINTS: usize = 17;
/// Robot features per frame: joints, base xyz (z = 0), heading quaternion.
pub const ROBOT_FEATURES: usize = ROBOT_JOINTS + 3 + 4;

/// The robot agent's joints, in feature order ([`echo_robot::robot_agent_joints`]).
pub fn robot_joint_names() -> Vec<String> {
    echo_robot::robot_agent_joints()
}

/// The robot's features in window frame `c`.
pub fn encode_robot(c: &Canonical, q: &[f64], base: [f64; 3]) -> [f32; ROBOT_FEATURES] {
    let mut f = [0f32; ROBOT_FEATURES];
    for (k, v) in q.iter().take(ROBOT_JOINTS).enumerate() {
        f[k] = *v as f32;
    }
    let p = c.world_to_window(&Vector3::new(base[0], base[1], 0.0));
    let yaw = base[2] - c.yaw();
    let h = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw);
    let o = ROBOT_JOINTS;
    f[o] = p.x as f32;
    f[o + 1] = p.y as f32;
    f[o + 2] = 0.0;
    f[o + 3] = h.i as f32;
    f[o + 4] = h.j as f32;
    f[o + 5] = h.k as f32;
    f[o + 6] = h.w as f32;
    f
}

/// Robot joint values and base (world x, y, yaw) back from features.
pub fn decode_robot(c: &Canonical, f: &[f32]) -> (Vec<f64>, [f64; 3]) {
    let q = f[..ROBOT_JOINTS].iter().map(|v| *v as f64).collect();
    let o = ROBOT_JOINTS;
    let p = c.window_to_world(&Vector3::new(f[o] as f64, f[o + 1] as f64, 0.0));
    let yaw = quaternion(&f[o + 3..o + 7]).euler_angles().2;
    (q, [p.x, p.y, yaw + c.yaw()])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joints_match_the_feature_layout() {
        assert_eq!(robot_joint_names().len(), ROBOT_JOINTS);
        assert_eq!(robot_joint_names()[0], "arm_left_1_joint");
        assert_eq!(robot_joint_names()[16], "head_2_joint");
    }
}
