//! What the robot did in each interaction of a run — did it wave back, did it reach the hand —
//! measured from time series of the partner's skeleton and the robot's grippers (both in the
//! robot's base frame, z up, the partner in front along +x).
//!
//! Rules (the numbers the demo's summary and the system tests report):
//! - **Wave.** A hand is *raised* while it is above its shoulder. While raised, its lateral
//!   coordinate (y, across the robot's view) is followed: a reversal of direction after an
//!   excursion of at least [`WAVE_HYSTERESIS_M`] is one half-oscillation. Oscillations =
//!   reversals / 2; amplitude = median peak-to-peak excursion between reversals; onset = first
//!   time the hand is raised. A recognisable wave: raised, ≥ 2 oscillations.
//! - **Contact.** From the smallest gripper–hand surface distance at each sample: the closest
//!   distance; contact made when the surfaces touch (`S_0`: ≤ 0) and stay within
//!   [`CONTACT_NEAR_M`] for at least [`CONTACT_HOLD_S`]; time to contact from the segment's
//!   start to the first touch.
//! - **Safety.** Time spent limiting and stopping, and the number of protective stops (entries
//!   into the stopping state), from the safety service's state at each sample.

use echo_motion::skeleton::j;
use echo_msgs::{Interaction, SafetyState};
use serde::{Deserialize, Serialize};

/// Smallest lateral excursion that counts as a half-oscillation of a wave, m.
pub const WAVE_HYSTERESIS_M: f64 = 0.03;
/// Contact holds while the surfaces stay this close, m.
pub const CONTACT_NEAR_M: f64 = 0.01;
/// Contact must hold this long to count, s.
pub const CONTACT_HOLD_S: f64 = 0.5;

/// One instant of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Time, s (the mission's clock).
    pub t: f64,
    /// The partner's SMPL-22 joints (empty: not seen).
    pub partner: Vec<[f64; 3]>,
    /// The robot's grasping frames (left, right).
    pub grippers: [[f64; 3]; 2],
    /// The robot's shoulders (arm joint 1 frames; left, right).
    pub shoulders: [[f64; 3]; 2],
    /// Smallest gripper–hand surface distance, m (infinite: partner not seen).
    pub surface_m: f64,
    /// The safety service's state (`None`: not reported yet).
    pub safety: Option<SafetyState>,
}

/// A wave, measured on one hand.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Wave {
    /// Time raised, s.
    pub raised_s: f64,
    /// Full oscillations while raised.
    pub oscillations: f64,
    /// Median peak-to-peak lateral excursion, m.
    pub amplitude_m: f64,
    /// First time raised (absolute), s.
    pub onset_s: Option<f64>,
}

impl Wave {
    /// Raised and at least two oscillations.
    pub fn recognisable(&self) -> bool {
        self.raised_s > 0.0 && self.oscillations >= 2.0
    }
}

/// The wave of a hand over time: `(t, hand, shoulder)` samples.
pub fn wave(samples: &[(f64, [f64; 3], [f64; 3])]) -> Wave {
    let mut w = Wave::default();
    let mut reversals = 0usize;
    let mut excursions = vec![];
    // Per raised stretch: the starting lateral position, the confirmed extremes, the direction
    // of travel (0: not yet moved by the hysteresis) and the running extreme.
    let mut stretch: Option<(f64, Vec<f64>, i8, f64)> = None;
    let mut prev_t: Option<f64> = None;
    let mut close = |st: Option<(f64, Vec<f64>, i8, f64)>, excursions: &mut Vec<f64>| {
        if let Some((anchor, ext, _, _)) = st {
            reversals += ext.len();
            let mut last = anchor;
            for (k, e) in ext.iter().enumerate() {
                // The first excursion starts where the hand was raised, not at an extreme:
                // counted only when it is the only one.
                if k > 0 || ext.len() == 1 {
                    excursions.push((e - last).abs());
                }
                last = *e;
            }
        }
    };
    for &(t, hand, shoulder) in samples {
        let finite = hand.iter().chain(&shoulder).all(|x| x.is_finite());
        if !(finite && hand[2] > shoulder[2]) {
            close(stretch.take(), &mut excursions);
            prev_t = None;
            continue;
        }
        w.onset_s.get_or_insert(t);
        if let Some(p) = prev_t {
            w.raised_s += (t - p).clamp(0.0, 0.5);
        }
        prev_t = Some(t);
        let y = hand[1];
        let (anchor, ext, dir, run) = stretch.get_or_insert((y, vec![], 0, y));
        match *dir {
            0 if (y - *anchor).abs() >= WAVE_HYSTERESIS_M => {
                *dir = if y > *anchor { 1 } else { -1 };
                *run = y;
            }
            0 => {}
            1 if y > *run => *run = y,
            -1 if y < *run => *run = y,
            d if (y - *run).abs() >= WAVE_HYSTERESIS_M => {
                ext.push(*run);
                *dir = -d;
                *run = y;
            }
            _ => {}
        }
    }
    close(stretch.take(), &mut excursions);
    w.oscillations = reversals as f64 / 2.0;
    if !excursions.is_empty() {
        excursions.sort_by(f64::total_cmp);
        w.amplitude_m = excursions[excursions.len() / 2];
    }
    w
}

