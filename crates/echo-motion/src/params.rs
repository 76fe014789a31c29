//! What a generated clip is drawn from: the interaction types, the parameter ranges, one clip's
//! parameters, and the dataset splits (disjoint seed ranges; the held-out split also draws from
//! held-out ranges). The choreography that turns parameters into motion is `synth`.

use std::f64::consts::PI;

use echo_msgs::Interaction;
use rand::{Rng, SeedableRng};

/// Every generated interaction type (the 12 social ones plus idle).
pub const KINDS: [Interaction; 13] = [
    Interaction::Handshake,
    Interaction::Wave,
    Interaction::HighFive,
    Interaction::Handover,
    Interaction::Hug,
    Interaction::Bow,
    Interaction::PointAndLook,
    Interaction::ApproachGreet,
    Interaction::ShoulderTap,
    Interaction::Imitation,
    Interaction::Clap,
    Interaction::WalkPast,
    Interaction::Idle,
];

/// The interaction types of the walking clips: those performed on the way to, or past, the
/// other person.
pub const WALKING_KINDS: [Interaction; 6] = [
    Interaction::Handshake,
    Interaction::HighFive,
    Interaction::Handover,
    Interaction::Hug,
    Interaction::ApproachGreet,
    Interaction::WalkPast,
];

/// The interaction types of the greeting clips ([`Split::greeting_clip`]): exchanges of hands
/// made on the way, briefly.
pub const GREETING_KINDS: [Interaction; 3] = [
    Interaction::Handshake,
    Interaction::HighFive,
    Interaction::Handover,
];

/// Ranges the clip parameters are drawn from.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamRanges {
    /// Body heights, metres (a union of intervals).
    pub height: Vec<(f64, f64)>,
    /// Reaction delays, seconds.
    pub delay: Vec<(f64, f64)>,
    /// Start distance between the pelvises, metres.
    pub distance: (f64, f64),
    /// Walking speed, m/s.
    pub speed: (f64, f64),
    /// Motion amplitude factor.
    pub amplitude: (f64, f64),
}

impl ParamRanges {
    /// The training (and validation, test) ranges.
    pub fn train() -> Self {
        ParamRanges {
            height: vec![(1.55, 1.90)],
            delay: vec![(0.25, 0.8)],
            distance: (1.2, 2.6),
            speed: (0.7, 1.3),
            amplitude: (0.8, 1.2),
        }
    }

    /// The walking ranges: people start 2.4–5 m apart and walk at 0.6–1.5 m/s (real people walk
    /// at a median 0.5–0.8 m/s, docs/RESULTS.md).
    pub fn walking() -> Self {
        ParamRanges {
            distance: (2.4, 5.0),
            speed: (0.6, 1.5),
            ..Self::train()
        }
    }

    /// The held-out ranges: heights and reaction delays outside the training ranges.
    pub fn held_out() -> Self {
        ParamRanges {
            height: vec![(1.48, 1.55), (1.90, 1.97)],
            delay: vec![(0.8, 1.2)],
            ..Self::train()
        }
    }
}

fn draw(rng: &mut impl Rng, ranges: &[(f64, f64)]) -> f64 {
    let total: f64 = ranges.iter().map(|(a, b)| b - a).sum();
    let mut x = rng.random_range(0.0..total.max(1e-9));
    for (a, b) in ranges {
        if x <= b - a {
            return a + x;
        }
        x -= b - a;
    }
    ranges.last().map_or(0.0, |r| r.1)
}

/// Parameters of one clip.
#[derive(Debug, Clone, PartialEq)]
pub struct ClipParams {
    /// Interaction.
    pub kind: Interaction,
    /// Seed (also of the noise).
    pub seed: u64,
    /// Heights of A and B.
    pub heights: [f64; 2],
    /// Start distance, metres.
    pub distance: f64,
    /// B's reaction delay, seconds.
    pub delay: f64,
    /// Walking speed, m/s.
    pub speed: f64,
    /// Right hand (true) or left.
    pub right_handed: bool,
    /// Amplitude factor.
    pub amplitude: f64,
    /// Scene placement: position and rotation.
    pub placement: (f64, f64, f64),
    /// Walk the way people walk ([`Split::walking_clip`]): approaches from further away at the
    /// drawn speed, with smooth starts and stops (raised-cosine speed ramps, peak acceleration
    /// 0.8–1.3 m/s²), gait and arm swing scaled with speed; handshakes, high fives and
    /// handovers stop up to 0.3 m further apart and, in 60 % of clips, end with both stepping
    /// back 0.2–0.6 m. `false`: the original choreography (short approaches; every existing
    /// split).
    pub locomotion: bool,
    /// With `locomotion`, a brief exchange ([`Split::greeting_clip`]): the hands rise while
    /// walking and meet on arrival, are held 0.1–0.8 s, and both step back at once to
    /// 1.1–1.8 m apart (the way the real walk-up handshake of CMU 18_01 + 19_01 goes:
    /// 0.3 s, then 1.2–1.7 m). `false`: the exchange is held about 2 s.
    pub brief: bool,
}

