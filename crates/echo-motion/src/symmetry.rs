//! The symmetries of a scene of people (one body per person, the same frame): the mirror image
//! across the x–z plane (y → −y, left and right exchanged: [`crate::skeleton::mirror`]), the
//! two people's roles exchanged, and both. Each is its own inverse. A forecast averaged over
//! them, each copy mapped back, does not depend on which person is called A nor on left and
//! right (`echo_eval::symmetry` offline, the forecaster service's `symmetrize` live).

use nalgebra::Vector3;

use crate::skeleton::{mirror as mirror_body, NUM_JOINTS};

/// One person's joints.
pub type Body = [Vector3<f64>; NUM_JOINTS];

/// A transform of one frame of a scene (its own inverse).
pub type Symmetry = fn(&[Body]) -> Vec<Body>;

/// The scene unchanged.
pub fn identity(scene: &[Body]) -> Vec<Body> {
    scene.to_vec()
}

/// Every person mirrored across the x–z plane.
pub fn mirror(scene: &[Body]) -> Vec<Body> {
    scene.iter().map(mirror_body).collect()
}

/// The people's order reversed (for two people: A and B exchanged).
pub fn swap(scene: &[Body]) -> Vec<Body> {
    scene.iter().rev().copied().collect()
}

/// Mirrored and exchanged.
pub fn mirror_swap(scene: &[Body]) -> Vec<Body> {
    mirror(&swap(scene))
}

/// The symmetries of a two-person scene.
pub const PAIR: [Symmetry; 4] = [identity, mirror, swap, mirror_swap];

/// The symmetries of one person.
pub const SINGLE: [Symmetry; 2] = [identity, mirror];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_symmetry_is_its_own_inverse_and_they_differ() {
        let body = |o: f64| -> Body {
            std::array::from_fn(|j| Vector3::new(o + 0.1 * j as f64, 0.03 * j as f64, 1.0))
        };
        let scene = vec![body(0.0), body(2.0)];
        for (i, g) in PAIR.iter().enumerate() {
            assert_eq!(g(&g(&scene)), scene, "{i}");
            for h in &PAIR[i + 1..] {
                assert_ne!(g(&scene), h(&scene));
            }
        }
        assert_eq!(swap(&scene)[0], scene[1]);
    }
}
