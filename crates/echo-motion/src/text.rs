//! Natural-language descriptions of generated interactions, in the style of InterHuman
//! ("One person extends a handshake with their right hand, while the other reciprocates with
//! their own."): 2–3 per clip with varied wording.

use echo_msgs::Interaction;
use rand::seq::SliceRandom;
use rand::Rng;

use crate::params::ClipParams;

fn templates(kind: Interaction) -> &'static [&'static str] {
    match kind {
        Interaction::Handshake => &[
            "One person extends a handshake with their {hand} hand, while the other reciprocates with their own.",
            "Two people walk up to each other and shake {hand} hands.",
            "The first person offers a {hand}-handed handshake and the second person takes it.",
            "They greet each other with a firm handshake.",
        ],
        Interaction::Wave => &[
            "One person waves at the other with their {hand} hand, and the other waves back.",
            "A person raises their {hand} hand and waves; after a moment the other person waves in return.",
            "Two people greet each other from a distance by waving.",
        ],
        Interaction::HighFive => &[
            "The two people give each other a high five.",
            "One person raises their {hand} hand and the other slaps it in a high five.",
            "They celebrate with a quick high five.",
        ],
        Interaction::Handover => &[
            "One person hands an object to the other, who reaches out and takes it.",
            "A person holds something out with their {hand} hand and the other person receives it.",
            "The first person passes an item over, and the second person grabs it and pulls it in.",
        ],
        Interaction::Hug => &[
            "Two people walk toward each other and embrace in a hug.",
            "They wrap their arms around each other in a warm hug, then let go.",
            "One person hugs the other, who hugs them back.",
        ],
        Interaction::Bow => &[
            "One person bows to the other, and the other bows back.",
            "A person bends forward in a polite bow; the other person returns the bow.",
            "The two people greet each other with a bow.",
        ],
        Interaction::PointAndLook => &[
            "One person points to something with their {hand} hand, and the other turns to look at it.",
            "A person points into the distance; the other person follows the gesture with their eyes.",
            "The first person shows the second person where to look by pointing.",
        ],
        Interaction::ApproachGreet => &[
            "One person walks up to the other and greets them with a wave.",
            "A person approaches the other, stops in front of them and says hello with a raised hand.",
            "Someone comes closer and greets the person waiting, who greets them back.",
        ],
        Interaction::ShoulderTap => &[
            "One person walks up behind the other and taps them on the shoulder, and the other turns around.",
            "A person gets the other's attention with a tap on the shoulder; the other person turns to face them.",
            "The first person approaches from behind and taps the second person, who turns around.",
        ],
        Interaction::Imitation => &[
            "One person moves their arms around and the other copies the movements like a mirror.",
            "The two people play a mirror game: the second person imitates the first person's arm motions.",
            "A person makes gestures with both arms while the other mimics them a moment later.",
        ],
        Interaction::Clap => &[
            "The two people clap their hands together in rhythm.",
            "One person starts clapping and the other joins in.",
            "They face each other and clap along at the same pace.",
        ],
        Interaction::WalkPast => &[
            "Two people walk past each other, stepping aside to keep their distance.",
            "The two people approach from opposite directions and pass each other.",
            "They walk toward each other, glance at one another and pass by.",
        ],
        Interaction::Idle => &[
            "Two people stand facing each other.",
            "The two people stand still, looking at each other.",
            "Two people wait in front of each other without doing much.",
        ],
    }
}

/// 2–3 distinct descriptions of the clip.
pub fn describe(p: &ClipParams, rng: &mut impl Rng) -> Vec<String> {
    let hand = if p.right_handed { "right" } else { "left" };
    let mut t: Vec<&str> = templates(p.kind).to_vec();
    t.shuffle(rng);
    let n = rng.random_range(2..=3).min(t.len());
    t[..n].iter().map(|s| s.replace("{hand}", hand)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn two_or_three_distinct_descriptions_with_the_hand() {
        for kind in crate::params::KINDS {
            for seed in 0..5 {
                let mut p = ClipParams::sample(kind, &crate::params::ParamRanges::train(), seed);
                p.right_handed = false;
                let d = describe(&p, &mut rand::rngs::StdRng::seed_from_u64(seed));
                assert!((2..=3).contains(&d.len()));
                assert!(d
                    .iter()
                    .all(|s| !s.contains("{hand}") && !s.contains("right hand")));
                let mut u = d.clone();
                u.dedup();
                assert_eq!(u.len(), d.len());
            }
        }
    }
}
