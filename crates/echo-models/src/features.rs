//! Per-frame features of an agent, in a window's canonical frame.
//!
//! Canonical frame: origin on the floor under agent A's pelvis at the last observed frame, x
//! along A's facing direction then, z up. Per agent and frame: local pose (22 joints relative to
//! the agent's pelvis, in the agent's heading frame: 66 values), root position (3) and heading
//! quaternion (a yaw, 4) — the paper's [local pose, root xyz + quaternion], 73 values.

use echo_motion::skeleton::{heading, NUM_JOINTS};
use echo_motion::symmetry::Body;
use nalgebra::{UnitQuaternion, Vector3};

/// Values per agent and frame.
pub const FEATURES: usize = 3 * NUM_JOINTS + 3 + 4;

/// The canonical frame of a window: world → canonical.
#[derive(Debug, Clone, Copy)]
pub struct Canonical {
    origin: Vector3<f64>,
    rot: UnitQuaternion<f64>,
}

impl Canonical {
    /// From agent A's joints at the last observed frame.
    pub fn of(a: &[Vector3<f64>; NUM_JOINTS]) -> Canonical {
        let h = heading(a);
        Canonical {
            origin: Vector3::new(a[0].x, a[0].y, 0.0),
            rot: h.inverse(),
        }
    }

    /// Heading of the window frame in the world (yaw about z), radians.
    pub fn yaw(self) -> f64 {
        self.rot.inverse().euler_angles().2
    }

    /// A window-frame point in the world.
    pub fn window_to_world(self, p: &Vector3<f64>) -> Vector3<f64> {
        self.to_world(p)
    }

    /// A world point in the window frame.
    pub fn world_to_window(self, p: &Vector3<f64>) -> Vector3<f64> {
        self.to_local(p)
    }

    fn to_local(self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rot * (p - self.origin)
    }

    fn to_world(self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rot.inverse() * p + self.origin
    }
}

/// Features of one agent's joints (world) in the canonical frame `c`.
pub fn encode(c: &Canonical, joints: &[Vector3<f64>; NUM_JOINTS]) -> [f32; FEATURES] {
    let p: [Vector3<f64>; NUM_JOINTS] = std::array::from_fn(|k| c.to_local(&joints[k]));
    let h = heading(&p);
    let root = p[0];
    let mut f = [0f32; FEATURES];
    for (k, x) in p.iter().enumerate() {
        let l = h.inverse() * (x - root);
        f[3 * k] = l.x as f32;
        f[3 * k + 1] = l.y as f32;
        f[3 * k + 2] = l.z as f32;
    }
    let o = 3 * NUM_JOINTS;
    f[o] = root.x as f32;
    f[o + 1] = root.y as f32;
    f[o + 2] = root.z as f32;
    f[o + 3] = h.i as f32;
    f[o + 4] = h.j as f32;
    f[o + 5] = h.k as f32;
    f[o + 6] = h.w as f32;
    f
}

/// A unit quaternion from 4 feature values `[x, y, z, w]`, renormalised (any 4 values decode;
/// near-zero ones to the identity).
pub fn quaternion(v: &[f32]) -> UnitQuaternion<f64> {
    let q = nalgebra::Quaternion::new(v[3] as f64, v[0] as f64, v[1] as f64, v[2] as f64);
    if q.norm() > 1e-6 {
        UnitQuaternion::from_quaternion(q)
    } else {
        UnitQuaternion::identity()
    }
}

/// Joints (world) back from features: the quaternion is renormalised (any 4 values decode).
pub fn decode(c: &Canonical, f: &[f32]) -> [Vector3<f64>; NUM_JOINTS] {
    let o = 3 * NUM_JOINTS;
    let root = Vector3::new(f[o] as f64, f[o + 1] as f64, f[o + 2] as f64);
    let h = quaternion(&f[o + 3..o + 7]);
    std::array::from_fn(|k| {
        let l = Vector3::new(f[3 * k] as f64, f[3 * k + 1] as f64, f[3 * k + 2] as f64);
        c.to_world(&(root + h * l))
    })
}

/// Features of a window's observed frames for both agents: `[agent][frame][feature]`, and the
/// canonical frame used.
pub fn encode_frames(frames: &[Vec<Body>]) -> (Canonical, Vec<Vec<[f32; FEATURES]>>) {
    let last = &frames[frames.len() - 1];
    let c = Canonical::of(&last[0]);
    let agents = (0..2)
        .map(|a| frames.iter().map(|f| encode(&c, &f[a])).collect())
        .collect();
    (c, agents)
}

#[cfg(test)]
mod tests {
    use super::*;
    use echo_motion::synth::{generate, Split};

    #[test]
    fn encode_decode_round_trip() {
        let clip = generate(&Split::Test.clip(3));
        let a = clip.joints(40, 0);
        let b = clip.joints(40, 1);
        let c = Canonical::of(&a);
        for x in [a, b] {
            let back = decode(&c, &encode(&c, &x));
            for k in 0..NUM_JOINTS {
                assert!((back[k] - x[k]).norm() < 1e-5);
            }
        }
        // A is at the canonical origin facing +x.
        let f = encode(&c, &a);
        let o = 3 * NUM_JOINTS;
        assert!(f[o].abs() < 1e-6 && f[o + 1].abs() < 1e-6);
        assert!((f[o + 6] - 1.0).abs() < 1e-6, "identity heading");
    }
}