/// Reaching the partner's hand.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Contact {
    /// Closest gripper–hand surface distance, m.
    pub closest_surface_m: f64,
    /// Longest time the surfaces stayed within [`CONTACT_NEAR_M`], s.
    pub held_s: f64,
    /// The surfaces touched (`S_0`) and stayed close for [`CONTACT_HOLD_S`].
    pub made: bool,
    /// From the segment's start to the first touch, s.
    pub time_to_contact_s: Option<f64>,
}

/// Contact over `(t, surface_m)` samples of a segment starting at `start_s`.
pub fn contact(samples: &[(f64, f64)], start_s: f64) -> Contact {
    let mut c = Contact {
        closest_surface_m: f64::INFINITY,
        held_s: 0.0,
        made: false,
        time_to_contact_s: None,
    };
    let mut run_start: Option<f64> = None;
    let mut touched_in_run = false;
    let mut touched_best = false;
    for &(t, d) in samples {
        if !d.is_finite() {
            run_start = None;
            continue;
        }
        c.closest_surface_m = c.closest_surface_m.min(d);
        if d <= echo_motion::sensors::CONTACT_MARGIN && c.time_to_contact_s.is_none() {
            c.time_to_contact_s = Some(t - start_s);
        }
        if d <= CONTACT_NEAR_M {
            let s = *run_start.get_or_insert(t);
            if run_start == Some(t) {
                touched_in_run = false;
            }
            touched_in_run |= d <= echo_motion::sensors::CONTACT_MARGIN;
            if t - s > c.held_s || (t - s == c.held_s && touched_in_run) {
                c.held_s = t - s;
                touched_best = touched_in_run;
            }
        } else {
            run_start = None;
        }
    }
    c.made = touched_best && c.held_s >= CONTACT_HOLD_S;
    c
}

/// Safety over a segment.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct SafetySummary {
    /// Time limiting, s.
    pub limiting_s: f64,
    /// Time stopping, s.
    pub stopping_s: f64,
    /// Time holding (or e-stopped), s.
    pub holding_s: f64,
    /// Protective stops (entries into stopping).
    pub stops: u32,
}

/// What the robot did in one interaction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InteractionReport {
    /// The interaction.
    pub interaction: Interaction,
    /// Its description.
    pub text: String,
    /// Start and end, s.
    pub start_s: f64,
    /// End, s.
    pub end_s: f64,
    /// Waves: the partner's hand and the robot's (the hand that waved more, each).
    pub partner_wave: Option<Wave>,
    /// The robot's wave.
    pub robot_wave: Option<Wave>,
    /// Contact interactions: the robot's reach of the partner's hand.
    pub contact: Option<Contact>,
    /// Safety during the interaction.
    pub safety: SafetySummary,
}

