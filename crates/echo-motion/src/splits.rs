//! Whole dataset splits of the generator, made in parallel: its original clips, its walking
//! clips and its greeting clips (the parameters from [`Split`]'s clip, walking_clip and
//! greeting_clip), each clip choreographed by [`crate::synth::generate`].

use crate::params::{ClipParams, Split};
use crate::synth::{generate, Clip};

/// Generate clips `range` of a split on `threads` threads, calling `progress` after each clip.
pub fn generate_split(
    split: Split,
    range: std::ops::Range<u64>,
    threads: usize,
    progress: &(dyn Fn() + Sync),
) -> Vec<Clip> {
    generate_clips(range.map(|i| split.clip(i)).collect(), threads, progress)
}

/// Generate the clips of `ids` (any family: [`Split::clip`], [`Split::walking_clip`],
/// [`Split::greeting_clip`]) on `threads` threads, calling `progress` after each clip.
pub fn generate_clips(
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
