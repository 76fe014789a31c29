//! The 22-joint SMPL body skeleton: topology, rest pose, per-subject body, FK and IK.
//!
//! Rest pose: standing, arms straight out sideways (T-pose), body frame x forward, y left, z up;
//! every local rotation is the identity in the rest pose.

use nalgebra::{Rotation3, UnitQuaternion, Vector3};

use crate::rotation::{frame_from_across_up, swing};

pub use echo_msgs::skeleton::{NUM_JOINTS, SMPL22 as JOINT_NAMES};

/// Parent of each joint (-1 for the pelvis).
pub const PARENTS: [i32; NUM_JOINTS] = [
    -1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19,
];

/// Left/right counterpart of each joint (itself on the midline): what a mirror image exchanges.
pub const MIRROR: [usize; NUM_JOINTS] = [
    0, 2, 1, 3, 5, 4, 6, 8, 7, 9, 11, 10, 12, 14, 13, 15, 17, 16, 19, 18, 21, 20,
];

/// A body's mirror image across the x–z plane (y → −y), left and right joints exchanged: the
/// same body seen in a mirror standing along x. Its own inverse.
pub fn mirror(p: &[Vector3<f64>; NUM_JOINTS]) -> [Vector3<f64>; NUM_JOINTS] {
    std::array::from_fn(|j| {
        let s = p[MIRROR[j]];
        Vector3::new(s.x, -s.y, s.z)
    })
}

/// Kinematic chains (also used for bone-length checks).
pub const CHAINS: [&[usize]; 5] = [
    &[0, 2, 5, 8, 11],
    &[0, 1, 4, 7, 10],
    &[0, 3, 6, 9, 12, 15],
    &[9, 14, 17, 19, 21],
    &[9, 13, 16, 18, 20],
];

/// Named joint indices.
#[allow(missing_docs)]
pub mod j {
    pub const PELVIS: usize = 0;
    pub const L_HIP: usize = 1;
    pub const R_HIP: usize = 2;
    pub const SPINE1: usize = 3;
    pub const L_KNEE: usize = 4;
    pub const R_KNEE: usize = 5;
    pub const SPINE2: usize = 6;
    pub const L_ANKLE: usize = 7;
    pub const R_ANKLE: usize = 8;
    pub const SPINE3: usize = 9;
    pub const L_FOOT: usize = 10;
    pub const R_FOOT: usize = 11;
    pub const NECK: usize = 12;
    pub const L_COLLAR: usize = 13;
    pub const R_COLLAR: usize = 14;
    pub const HEAD: usize = 15;
    pub const L_SHOULDER: usize = 16;
    pub const R_SHOULDER: usize = 17;
    pub const L_ELBOW: usize = 18;
    pub const R_ELBOW: usize = 19;
    pub const L_WRIST: usize = 20;
    pub const R_WRIST: usize = 21;
}

/// Rest offsets of each joint from its parent for a 1.75 m person (metres, body frame).
const REST_OFFSETS: [[f64; 3]; NUM_JOINTS] = [
    [0.0, 0.0, 0.0],
    [0.0, 0.09, -0.09],
    [0.0, -0.09, -0.09],
    [-0.01, 0.0, 0.11],
    [0.0, 0.01, -0.40],
    [0.0, -0.01, -0.40],
    [0.0, 0.0, 0.14],
    [-0.01, 0.0, -0.40],
    [-0.01, 0.0, -0.40],
    [0.0, 0.0, 0.08],
    [0.12, 0.0, -0.06],
    [0.12, 0.0, -0.06],
    [0.0, 0.0, 0.24],
    [0.0, 0.07, 0.13],
    [0.0, -0.07, 0.13],
    [0.02, 0.0, 0.11],
    [0.0, 0.11, 0.02],
    [0.0, -0.11, 0.02],
    [0.0, 0.27, 0.0],
    [0.0, -0.27, 0.0],
    [0.0, 0.25, 0.0],
    [0.0, -0.25, 0.0],
];

/// Standing pelvis height of the reference 1.75 m body.
pub const REST_PELVIS_HEIGHT: f64 = 0.96;

/// Children of each joint.
pub fn children(joint: usize) -> impl Iterator<Item = usize> {
    (0..NUM_JOINTS).filter(move |c| PARENTS[*c] == joint as i32)
}

