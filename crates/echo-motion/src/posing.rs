//! Building poses from intentions: where each hand should be, where the head looks, how far the
//! spine bends, the gait phase. Arms are solved by two-bone inverse kinematics with an elbow
//! hint; everything ends as local rotations, so the skeleton's bone lengths never change.

use std::f64::consts::PI;

use nalgebra::{UnitQuaternion, Vector3};

use crate::rotation::swing;
use crate::skeleton::{j, Body, Pose, PARENTS};

/// What one person does at one instant.
#[derive(Debug, Clone, PartialEq)]
pub struct Intent {
    /// Pelvis position on the floor plane (x, y); the height follows the body.
    pub root_xy: [f64; 2],
    /// Facing direction (yaw about z).
    pub yaw: f64,
    /// Forward bend of the spine, radians (bow).
    pub spine_pitch: f64,
    /// Left hand target in the body frame relative to the left shoulder (`None`: arm down).
    pub left_hand: Option<Vector3<f64>>,
    /// Right hand target in the body frame relative to the right shoulder.
    pub right_hand: Option<Vector3<f64>>,
    /// Point the head looks at, in the world (`None`: straight ahead).
    pub look_at: Option<Vector3<f64>>,
    /// Gait phase (radians) and amplitude in [0, 1] (0 = standing).
    pub gait: (f64, f64),
    /// Arm swing while walking, in [0, 1] (0: the arms hang still): each arm swings opposite
    /// its leg, ±0.2 arm lengths at full gait; an arm reaching for something swings less the
    /// further its target is from the hanging position.
    pub arm_swing: f64,
}

impl Intent {
    /// Standing at `(x, y)` facing `yaw`.
    pub fn standing(x: f64, y: f64, yaw: f64) -> Intent {
        Intent {
            root_xy: [x, y],
            yaw,
            spine_pitch: 0.0,
            left_hand: None,
            right_hand: None,
            look_at: None,
            gait: (0.0, 0.0),
            arm_swing: 0.0,
        }
    }
}

/// Solve the pose for `intent`.
pub fn pose(body: &Body, it: &Intent) -> Pose {
    let mut root = Vector3::new(it.root_xy[0], it.root_xy[1], body.pelvis_height());
    let (phase, amp) = it.gait;
    root.z -= 0.015 * amp * (2.0 * phase).cos().abs();
    let mut p = Pose::rest(root, it.yaw);
    // Spine: the bend spread over three joints.
    let bend = UnitQuaternion::from_euler_angles(0.0, it.spine_pitch / 3.0, 0.0);
    p.local[j::SPINE1] = bend;
    p.local[j::SPINE2] = bend;
    p.local[j::SPINE3] = bend;
    // Legs: a gait whose hip swing moves the stance foot back by one step (0.6 m) per half
    // cycle, so that with the phase driven by the distance walked the stance foot stays nearly
    // put; the swing knee bends to lift the foot off the floor.
    if amp > 0.0 {
        let leg = body.offsets[j::L_KNEE].norm() + body.offsets[j::L_ANKLE].norm();
        let swing_amp = (0.3 / leg).clamp(0.0, 0.9).asin();
        for (hip, knee, sign) in [(j::L_HIP, j::L_KNEE, 1.0), (j::R_HIP, j::R_KNEE, -1.0)] {
            let s = phase.sin() * sign;
            let lift = (phase.cos() * sign).max(0.0);
            p.local[hip] = UnitQuaternion::from_euler_angles(0.0, -swing_amp * s * amp, 0.0);
            p.local[knee] = UnitQuaternion::from_euler_angles(0.0, 1.1 * lift * lift * amp, 0.0);
        }
    }
    // Arms.
    for (right, target) in [(false, it.left_hand), (true, it.right_hand)] {
        let down = arm_down(body, right);
        let mut target = target.unwrap_or(down);
        if it.arm_swing > 0.0 && amp > 0.0 {
            // The left arm swings back as the left leg swings forward (sin(phase) > 0).
            let sign = if right { 1.0 } else { -1.0 };
            let free = 1.0 - ((target - down).norm() / 0.3).clamp(0.0, 1.0);
            target.x +=
                sign * 0.2 * arm_length(body, right) * it.arm_swing * amp * free * phase.sin();
        }
        reach(&mut p, body, right, &target);
    }
    // Head: yaw and pitch toward the target, limited to what a neck does.
    if let Some(t) = it.look_at {
        let g = p.global_rotations();
        let neck_g = g[j::NECK];
        let head_pos = crate::skeleton::forward(body, &p)[j::HEAD];
        let d = neck_g.inverse() * (t - head_pos);
        let yaw = d.y.atan2(d.x).clamp(-1.2, 1.2);
        let pitch = (-d.z).atan2(d.xy().norm()).clamp(-0.6, 0.6);
        p.local[j::HEAD] = UnitQuaternion::from_euler_angles(0.0, pitch * 0.6, yaw * 0.6);
        p.local[j::NECK] = UnitQuaternion::from_euler_angles(0.0, pitch * 0.4, yaw * 0.4);
    }
    p
}

/// Hand target of a relaxed arm hanging down (relative to the shoulder, body frame).
pub fn arm_down(body: &Body, right: bool) -> Vector3<f64> {
    let side = if right { -1.0 } else { 1.0 };
    let l = arm_length(body, right);
    Vector3::new(0.06, 0.08 * side, -0.96 * l)
}

