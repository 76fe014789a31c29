//! Speed and separation monitoring (ISO/TS 15066 style), with a collaborative contact mode for
//! the interaction partner.
//!
//! Protective separation distance (ISO/TS 15066 §5.5.4, now ISO 10218-2:2025):
//! `Sp = vh·(Tr + Ts) + vr·Tr + Ss + C + Zd + Zr` with vh = 1.6 m/s (2.0 m/s within 0.5 m),
//! Tr the loop's reaction time, Ts the robot's current stopping time (from the filter's braking
//! law), vr the fastest robot capsule end, Ss = vr·Ts/2 its stopping distance, C the intrusion
//! distance, Zd and Zr the position uncertainties. The speed scale is 1 beyond `Sp + slow_zone`,
//! 0 (stop) at `Sp`, linear in between. The distance is the smallest surface distance between
//! the robot's capsules and every tracked person's capsules, now and over the forecast.
//!
//! Contact mode (power and force limiting, ISO/TS 15066 §5.5.5): while the intent names a contact
//! interaction (handshake, high five, handover, hug, shoulder tap), the *partner* — not a
//! bystander — is governed by three rules instead of `Sp`:
//! - the intended regions (hands and forearms; upper arms and torso too for hug and shoulder
//!   tap) may touch any robot part;
//! - no robot part moves toward the partner's head inside `head_clearance_m`, nor toward the
//!   remaining regions inside `body_clearance_m` (protective stop); the partner may step closer
//!   to a robot part that holds still or moves away, down to half the clearance;
//! - within `contact_zone_m` of the partner the whole robot moves at most `contact_speed_mps`
//!   (fastest capsule end), a transient-contact speed.

use echo_msgs::Interaction;
use echo_robot::collision::{Capsule, Part};
use nalgebra::Vector3;

use crate::config::SeparationConfig;

pub use echo_motion::sensors::BodyPart as HumanPart;

/// Capsules of one person from SMPL-22 joints (the shared body model of `echo_motion::sensors`).
pub fn human_capsules(joints: &[[f64; 3]]) -> Vec<(HumanPart, Capsule)> {
    let p: Vec<Vector3<f64>> = joints.iter().map(|x| Vector3::from(*x)).collect();
    echo_motion::sensors::body_capsules(&p)
}

/// One tracked person (current skeleton or a forecast frame).
#[derive(Debug, Clone)]
pub struct Person {
    /// The interaction partner (contact mode may apply), or anybody else (always `Sp`).
    pub partner: bool,
    /// Body capsules.
    pub capsules: Vec<(HumanPart, Capsule)>,
}

/// Whether the robot may touch `part` of the partner during `interaction`.
fn contact_allowed(interaction: Option<Interaction>, part: HumanPart) -> bool {
    match interaction {
        Some(i) if i.is_contact() => match part {
            HumanPart::Hand(_) | HumanPart::Forearm(_) => true,
            HumanPart::UpperArm(_) | HumanPart::Torso => {
                matches!(i, Interaction::Hug | Interaction::ShoulderTap)
            }
            _ => false,
        },
        _ => false,
    }
}

/// The rule a (person, body part) pair is held to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Rule {
    /// Protective separation distance `Sp`.
    Separation,
    /// Contact allowed (at the contact speed).
    Contact,
    /// A fixed clearance, m (at the contact speed).
    Clearance(f64),
}

/// The rule for `part` of a person.
pub fn rule(
    cfg: &SeparationConfig,
    interaction: Option<Interaction>,
    partner: bool,
    part: HumanPart,
) -> Rule {
    if !partner || !interaction.is_some_and(|i| i.is_contact()) {
        Rule::Separation
    } else if part == HumanPart::Head {
        Rule::Clearance(cfg.head_clearance_m)
    } else if contact_allowed(interaction, part) {
        Rule::Contact
    } else {
        Rule::Clearance(cfg.body_clearance_m)
    }
}

/// The pair that comes closest to its required clearance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClearancePair {
    /// Surface distance, m.
    pub distance: f64,
    /// Inside the clearance, the robot's motion this cycle brings the pair closer.
    pub approaching: bool,
    /// Required clearance, m.
    pub required: f64,
    /// Robot part.
    pub robot: Part,
    /// Partner's body part.
    pub human: HumanPart,
}

impl ClearancePair {
    /// Inside the clearance with the robot moving closer, or inside half of it at all.
    pub fn violated(&self) -> bool {
        self.distance < self.required && (self.approaching || self.distance < self.required / 2.0)
    }
}

/// The outcome for one control cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Assessment {
    /// Smallest robot–human surface distance held to `Sp`, m.
    pub min_distance: f64,
    /// Protective separation distance, m.
    pub protective: f64,
    /// Speed scale for every group from `Sp`.
    pub scale: f64,
    /// The robot and human parts at `min_distance` (what holds the robot back).
    pub closest: Option<(Part, HumanPart)>,
    /// Contact mode: the pair with the least margin over its clearance.
    pub clearance: Option<ClearancePair>,
    /// Contact mode: smallest distance between the robot and the partner, m.
    pub partner_distance: f64,
    /// Contact-speed cap for every group, ≤ 1.
    pub contact_scale: f64,
}