/// A subject's body: the offset of every joint from its parent in the parent's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// Offsets (index 0 unused).
    pub offsets: [Vector3<f64>; NUM_JOINTS],
}

impl Body {
    /// The reference body scaled to `height_m` (top of head; the reference is 1.75 m).
    pub fn with_height(height_m: f64) -> Body {
        let s = height_m / 1.75;
        Body {
            offsets: REST_OFFSETS.map(|o| Vector3::from(o) * s),
        }
    }

    /// Bone length from each joint's parent.
    pub fn bone_lengths(&self) -> [f64; NUM_JOINTS] {
        self.offsets.map(|o| o.norm())
    }

    /// Standing pelvis height of this body.
    pub fn pelvis_height(&self) -> f64 {
        // hip drop + thigh + shin + ankle-to-sole allowance
        -(self.offsets[j::L_HIP].z + self.offsets[j::L_KNEE].z + self.offsets[j::L_ANKLE].z)
            + 0.06 * self.offsets[j::L_KNEE].norm() / 0.40
    }
}

/// A pose: root position and heading, and a local rotation per joint.
#[derive(Debug, Clone, PartialEq)]
pub struct Pose {
    /// Pelvis position in the world.
    pub root_position: Vector3<f64>,
    /// Root frame: heading about z (x = facing direction on the floor).
    pub root_orientation: UnitQuaternion<f64>,
    /// Rotation of each joint relative to its parent; entry 0 is the pelvis relative to the root frame.
    pub local: [UnitQuaternion<f64>; NUM_JOINTS],
}

impl Pose {
    /// The rest pose at `root_position` facing `yaw`.
    pub fn rest(root_position: Vector3<f64>, yaw: f64) -> Pose {
        Pose {
            root_position,
            root_orientation: UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
            local: [UnitQuaternion::identity(); NUM_JOINTS],
        }
    }

    /// Global rotation of every joint.
    pub fn global_rotations(&self) -> [UnitQuaternion<f64>; NUM_JOINTS] {
        let mut g = [UnitQuaternion::identity(); NUM_JOINTS];
        g[0] = self.root_orientation * self.local[0];
        for k in 1..NUM_JOINTS {
            g[k] = g[PARENTS[k] as usize] * self.local[k];
        }
        g
    }
}

/// Forward kinematics: joint positions of `pose` for `body`.
pub fn forward(body: &Body, pose: &Pose) -> [Vector3<f64>; NUM_JOINTS] {
    let g = pose.global_rotations();
    let mut p = [Vector3::zeros(); NUM_JOINTS];
    p[0] = pose.root_position;
    for k in 1..NUM_JOINTS {
        let parent = PARENTS[k] as usize;
        p[k] = p[parent] + g[parent] * body.offsets[k];
    }
    p
}

/// Heading of a skeleton from its hips and shoulders: x = facing direction on the floor (z up).
pub fn heading(p: &[Vector3<f64>; NUM_JOINTS]) -> UnitQuaternion<f64> {
    let across = (p[j::R_HIP] - p[j::L_HIP]) + (p[j::R_SHOULDER] - p[j::L_SHOULDER]);
    let fwd = Vector3::z().cross(&across);
    let yaw = if fwd.xy().norm() < 1e-9 {
        0.0
    } else {
        fwd.y.atan2(fwd.x)
    };
    UnitQuaternion::from_euler_angles(0.0, 0.0, yaw)
}