/// Upper arm + forearm length.
pub fn arm_length(body: &Body, right: bool) -> f64 {
    let (e, w) = if right {
        (j::R_ELBOW, j::R_WRIST)
    } else {
        (j::L_ELBOW, j::L_WRIST)
    };
    body.offsets[e].norm() + body.offsets[w].norm()
}

/// Set shoulder and elbow so the wrist reaches `target` (body frame, relative to the shoulder),
/// elbow hanging down and slightly out; unreachable targets are approached along the line.
pub fn reach(p: &mut Pose, body: &Body, right: bool, target: &Vector3<f64>) {
    let (shoulder, elbow, wrist) = if right {
        (j::R_SHOULDER, j::R_ELBOW, j::R_WRIST)
    } else {
        (j::L_SHOULDER, j::L_ELBOW, j::L_WRIST)
    };
    let l1 = body.offsets[elbow].norm();
    let l2 = body.offsets[wrist].norm();
    let d = target.norm().clamp((l1 - l2).abs() + 1e-3, l1 + l2 - 1e-3);
    let u = target.try_normalize(1e-9).unwrap_or(-Vector3::z());
    let side = if right { -1.0 } else { 1.0 };
    let hint = Vector3::new(-0.3, 0.5 * side, -1.0);
    let n = (hint - u * u.dot(&hint))
        .try_normalize(1e-9)
        .unwrap_or(Vector3::x());
    let cos_a = ((l1 * l1 + d * d - l2 * l2) / (2.0 * l1 * d)).clamp(-1.0, 1.0);
    let a = cos_a.acos();
    let e = (u * a.cos() + n * a.sin()) * l1;
    let upper = e;
    let fore = u * d - e;
    set_arm(p, body, shoulder, elbow, wrist, &upper, &fore);
}

/// Local rotations making the upper arm and forearm point along `upper` and `fore` (body frame).
fn set_arm(
    p: &mut Pose,
    body: &Body,
    shoulder: usize,
    elbow: usize,
    wrist: usize,
    upper: &Vector3<f64>,
    fore: &Vector3<f64>,
) {
    let g = p.global_rotations();
    let heading = p.root_orientation;
    let collar_g = g[PARENTS[shoulder] as usize];
    let s_g = collar_g
        * swing(
            &body.offsets[elbow],
            &(collar_g.inverse() * (heading * upper)),
        );
    p.local[shoulder] = collar_g.inverse() * s_g;
    let e_g = s_g * swing(&body.offsets[wrist], &(s_g.inverse() * (heading * fore)));
    p.local[elbow] = s_g.inverse() * e_g;
}

/// Shoulder position in the world for a pose (to turn world hand targets into arm targets).
pub fn shoulder_world(body: &Body, p: &Pose, right: bool) -> Vector3<f64> {
    crate::skeleton::forward(body, p)[if right { j::R_SHOULDER } else { j::L_SHOULDER }]
}

/// A world point expressed relative to the shoulder, in the body (heading) frame.
pub fn to_arm_target(body: &Body, it: &Intent, right: bool, world: &Vector3<f64>) -> Vector3<f64> {
    let p = pose(
        body,
        &Intent {
            left_hand: None,
            right_hand: None,
            look_at: None,
            ..it.clone()
        },
    );
    let s = shoulder_world(body, &p, right);
    UnitQuaternion::from_euler_angles(0.0, 0.0, it.yaw).inverse() * (world - s)
}

/// Wrap an angle to (−π, π].
pub fn wrap(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(2.0 * PI) - PI;
    if w == -PI {
        PI
    } else {
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::forward;

    #[test]
    fn reach_puts_the_wrist_on_reachable_targets() {
        let body = Body::with_height(1.8);
        let it = Intent::standing(0.0, 0.0, 0.7);
        for target in [
            Vector3::new(0.4, -0.1, -0.1),
            Vector3::new(0.1, -0.2, 0.4),
            Vector3::new(0.3, 0.2, -0.3),
        ] {
            let mut it2 = it.clone();
            it2.right_hand = Some(target);
            let p = pose(&body, &it2);
            let x = forward(&body, &p);
            let got = UnitQuaternion::from_euler_angles(0.0, 0.0, 0.7).inverse()
                * (x[j::R_WRIST] - x[j::R_SHOULDER]);
            assert!((got - target).norm() < 1e-6, "{got:?} vs {target:?}");
        }
    }

    #[test]
    fn world_targets_round_trip() {
        let body = Body::with_height(1.6);
        let mut it = Intent::standing(1.0, 2.0, -2.0);
        let world = Vector3::new(1.3, 1.6, 1.1);
        it.left_hand = Some(to_arm_target(&body, &it, false, &world));
        let x = forward(&body, &pose(&body, &it));
        assert!((x[j::L_WRIST] - world).norm() < 1e-6);
    }

    #[test]
    fn the_head_turns_toward_what_it_looks_at() {
        let body = Body::with_height(1.75);
        let mut it = Intent::standing(0.0, 0.0, 0.0);
        it.look_at = Some(Vector3::new(1.0, 1.0, 1.6));
        let g = pose(&body, &it).global_rotations();
        let fwd = g[j::HEAD] * Vector3::x();
        assert!(fwd.y > 0.3, "{fwd:?}");
    }
}
