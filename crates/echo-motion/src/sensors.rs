//! Contact and proximity sensors on a capsule body model.
//!
//! Each person is 12 capsules: head (sphere), torso (pelvis–neck), upper arms, forearms, hands
//! (spheres beyond the wrists), thighs and shins; radii scale with the body (pelvis–neck length
//! relative to the reference 0.57 m). The sensor `S_m(A, B)` fires for a pair of parts when
//! their surfaces are within margin `m`; the adaptive proximity weight of the method is
//! `w_pr = 0.5·S_0 + 0.5·S_0.05`.

use echo_geometry::Capsule;
use nalgebra::Vector3;

use crate::skeleton::{j, NUM_JOINTS};

/// A body part of the capsule model (`true` = left).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BodyPart {
    /// Head sphere.
    Head,
    /// Pelvis to neck.
    Torso,
    /// Shoulder to elbow.
    UpperArm(bool),
    /// Elbow to wrist.
    Forearm(bool),
    /// Hand sphere beyond the wrist.
    Hand(bool),
    /// Hip to knee.
    Thigh(bool),
    /// Knee to ankle.
    Shin(bool),
}

/// Number of capsules per person.
pub const NUM_PARTS: usize = 12;

/// Contact margin of `S_0`, metres.
pub const CONTACT_MARGIN: f64 = 0.0;
/// Proximity margin of `S_0.05`, metres.
pub const PROXIMITY_MARGIN: f64 = 0.05;

/// The capsules of a person (11 parts, legs as thigh + shin) from SMPL-22 joint positions (empty if fewer joints are given).
pub fn body_capsules(p: &[Vector3<f64>]) -> Vec<(BodyPart, Capsule)> {
    if p.len() < NUM_JOINTS {
        return vec![];
    }
    let s = ((p[j::NECK] - p[j::PELVIS]).norm() / 0.57).clamp(0.6, 1.5);
    let cap = |a: usize, b: usize, r: f64| Capsule {
        a: p[a],
        b: p[b],
        radius: r * s,
    };
    let hand = |w: usize, e: usize| {
        let dir = (p[w] - p[e])
            .try_normalize(1e-9)
            .unwrap_or_else(Vector3::zeros);
        Capsule::sphere(p[w] + dir * 0.08 * s, 0.05 * s)
    };
    vec![
        (BodyPart::Head, Capsule::sphere(p[j::HEAD], 0.11 * s)),
        (BodyPart::Torso, cap(j::PELVIS, j::NECK, 0.16)),
        (
            BodyPart::UpperArm(true),
            cap(j::L_SHOULDER, j::L_ELBOW, 0.05),
        ),
        (
            BodyPart::UpperArm(false),
            cap(j::R_SHOULDER, j::R_ELBOW, 0.05),
        ),
        (BodyPart::Forearm(true), cap(j::L_ELBOW, j::L_WRIST, 0.04)),
        (BodyPart::Forearm(false), cap(j::R_ELBOW, j::R_WRIST, 0.04)),
        (BodyPart::Hand(true), hand(j::L_WRIST, j::L_ELBOW)),
        (BodyPart::Hand(false), hand(j::R_WRIST, j::R_ELBOW)),
        (BodyPart::Thigh(true), cap(j::L_HIP, j::L_KNEE, 0.07)),
        (BodyPart::Thigh(false), cap(j::R_HIP, j::R_KNEE, 0.07)),
        (BodyPart::Shin(true), cap(j::L_KNEE, j::L_ANKLE, 0.05)),
        (BodyPart::Shin(false), cap(j::R_KNEE, j::R_ANKLE, 0.05)),
    ]
}

/// Surface distances between every part of A and every part of B (`[a][b]`). Works for any
/// two capsule models: person–person, or person–robot with the robot's capsules
/// (`echo_robot::collision::RobotBody::at`).
pub fn part_distances<A, B>(a: &[(A, Capsule)], b: &[(B, Capsule)]) -> Vec<Vec<f64>> {
    a.iter()
        .map(|(_, ca)| b.iter().map(|(_, cb)| ca.distance(cb)).collect())
        .collect()
}