impl Assessment {
    /// A protective stop is required: inside `Sp`, or a robot part moves into a clearance.
    pub fn stop(&self) -> bool {
        (self.scale == 0.0 && self.min_distance.is_finite())
            || self.clearance.is_some_and(|c| c.violated())
    }
}

/// Assess separation for robot capsules `robot` (and `robot_next`, the same capsules one cycle
/// ahead at the current velocity; fastest capsule-end speed `vr`, stopping time `ts`) against
/// `people` (current and forecast).
#[allow(clippy::too_many_arguments)]
pub fn assess(
    cfg: &SeparationConfig,
    robot: &[(Part, Capsule)],
    robot_next: &[(Part, Capsule)],
    people: &[Person],
    interaction: Option<Interaction>,
    vr: f64,
    ts: f64,
) -> Assessment {
    let mut d = f64::INFINITY;
    let mut closest = None;
    let mut clearance: Option<ClearancePair> = None;
    let mut d_partner = f64::INFINITY;
    for person in people {
        for (hp, hc) in &person.capsules {
            let r = rule(cfg, interaction, person.partner, *hp);
            for (k, (rp, rc)) in robot.iter().enumerate() {
                let dist = rc.distance(hc);
                match r {
                    Rule::Separation => {
                        if dist < d {
                            d = dist;
                            closest = Some((*rp, *hp));
                        }
                    }
                    Rule::Contact => d_partner = d_partner.min(dist),
                    Rule::Clearance(required) => {
                        d_partner = d_partner.min(dist);
                        // Only inside the clearance does the direction matter.
                        let approaching = dist < required
                            && robot_next
                                .get(k)
                                .is_some_and(|(_, next)| next.distance(hc) < dist);
                        let cand = ClearancePair {
                            distance: dist,
                            approaching,
                            required,
                            robot: *rp,
                            human: *hp,
                        };
                        // Violations first, then the smallest margin.
                        let key = |c: &ClearancePair| (!c.violated(), c.distance - c.required);
                        if clearance.is_none_or(|c| key(&cand) < key(&c)) {
                            clearance = Some(cand);
                        }
                    }
                }
            }
        }
    }
    let vh = if d < 0.5 {
        cfg.human_speed_close_mps
    } else {
        cfg.human_speed_mps
    };
    let tr = cfg.reaction_time_s;
    let ss = vr * ts / 2.0;
    let sp = vh * (tr + ts)
        + vr * tr
        + ss
        + cfg.intrusion_m
        + cfg.human_uncertainty_m
        + cfg.robot_uncertainty_m;
    let scale = if d.is_infinite() {
        1.0
    } else {
        ((d - sp) / cfg.slow_zone_m.max(1e-6)).clamp(0.0, 1.0)
    };
    let contact_scale = if d_partner < cfg.contact_zone_m && vr > cfg.contact_speed_mps {
        (cfg.contact_speed_mps / vr).clamp(0.0, 1.0)
    } else {
        1.0
    };
    Assessment {
        min_distance: d,
        protective: sp,
        scale,
        closest,
        clearance,
        partner_distance: d_partner,
        contact_scale,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn robot_at(x: f64) -> Vec<(Part, Capsule)> {
        vec![
            (
                Part::Torso,
                Capsule::sphere(Vector3::new(-1.0, 0.0, 1.0), 0.2),
            ),
            (
                Part::Forearm(false),
                Capsule::sphere(Vector3::new(x - 0.2, 0.0, 1.0), 0.05),
            ),
            (
                Part::Gripper(false),
                Capsule::sphere(Vector3::new(x, 0.0, 1.0), 0.05),
            ),
        ]
    }

    fn person_at(x: f64, partner: bool) -> Person {
        Person {
            partner,
            capsules: vec![
                (
                    HumanPart::Hand(false),
                    Capsule::sphere(Vector3::new(x, 0.0, 1.0), 0.05),
                ),
                (
                    HumanPart::Torso,
                    Capsule::sphere(Vector3::new(x + 0.35, 0.0, 1.1), 0.15),
                ),
                (
                    HumanPart::Head,
                    Capsule::sphere(Vector3::new(x + 0.35, 0.0, 1.6), 0.11),
                ),
            ],
        }
    }

    #[test]
    fn scale_falls_to_zero_at_the_protective_distance() {
        let cfg = SeparationConfig::default();
        let far = assess(
            &cfg,
            &robot_at(0.5),
            &robot_at(0.5),
            &[person_at(3.0, true)],
            None,
            0.0,
            0.0,
        );
        assert_eq!(far.scale, 1.0);
        let near = assess(
            &cfg,
            &robot_at(0.5),
            &robot_at(0.5),
            &[person_at(0.7, true)],
            None,
            0.0,
            0.0,
        );
        assert_eq!(near.scale, 0.0, "{near:?}");
        assert!(near.stop());
        assert_eq!(
            near.closest,
            Some((Part::Gripper(false), HumanPart::Hand(false)))
        );
        // Faster robots need more room.
        let people = [person_at(1.4, true)];
        let mid = assess(
            &cfg,
            &robot_at(0.5),
            &robot_at(0.5),
            &people,
            None,
            0.0,
            0.0,
        );
        let mid_fast = assess(
            &cfg,
            &robot_at(0.5),
            &robot_at(0.5),
            &people,
            None,
            1.0,
            0.5,
        );
        assert!(
            mid_fast.scale < mid.scale && mid.scale > 0.0,
            "{mid:?} {mid_fast:?}"
        );
    }

    #[test]
    fn the_partner_may_be_touched_slowly_in_a_contact_interaction() {
        let cfg = SeparationConfig::default();
        let hs = Some(Interaction::Handshake);
        // Gripper 5 cm from the partner's hand, forearm 0.1 m from it.
        let a = assess(
            &cfg,
            &robot_at(0.5),
            &robot_at(0.5),
            &[person_at(0.6, true)],
            hs,
            0.5,
            0.1,
        );
        assert!(!a.stop(), "{a:?}");
        assert_eq!(a.scale, 1.0);
        assert!((a.contact_scale - 0.5).abs() < 1e-9, "{a:?}");
        assert!(a.partner_distance < 0.06);
        // Slow enough already: no cap.
        let slow = assess(
            &cfg,
            &robot_at(0.5),
            &robot_at(0.5),
            &[person_at(0.6, true)],
            hs,
            0.2,
            0.1,
        );
        assert_eq!(slow.contact_scale, 1.0);
        // Without the contact intent the same scene stops the robot.
        assert!(assess(
            &cfg,
            &robot_at(0.5),
            &robot_at(0.5),
            &[person_at(0.6, true)],
            None,
            0.5,
            0.1
        )
        .stop());
        // A bystander at the same place is held to Sp even during a handshake.
        let b = assess(
            &cfg,
            &robot_at(0.5),
            &robot_at(0.5),
            &[person_at(0.6, false)],
            hs,
            0.5,
            0.1,
        );
        assert!(b.stop(), "{b:?}");
    }

    #[test]
    fn head_and_other_regions_keep_their_clearance() {
        let cfg = SeparationConfig::default();
        let hs = Some(Interaction::Handshake);
        // The gripper at the partner's torso (not an intended region in a handshake).
        let mut p = person_at(2.0, true);
        p.capsules[1].1 = Capsule::sphere(Vector3::new(0.5 + 0.05 + 0.15 + 0.05, 0.0, 1.0), 0.15);
        // Moving toward the torso inside its clearance: stop.
        let a = assess(
            &cfg,
            &robot_at(0.5),
            &robot_at(0.51),
            &[p.clone()],
            hs,
            0.1,
            0.1,
        );
        let c = a.clearance.expect("clearance pair");
        assert_eq!((c.robot, c.human), (Part::Gripper(false), HumanPart::Torso));
        assert!((c.distance - 0.05).abs() < 1e-9 && c.required == cfg.body_clearance_m);
        assert!(a.stop());
        // Moving away inside half the clearance (0.04 m): stop too.
        let mut inner = p.clone();
        inner.capsules[1].1.a.x -= 0.01;
        inner.capsules[1].1.b.x -= 0.01;
        let away = assess(
            &cfg,
            &robot_at(0.5),
            &robot_at(0.49),
            &[inner],
            hs,
            0.1,
            0.1,
        );
        assert!(away.stop());
        // At 0.08 m moving away: allowed; moving closer: stop.
        let mut q = p.clone();
        q.capsules[1].1.a.x += 0.03;
        q.capsules[1].1.b.x += 0.03;
        assert!(!assess(
            &cfg,
            &robot_at(0.5),
            &robot_at(0.49),
            &[q.clone()],
            hs,
            0.1,
            0.1
        )
        .stop());
        assert!(assess(&cfg, &robot_at(0.5), &robot_at(0.51), &[q], hs, 0.1, 0.1).stop());
        // For a hug the torso is an intended region.
        assert!(!assess(
            &cfg,
            &robot_at(0.5),
            &robot_at(0.5),
            &[p],
            Some(Interaction::Hug),
            0.1,
            0.1
        )
        .stop());
        // The head: never touched, whatever the interaction.
        let mut h = person_at(2.0, true);
        h.capsules[2].1 = Capsule::sphere(Vector3::new(0.5 + 0.05 + 0.2 + 0.11, 0.0, 1.0), 0.11);
        for i in [Interaction::Handshake, Interaction::Hug] {
            let a = assess(
                &cfg,
                &robot_at(0.5),
                &robot_at(0.51),
                &[h.clone()],
                Some(i),
                0.1,
                0.1,
            );
            assert!(a.stop(), "{i:?}: {a:?}");
            assert_eq!(a.clearance.map(|c| c.human), Some(HumanPart::Head));
        }
        assert_eq!(
            rule(&cfg, hs, true, HumanPart::Head),
            Rule::Clearance(cfg.head_clearance_m)
        );
        assert_eq!(
            rule(&cfg, None, true, HumanPart::Hand(true)),
            Rule::Separation
        );
    }
}
