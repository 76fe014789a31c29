//! One dataset layer for training and evaluation.
//!
//! * [`spec`]: the `--data` spec: sources (synthetic, InterGen layout, two-person BVH, a CMU
//!   directory, Echo's format) with weights;
//! * [`source`]: loading each source as captures per split (the split rule of each source);
//! * [`augment`]: role swap, mirror, speed and proportion augmentations;
//! * [`stats`]: motion statistics to compare sources (synthetic against real).
//!
//! [`windows`] turns a spec into training or evaluation windows.

pub mod augment;
pub mod source;
pub mod spec;
pub mod stats;

use std::path::PathBuf;

use echo_eval::window::Window;
use echo_motion::synth::Split;
use rand::{Rng, SeedableRng};

pub use source::Capture;
pub use spec::{Family, Item, Source, Spec, SpecError};

/// Why data could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// The spec is wrong.
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// A file could not be read.
    #[error("{0}: {1}")]
    Io(PathBuf, std::io::Error),
    /// A BVH capture could not be used.
    #[error("{0}")]
    Bvh(String),
    /// A dataset directory could not be used.
    #[error("{0}")]
    Dataset(String),
    /// Nothing to use.
    #[error("{0}")]
    Empty(String),
}

/// Captures of every item of `spec` for `split`, with their items.
pub fn captures(
    spec: &Spec,
    split: Split,
    synthetic_clips: u64,
) -> Result<Vec<(Item, Vec<Capture>)>, DataError> {
    spec.items
        .iter()
        .map(|it| {
            Ok((
                it.clone(),
                source::load(&it.source, split, synthetic_clips)?,
            ))
        })
        .collect()
}

/// How windows are cut.
#[derive(Debug, Clone, Copy)]
pub struct Cut {
    /// Window stride of synthetic captures, frames at 15 Hz.
    pub stride: usize,
    /// Window stride of real captures (few and precious), frames at 15 Hz.
    pub real_stride: usize,
    /// Augmentations (training only).
    pub augment: augment::Augment,
    /// Seed of the weighted mix.
    pub seed: u64,
}

/// Windows of `per_item` captures: each item's captures (augmented), cut at `cut.stride`; when
/// any item has a weight, the items are mixed so that each one's share of the windows is its
/// weight's share (items without one weigh 1): windows are drawn with replacement, seeded, and
/// the total stays the number of windows there are.
pub fn windows(per_item: &[(Item, Vec<Capture>)], cut: &Cut) -> Vec<Window> {
    let per: Vec<(Option<f64>, Vec<Window>)> = per_item
        .iter()
        .map(|(it, caps)| {
            let w: Vec<Window> = caps
                .iter()
                .flat_map(|c| {
                    let stride = if c.real { cut.real_stride } else { cut.stride };
                    augment::expand(&c.clip, c.real, &cut.augment)
                        .into_iter()
                        .flat_map(move |clip| echo_eval::window::windows(&clip, stride))
                })
                .collect();
            (it.weight, w)
        })
        .collect();
    if per.iter().all(|(w, _)| w.is_none()) {
        return per.into_iter().flat_map(|(_, w)| w).collect();
    }
    let total: usize = per.iter().map(|(_, w)| w.len()).sum();
    let weights: f64 = per
        .iter()
        .filter(|(_, w)| !w.is_empty())
        .map(|(x, _)| x.unwrap_or(1.0))
        .sum();
    let mut rng = rand::rngs::StdRng::seed_from_u64(cut.seed);
    let mut out = Vec::with_capacity(total);
    for (x, w) in &per {
        if w.is_empty() {
            continue;
        }
        let n = (total as f64 * x.unwrap_or(1.0) / weights).round() as usize;
        out.extend((0..n).map(|_| w[rng.random_range(0..w.len())].clone()));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_set_each_items_share() {
        use echo_motion::synth::generate_split;
        let caps = |split: Split| -> Vec<Capture> {
            generate_split(split, 0..6, 2, &|| {})
                .into_iter()
                .map(|clip| Capture {
                    name: clip.params.seed.to_string(),
                    source: "synthetic",
                    real: false,
                    clip,
                    report: None,
                })
                .collect()
        };
        let item = |w: f64| Item {
            source: Source::Synthetic {
                clips: None,
                family: Family::Standing,
            },
            weight: Some(w),
        };
        let per = vec![
            (item(3.0), caps(Split::Val)),
            (item(1.0), caps(Split::Test)),
        ];
        let cut = Cut {
            stride: 8,
            real_stride: 8,
            augment: augment::Augment::NONE,
            seed: 1,
        };
        let n: usize = per
            .iter()
            .map(|p| windows(std::slice::from_ref(p), &cut).len())
            .sum();
        let mixed = windows(&per, &cut);
        assert!(mixed.len().abs_diff(n) <= 1);
        let from0 = mixed
            .iter()
            .filter(|w| per[0].1.iter().any(|c| c.clip.params.seed == w.origin.0))
            .count();
        let share = from0 as f64 / mixed.len() as f64;
        assert!((share - 0.75).abs() < 0.02, "{share}");
        // Unweighted: every window once.
        let plain: Vec<(Item, Vec<Capture>)> = per
            .iter()
            .map(|(i, c)| {
                (
                    Item {
                        weight: None,
                        ..i.clone()
                    },
                    c.clone(),
                )
            })
            .collect();
        assert_eq!(windows(&plain, &cut).len(), n);
    }
}