/// `S_m(A, B)` per part pair: surfaces within `margin`.
pub fn sensor(distances: &[Vec<f64>], margin: f64) -> Vec<Vec<bool>> {
    distances
        .iter()
        .map(|row| row.iter().map(|d| *d <= margin).collect())
        .collect()
}

/// Whether any pair fires.
pub fn any(s: &[Vec<bool>]) -> bool {
    s.iter().flatten().any(|x| *x)
}

/// The adaptive proximity weight per part pair: `0.5·S_0 + 0.5·S_0.05`.
pub fn proximity_weight(distances: &[Vec<f64>]) -> Vec<Vec<f64>> {
    distances
        .iter()
        .map(|row| {
            row.iter()
                .map(|d| {
                    0.5 * f64::from(u8::from(*d <= CONTACT_MARGIN))
                        + 0.5 * f64::from(u8::from(*d <= PROXIMITY_MARGIN))
                })
                .collect()
        })
        .collect()
}

/// Frame-level contact (`S_0`) and proximity (`S_0.05`) between two people.
pub fn contact_and_proximity(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> (bool, bool) {
    let d = part_distances(&body_capsules(a), &body_capsules(b));
    let min = d.iter().flatten().fold(f64::INFINITY, |m, x| m.min(*x));
    (min <= CONTACT_MARGIN, min <= PROXIMITY_MARGIN)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::{forward, Body, Pose};

    fn person_at(x: f64, yaw: f64) -> [Vector3<f64>; NUM_JOINTS] {
        let b = Body::with_height(1.75);
        forward(
            &b,
            &Pose::rest(Vector3::new(x, 0.0, b.pelvis_height()), yaw),
        )
    }

    #[test]
    fn contact_needs_touching_and_proximity_is_five_centimetres() {
        // T-poses facing each other: hands (0.55 m to the side) meet only sideways.
        let a = person_at(0.0, 0.0);
        let far = person_at(2.0, std::f64::consts::PI);
        assert_eq!(contact_and_proximity(&a, &far), (false, false));
        // Torsos of radius 0.16 each: 0.30 m apart → overlap → contact.
        let near = person_at(0.30, std::f64::consts::PI);
        assert_eq!(contact_and_proximity(&a, &near), (true, true));
        // 0.35 m apart: surfaces 3 cm apart → proximity only.
        let close = person_at(0.35, std::f64::consts::PI);
        assert_eq!(contact_and_proximity(&a, &close), (false, true));
    }

    #[test]
    fn the_same_sensor_works_between_a_person_and_the_robot() {
        let m = echo_robot::RobotModel::tiago_dual();
        let home = echo_robot::home_pose();
        let q = m
            .values_from(home.iter().map(|(n, v)| (n.as_str(), *v)))
            .unwrap();
        let robot = echo_robot::collision::RobotBody::tiago(&m)
            .unwrap()
            .at(&m, &q);
        let near = body_capsules(&person_at(0.46, std::f64::consts::PI));
        let far = body_capsules(&person_at(2.0, std::f64::consts::PI));
        assert!(any(&sensor(
            &part_distances(&near, &robot),
            PROXIMITY_MARGIN
        )));
        assert!(!any(&sensor(
            &part_distances(&far, &robot),
            PROXIMITY_MARGIN
        )));
    }

    #[test]
    fn weight_is_half_for_proximity_and_one_for_contact() {
        let d = vec![vec![-0.01, 0.03, 0.2]];
        assert_eq!(proximity_weight(&d), vec![vec![1.0, 0.5, 0.0]]);
        let s = sensor(&d, 0.05);
        assert_eq!(s, vec![vec![true, true, false]]);
        assert!(any(&s));
    }
}