impl ClipParams {
    /// Draw parameters for `kind` from `ranges` with `seed`.
    pub fn sample(kind: Interaction, ranges: &ParamRanges, seed: u64) -> ClipParams {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        ClipParams {
            kind,
            seed,
            heights: [
                draw(&mut rng, &ranges.height),
                draw(&mut rng, &ranges.height),
            ],
            distance: rng.random_range(ranges.distance.0..ranges.distance.1),
            delay: draw(&mut rng, &ranges.delay),
            speed: rng.random_range(ranges.speed.0..ranges.speed.1),
            right_handed: rng.random::<f64>() < 0.85,
            amplitude: rng.random_range(ranges.amplitude.0..ranges.amplitude.1),
            placement: (
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-PI..PI),
            ),
            locomotion: false,
            brief: false,
        }
    }
}

/// Dataset splits: disjoint seed ranges; the held-out split also draws from the held-out ranges.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Split {
    /// Training.
    Train,
    /// Validation.
    Val,
    /// Test.
    Test,
    /// Out-of-range generalisation test.
    HeldOut,
}

impl Split {
    /// First seed of the split.
    pub fn seed_base(self) -> u64 {
        match self {
            Split::Train => 0,
            Split::Val => 1_000_000_000,
            Split::Test => 2_000_000_000,
            Split::HeldOut => 3_000_000_000,
        }
    }

    /// Parameter ranges of the split.
    pub fn ranges(self) -> ParamRanges {
        match self {
            Split::HeldOut => ParamRanges::held_out(),
            _ => ParamRanges::train(),
        }
    }

    /// Parse "train", "val", "test", "held-out".
    pub fn parse(s: &str) -> Option<Split> {
        match s {
            "train" => Some(Split::Train),
            "val" => Some(Split::Val),
            "test" => Some(Split::Test),
            "held-out" | "heldout" => Some(Split::HeldOut),
            _ => None,
        }
    }

    /// Parameters of clip `i` of the split (types cycle through [`KINDS`]).
    pub fn clip(self, i: u64) -> ClipParams {
        let kind = KINDS[(i % KINDS.len() as u64) as usize];
        ClipParams::sample(kind, &self.ranges(), self.seed_base() + i)
    }
}

impl Split {
    /// The `i`-th walking clip of the split ([`WALKING_KINDS`] in turn, walking ranges, seeds
    /// 500 000 000 after the split's own).
    pub fn walking_clip(self, i: u64) -> ClipParams {
        let kind = WALKING_KINDS[(i % WALKING_KINDS.len() as u64) as usize];
        let mut p = ClipParams::sample(
            kind,
            &self.walking_ranges(),
            self.seed_base() + 500_000_000 + i,
        );
        p.locomotion = true;
        p
    }

    /// The `i`-th greeting clip of the split: a walking clip of [`GREETING_KINDS`] (in turn)
    /// whose exchange is brief ([`ClipParams::brief`]); seeds 700 000 000 after the split's own.
    pub fn greeting_clip(self, i: u64) -> ClipParams {
        let kind = GREETING_KINDS[(i % GREETING_KINDS.len() as u64) as usize];
        let mut p = ClipParams::sample(
            kind,
            &self.walking_ranges(),
            self.seed_base() + 700_000_000 + i,
        );
        p.locomotion = true;
        p.brief = true;
        p
    }

    fn walking_ranges(self) -> ParamRanges {
        match self {
            Split::HeldOut => ParamRanges {
                distance: (2.4, 5.0),
                speed: (0.6, 1.5),
                ..ParamRanges::held_out()
            },
            _ => ParamRanges::walking(),
        }
    }
}