/// Score one interaction (`interaction`, `text`, from `start_s` to `end_s`) over a run's samples.
pub fn report(
    interaction: Interaction,
    text: &str,
    start_s: f64,
    end_s: f64,
    samples: &[Sample],
) -> InteractionReport {
    let seg: Vec<&Sample> = samples
        .iter()
        .filter(|s| s.t >= start_s && s.t <= end_s)
        .collect();
    let best = |waves: Vec<Wave>| {
        waves.into_iter().max_by(|a, b| {
            (a.oscillations, a.amplitude_m)
                .partial_cmp(&(b.oscillations, b.amplitude_m))
                .unwrap_or(std::cmp::Ordering::Equal)
        })
    };
    let is_wave = interaction == Interaction::Wave;
    let partner_wave = is_wave.then(|| {
        best(
            [(j::L_WRIST, j::L_SHOULDER), (j::R_WRIST, j::R_SHOULDER)]
                .into_iter()
                .map(|(w, sh)| {
                    wave(
                        &seg.iter()
                            .filter(|s| s.partner.len() > w.max(sh))
                            .map(|s| (s.t, s.partner[w], s.partner[sh]))
                            .collect::<Vec<_>>(),
                    )
                })
                .collect(),
        )
        .unwrap_or_default()
    });
    let robot_wave = is_wave.then(|| {
        best(
            (0..2)
                .map(|a| {
                    wave(
                        &seg.iter()
                            .map(|s| (s.t, s.grippers[a], s.shoulders[a]))
                            .collect::<Vec<_>>(),
                    )
                })
                .collect(),
        )
        .unwrap_or_default()
    });
    let contact_kind = matches!(
        interaction,
        Interaction::Handshake | Interaction::Handover | Interaction::HighFive
    );
    let contact = contact_kind.then(|| {
        contact(
            &seg.iter().map(|s| (s.t, s.surface_m)).collect::<Vec<_>>(),
            start_s,
        )
    });
    let mut safety = SafetySummary::default();
    for w in seg.windows(2) {
        let dt = (w[1].t - w[0].t).clamp(0.0, 0.5);
        match w[0].safety {
            Some(SafetyState::Limiting) => safety.limiting_s += dt,
            Some(SafetyState::Stopping) => safety.stopping_s += dt,
            Some(SafetyState::Holding | SafetyState::EStopped) => safety.holding_s += dt,
            _ => {}
        }
        let stopping = |s: Option<SafetyState>| s == Some(SafetyState::Stopping);
        if stopping(w[1].safety) && !stopping(w[0].safety) {
            safety.stops += 1;
        }
    }
    InteractionReport {
        interaction,
        text: text.to_string(),
        start_s,
        end_s,
        partner_wave,
        robot_wave,
        contact,
        safety,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn waving(amp: f64, hz: f64, raised: bool) -> Vec<(f64, [f64; 3], [f64; 3])> {
        (0..60)
            .map(|k| {
                let t = k as f64 / 15.0;
                let y = amp / 2.0 * (2.0 * std::f64::consts::PI * hz * t).sin();
                let z = if raised { 1.6 } else { 1.0 };
                (t, [0.5, y, z], [0.5, 0.0, 1.4])
            })
            .collect()
    }

    #[test]
    fn a_raised_oscillating_hand_is_a_wave_and_a_still_or_low_one_is_not() {
        // 4 s at 1.5 Hz: 6 oscillations of 0.2 m peak to peak.
        let w = wave(&waving(0.2, 1.5, true));
        assert!(w.recognisable(), "{w:?}");
        assert!((w.oscillations - 5.5).abs() <= 0.5, "{w:?}");
        assert!((w.amplitude_m - 0.2).abs() < 0.03, "{w:?}");
        assert_eq!(w.onset_s, Some(0.0));
        // Below the shoulder: not raised, no wave.
        let low = wave(&waving(0.2, 1.5, false));
        assert_eq!(low.raised_s, 0.0);
        assert!(!low.recognisable());
        // Raised but trembling below the hysteresis: no oscillation.
        let still = wave(&waving(0.02, 1.5, true));
        assert_eq!(still.oscillations, 0.0);
        assert!(!still.recognisable());
    }

    #[test]
    fn contact_needs_a_touch_held_for_half_a_second() {
        let series = |touch_s: f64| -> Vec<(f64, f64)> {
            (0..45)
                .map(|k| {
                    let t = k as f64 / 15.0;
                    let d = if (1.0..1.0 + touch_s).contains(&t) {
                        -0.01
                    } else {
                        0.05
                    };
                    (t, d)
                })
                .collect()
        };
        let held = contact(&series(0.8), 0.0);
        assert!(held.made, "{held:?}");
        assert!((held.time_to_contact_s.unwrap() - 1.0).abs() < 0.07);
        assert!(held.held_s >= 0.5);
        let brief = contact(&series(0.2), 0.0);
        assert!(!brief.made && brief.closest_surface_m < 0.0, "{brief:?}");
        let never = contact(&[(0.0, 0.3), (1.0, f64::INFINITY), (2.0, 0.02)], 0.0);
        assert!(!never.made && never.time_to_contact_s.is_none());
        assert_eq!(never.closest_surface_m, 0.02);
    }

    #[test]
    fn reports_count_safety_time_and_stops() {
        let s = |t: f64, safety| Sample {
            t,
            partner: vec![],
            grippers: [[0.0; 3]; 2],
            shoulders: [[0.0; 3]; 2],
            surface_m: 0.1,
            safety: Some(safety),
        };
        use SafetyState::*;
        let samples = vec![
            s(0.0, Following),
            s(0.5, Stopping),
            s(1.0, Limiting),
            s(1.5, Stopping),
            s(2.0, Following),
            s(9.0, Stopping),
        ];
        let r = report(Interaction::Handshake, "x", 0.0, 2.0, &samples);
        assert_eq!(r.safety.stops, 2);
        assert!((r.safety.stopping_s - 1.0).abs() < 1e-9);
        assert!((r.safety.limiting_s - 0.5).abs() < 1e-9);
        assert!(r.contact.is_some() && r.robot_wave.is_none());
    }
}
