//! Whole dataset splits of the generator, made in parallel: its original clips, its walking
//! clips and its greeting clips ([`Split`]'s clip, walking_clip and greeting_clip), each clip
//! choreographed by [`crate::synth::generate`].

use crate::params::{ClipParams, Split};
use crate::synth::{generate, Clip};

/// Generate walking clips `range` of a split ([`Split::walking_clip`]).
pub fn generate_walking_split(
    split: Split,
    range: std::ops::Range<u64>,
    threads: usize,
    progress: &(dyn Fn() + Sync),
) -> Vec<Clip> {
    generate_params(
        range.map(|i| split.walking_clip(i)).collect(),
        threads,
        progress,
    )
}

/// Generate greeting clips `range` of a split ([`Split::greeting_clip`]).
pub fn generate_greeting_split(
    split: Split,
    range: std::ops::Range<u64>,
    threads: usize,
    progress: &(dyn Fn() + Sync),
) -> Vec<Clip> {
    generate_params(
        range.map(|i| split.greeting_clip(i)).collect(),
        threads,
        progress,
    )
}

/// Generate clips `range` of a split on `threads` threads, calling `progress` after each clip.
pub fn generate_split(
    split: Split,
    range: std::ops::Range<u64>,
    threads: usize,
    progress: &(dyn Fn() + Sync),
) -> Vec<Clip> {
    generate_params(range.map(|i| split.clip(i)).collect(), threads, progress)
}

fn generate_params(
    ids: Vec<ClipParams>,
    threads: usize,
    progress: &(dyn Fn() + Sync),
) -> Vec<Clip> {
    let threads = threads.max(1);
    let chunk = ids.len().div_ceil(threads).max(1);
    let mut out: Vec<Vec<Clip>> = vec![];
    std::thread::scope(|s| {
        let handles: Vec<_> = ids
            .chunks(chunk)
            .map(|c| {
                s.spawn(move || {
                    c.iter()
                        .map(|params| {
                            let clip = generate(params);
                            progress();
                            clip
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        for h in handles {
            out.push(h.join().unwrap_or_default());
        }
    });
    out.into_iter().flatten().collect()
}
