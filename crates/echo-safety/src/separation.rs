//! Speed and separation monitoring, ISO/TS 15066 style.
//!
//! Protective separation distance (ISO/TS 15066 §5.5.4, now ISO 10218-2:2025):
//! `Sp = vh·(Tr + Ts) + vr·Tr + Ss + C + Zd + Zr` with vh = 1.6 m/s (2.0 m/s within 0.5 m),
//! Tr the loop's reaction time, Ts the robot's current stopping time (from the filter's braking
//! law), vr the fastest robot capsule end, Ss = vr·Ts/2 its stopping distance, C the intrusion
//! distance, Zd and Zr the position uncertainties. The speed scale is 1 beyond `Sp + slow_zone`,
//! 0 (stop) at `Sp`, linear in between. The distance is the smallest surface distance between
//! the robot's capsules and every tracked person's capsules, now and over the forecast.
//!
//! Contact interactions (handshake, high five, handover, hug, shoulder tap) let the robot's
//! end effectors (wrist, gripper) approach the person's hands and arms (and torso for hug and
//! shoulder tap) — never the head — at no more than `contact_speed` within `contact_zone`.

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

/// Whether the end effectors may approach `part` during `interaction`.
pub fn contact_allowed(interaction: Option<Interaction>, part: HumanPart) -> bool {
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

/// The outcome for one control cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Assessment {
    /// Smallest robot–human surface distance that counts for separation, m.
    pub min_distance: f64,
    /// Protective separation distance, m.
    pub protective: f64,
    /// Speed scale for every group.
    pub scale: f64,
    /// Extra scale for the arms (end-effector contact speed cap), ≤ 1.
    pub arm_scale: f64,
    /// Smallest end-effector distance to an allowed contact part, m.
    pub contact_distance: f64,
}

/// Assess separation for robot capsules `robot` (with the fastest capsule-end speed `vr` and
/// stopping time `ts`) against `people` (each a list of capsules, current and forecast).
pub fn assess(
    cfg: &SeparationConfig,
    robot: &[(Part, Capsule)],
    people: &[Vec<(HumanPart, Capsule)>],
    interaction: Option<Interaction>,
    vr: f64,
    v_ee: f64,
    ts: f64,
) -> Assessment {
    let mut d = f64::INFINITY;
    let mut d_contact = f64::INFINITY;
    for person in people {
        for (hp, hc) in person {
            for (rp, rc) in robot {
                let dist = rc.distance(hc);
                if rp.is_end_effector() && contact_allowed(interaction, *hp) {
                    d_contact = d_contact.min(dist);
                } else {
                    d = d.min(dist);
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
    let arm_scale = if d_contact < cfg.contact_zone_m && v_ee > cfg.contact_speed_mps {
        (cfg.contact_speed_mps / v_ee).clamp(0.0, 1.0)
    } else {
        1.0
    };
    Assessment {
        min_distance: d,
        protective: sp,
        scale,
        arm_scale,
        contact_distance: d_contact,
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
                Part::Gripper(false),
                Capsule::sphere(Vector3::new(x, 0.0, 1.0), 0.05),
            ),
        ]
    }

    fn hand_at(x: f64) -> Vec<(HumanPart, Capsule)> {
        vec![
            (
                HumanPart::Hand(false),
                Capsule::sphere(Vector3::new(x, 0.0, 1.0), 0.05),
            ),
            (
                HumanPart::Head,
                Capsule::sphere(Vector3::new(x + 0.5, 0.0, 1.6), 0.11),
            ),
        ]
    }

    #[test]
    fn scale_falls_to_zero_at_the_protective_distance() {
        let cfg = SeparationConfig::default();
        let far = assess(&cfg, &robot_at(0.5), &[hand_at(3.0)], None, 0.0, 0.0, 0.0);
        assert_eq!(far.scale, 1.0);
        let near = assess(&cfg, &robot_at(0.5), &[hand_at(0.7)], None, 0.0, 0.0, 0.0);
        assert_eq!(near.scale, 0.0, "{near:?}");
        // Faster robots need more room.
        let mid = assess(&cfg, &robot_at(0.5), &[hand_at(1.4)], None, 0.0, 0.0, 0.0);
        let mid_fast = assess(&cfg, &robot_at(0.5), &[hand_at(1.4)], None, 1.0, 1.0, 0.5);
        assert!(
            mid_fast.scale < mid.scale && mid.scale > 0.0,
            "{mid:?} {mid_fast:?}"
        );
    }

    #[test]
    fn contact_lets_only_the_end_effector_near_the_hand_slowly() {
        let cfg = SeparationConfig::default();
        let hs = Some(Interaction::Handshake);
        let a = assess(&cfg, &robot_at(0.5), &[hand_at(0.65)], hs, 0.2, 0.5, 0.1);
        // The gripper near the hand no longer stops the robot, but the arm is capped.
        assert!(a.contact_distance < 0.1);
        assert!(a.scale > 0.0, "{a:?}");
        assert!((a.arm_scale - 0.5).abs() < 1e-9);
        // Without the contact intent the same scene stops the robot.
        assert_eq!(
            assess(&cfg, &robot_at(0.5), &[hand_at(0.65)], None, 0.5, 0.5, 0.2).scale,
            0.0
        );
        // The head is never a contact part.
        assert!(!contact_allowed(hs, HumanPart::Head));
    }
}
