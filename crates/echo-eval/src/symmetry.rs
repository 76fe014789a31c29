//! Symmetrized prediction: the average of a predictor's forecasts of the scene as observed, its
//! mirror image, and — for two people — with the people's roles exchanged (and both), each
//! mapped back. The result is exactly invariant to which person is called A and to left/right
//! reflection, whatever the inner predictor learned; averaging also shrinks what the forecasts
//! disagree on. Valid only when the window's description names no role or side (real captures'
//! prompts such as "Two people walk up to each other and shake hands."): the description is
//! passed unchanged to every copy.
//!
//! ```text
//! ŷ = ¼ Σ_{g ∈ {id, M, S, M∘S}} g⁻¹( f( g(x) ) )     M: y → −y, left ↔ right   S: A ↔ B
//! ```

use echo_motion::symmetry::{Symmetry, PAIR, SINGLE};
use nalgebra::Vector3;

use crate::metrics::Frame;
use crate::window::{Predictor, Window};

/// A predictor averaged over the symmetries of a two-person scene (module docs).
pub struct Symmetrized<P>(pub P);

impl<P: Predictor> Predictor for Symmetrized<P> {
    fn name(&self) -> String {
        format!("{} (symmetrized)", self.0.name())
    }

    fn predict(&mut self, batch: &[&Window]) -> Vec<Vec<Frame>> {
        let pair = batch.iter().all(|w| w.obs.iter().all(|f| f.len() == 2));
        let group: &[Symmetry] = if pair { &PAIR } else { &SINGLE };
        // Every transform is its own inverse; all copies go through one call (one batch).
        let copies: Vec<Window> = group
            .iter()
            .flat_map(|g| {
                batch.iter().map(move |w| Window {
                    obs: w.obs.iter().map(|f| g(f)).collect(),
                    ..(*w).clone()
                })
            })
            .collect();
        let refs: Vec<&Window> = copies.iter().collect();
        let preds = self.0.predict(&refs);
        let n = batch.len();
        let k = group.len() as f64;
        (0..n)
            .map(|i| {
                let back: Vec<Vec<Frame>> = group
                    .iter()
                    .enumerate()
                    .map(|(gi, g)| preds[gi * n + i].iter().map(|f| g(f)).collect())
                    .collect();
                (0..back[0].len())
                    .map(|t| {
                        (0..back[0][t].len())
                            .map(|a| {
                                std::array::from_fn(|j| {
                                    back.iter().map(|b| b[t][a][j]).sum::<Vector3<f64>>() / k
                                })
                            })
                            .collect()
                    })
                    .collect()
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::window::{ConstantVelocity, OBS_FRAMES, PRED_FRAMES};
    use echo_motion::symmetry::{mirror, swap};

    /// Deliberately lopsided: moves person A (only) towards +y, by an amount that depends on
    /// A's left wrist.
    struct Lopsided;
    impl Predictor for Lopsided {
        fn name(&self) -> String {
            "lopsided".into()
        }
        fn predict(&mut self, batch: &[&Window]) -> Vec<Vec<Frame>> {
            batch
                .iter()
                .map(|w| {
                    let last = w.obs[w.obs.len() - 1].clone();
                    let push = 0.1 + last[0][20].x.abs();
                    (1..=PRED_FRAMES)
                        .map(|k| {
                            let mut f = last.clone();
                            for j in f[0].iter_mut() {
                                j.y += push * k as f64 * 0.01;
                            }
                            f
                        })
                        .collect()
                })
                .collect()
        }
    }

    fn window(seed: f64) -> Window {
        let person = |o: f64, t: f64| -> [Vector3<f64>; 22] {
            std::array::from_fn(|j| {
                Vector3::new(
                    o + 0.01 * j as f64 + 0.03 * t * seed,
                    0.02 * (j as f64 * seed).sin() + 0.01 * t,
                    1.0 + 0.05 * j as f64,
                )
            })
        };
        Window {
            kind: echo_msgs::Interaction::Idle,
            texts: vec!["Two people stand.".into()],
            obs: (0..OBS_FRAMES)
                .map(|t| vec![person(0.0, t as f64), person(1.5, -(t as f64))])
                .collect(),
            future: vec![],
            origin: (0, 0),
        }
    }

    fn close(a: &[Frame], b: &[Frame]) -> bool {
        a.iter().zip(b).all(|(x, y)| {
            x.iter()
                .zip(y)
                .all(|(p, q)| p.iter().zip(q).all(|(u, v)| (u - v).norm() < 1e-12))
        })
    }

    #[test]
    fn the_average_is_invariant_to_roles_and_reflection_though_the_predictor_is_not() {
        let w = window(0.7);
        let swapped = Window {
            obs: w.obs.iter().map(|f| swap(f)).collect(),
            ..w.clone()
        };
        let mirrored = Window {
            obs: w.obs.iter().map(|f| mirror(f)).collect(),
            ..w.clone()
        };
        // The inner predictor depends on who is called A.
        let raw = Lopsided.predict(&[&w, &swapped]);
        let raw_back: Vec<Frame> = raw[1].iter().map(|f| swap(f)).collect();
        assert!(!close(&raw[0], &raw_back));

        let mut sym = Symmetrized(Lopsided);
        let p = sym.predict(&[&w, &swapped, &mirrored]);
        let from_swapped: Vec<Frame> = p[1].iter().map(|f| swap(f)).collect();
        let from_mirrored: Vec<Frame> = p[2].iter().map(|f| mirror(f)).collect();
        assert!(close(&p[0], &from_swapped), "role swap");
        assert!(close(&p[0], &from_mirrored), "reflection");
        assert_eq!(sym.name(), "lopsided (symmetrized)");
    }

    #[test]
    fn an_already_symmetric_predictor_is_unchanged() {
        let w = window(0.3);
        let plain = ConstantVelocity.predict(&[&w]);
        let sym = Symmetrized(ConstantVelocity).predict(&[&w]);
        assert!(close(&plain[0], &sym[0]));
        assert_eq!(sym[0].len(), PRED_FRAMES);
    }
}