/// Inverse kinematics: the body (offsets measured from these positions) and the pose whose
/// forward kinematics reproduces `p`. Leaf joints (feet, head, wrists) get identity rotations.
pub fn inverse(p: &[Vector3<f64>; NUM_JOINTS]) -> (Body, Pose) {
    let rest = Body::with_height(1.75);
    let root = heading(p);
    let mut g = [UnitQuaternion::identity(); NUM_JOINTS];
    let mut local = [UnitQuaternion::identity(); NUM_JOINTS];
    let mut offsets = [Vector3::zeros(); NUM_JOINTS];

    // Pelvis and upper spine have several children: full frame from two directions.
    let multi = |across: Vector3<f64>, up: Vector3<f64>, fallback: UnitQuaternion<f64>| {
        frame_from_across_up(&across, &up)
            .map(|r: Rotation3<f64>| UnitQuaternion::from_rotation_matrix(&r))
            .unwrap_or(fallback)
    };
    for k in 0..NUM_JOINTS {
        let parent_g = if k == 0 { root } else { g[PARENTS[k] as usize] };
        if k > 0 {
            offsets[k] = g[PARENTS[k] as usize].inverse() * (p[k] - p[PARENTS[k] as usize]);
        }
        let kids: Vec<usize> = children(k).collect();
        g[k] = match kids.as_slice() {
            [] => parent_g,
            [c] => {
                let observed = parent_g.inverse() * (p[*c] - p[k]);
                parent_g * swing(&rest.offsets[*c], &observed)
            }
            _ if k == j::PELVIS => multi(p[j::L_HIP] - p[j::R_HIP], p[j::SPINE1] - p[0], root),
            _ => multi(p[j::L_COLLAR] - p[j::R_COLLAR], p[j::NECK] - p[k], parent_g),
        };
        local[k] = parent_g.inverse() * g[k];
    }
    // Multi-child frames are exact by construction; single-child offsets are along the rest
    // direction with the measured length: rewrite them so FK reproduces `p` exactly.
    for k in 1..NUM_JOINTS {
        let parent = PARENTS[k] as usize;
        offsets[k] = g[parent].inverse() * (p[k] - p[parent]);
    }
    (
        Body { offsets },
        Pose {
            root_position: p[0],
            root_orientation: root,
            local,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mirror_image_exchanges_left_and_right_and_is_its_own_inverse() {
        let p = forward(&Body::with_height(1.7), &random_pose(3));
        let m = mirror(&p);
        // Joint 20 is the left wrist, 21 the right one.
        assert_eq!(JOINT_NAMES[20], "left_wrist");
        assert!((m[21] - Vector3::new(p[20].x, -p[20].y, p[20].z)).norm() < 1e-12);
        for (a, b) in mirror(&m).iter().zip(&p) {
            assert!((a - b).norm() < 1e-12);
        }
    }

    fn random_pose(seed: u64) -> Pose {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut pose = Pose::rest(Vector3::new(1.5, -0.3, 0.95), rng.random_range(-3.0..3.0));
        for q in pose.local.iter_mut() {
            *q = UnitQuaternion::from_euler_angles(
                rng.random_range(-0.6..0.6),
                rng.random_range(-0.6..0.6),
                rng.random_range(-0.6..0.6),
            );
        }
        pose
    }

    #[test]
    fn ik_then_fk_reproduces_positions() {
        for seed in 0..50 {
            let body = Body::with_height(1.5 + 0.01 * seed as f64);
            let p = forward(&body, &random_pose(seed));
            let (b2, pose2) = inverse(&p);
            let p2 = forward(&b2, &pose2);
            let err = (0..NUM_JOINTS)
                .map(|k| (p[k] - p2[k]).norm())
                .fold(0.0, f64::max);
            assert!(err < 1e-9, "seed {seed}: {err} m");
            // Bone lengths are the subject's.
            for k in 1..NUM_JOINTS {
                assert!((b2.offsets[k].norm() - body.offsets[k].norm()).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn ik_recovers_heading_and_arm_rotation() {
        let body = Body::with_height(1.75);
        let mut pose = Pose::rest(Vector3::new(2.0, 0.0, 0.96), std::f64::consts::PI);
        // Lower the right upper arm by 80° (rotation about the body x axis).
        pose.local[j::R_SHOULDER] = UnitQuaternion::from_euler_angles(1.4, 0.0, 0.0);
        let p = forward(&body, &pose);
        let (_, got) = inverse(&p);
        assert!(got.root_orientation.angle_to(&pose.root_orientation) < 1e-9);
        assert!(got.local[j::R_SHOULDER].angle_to(&pose.local[j::R_SHOULDER]) < 1e-9);
    }

    #[test]
    fn rest_body_is_as_tall_as_asked() {
        let body = Body::with_height(1.75);
        let p = forward(
            &body,
            &Pose::rest(Vector3::new(0.0, 0.0, body.pelvis_height()), 0.0),
        );
        // Head joint sits ~0.1 m below the top of the head; ankles ~0.06 m above the floor.
        assert!((p[j::HEAD].z - 1.63).abs() < 0.05, "{}", p[j::HEAD].z);
        assert!((p[j::L_ANKLE].z - 0.06).abs() < 0.03, "{}", p[j::L_ANKLE].z);
    }
}
