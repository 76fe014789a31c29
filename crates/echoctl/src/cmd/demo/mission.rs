//! The demo's account of what the robot did: samples of the partner, the robot's grippers and
//! the safety state at every skeleton frame, scored per interaction of the mission
//! (`echo_eval::behaviour`).

use echo_eval::behaviour::{self, InteractionReport, Sample};
use echo_eval::live::joints_of;
use echo_msgs::{HumanSkeletons, JointState, SafetyState, SafetyStatus};
use echo_robot::collision::RobotBody;
use echo_robot::{JointValues, RobotModel};
use echo_sim::mission::Mission;
use nalgebra::{Isometry3, Vector3};

use echo_robot::GRASPING_FRAMES as GRASP;
use echo_robot::SHOULDER_LINKS as SHOULDER;

/// Collects samples while the mission plays.
pub struct MissionObserver {
    /// The mission the partner performs.
    pub mission: Mission,
    /// Mission time 0, ns since the UNIX epoch (the mock estimator's script start).
    pub t0_ns: u64,
    model: RobotModel,
    body: Option<RobotBody>,
    q: Option<JointValues>,
    safety: Option<SafetyState>,
    samples: Vec<Sample>,
}

impl MissionObserver {
    /// Observe `mission` started at `t0_ns`.
    pub fn new(mission: Mission, t0_ns: u64) -> MissionObserver {
        let model = RobotModel::tiago_dual();
        MissionObserver {
            body: RobotBody::tiago(&model).ok(),
            model,
            mission,
            t0_ns,
            q: None,
            safety: None,
            samples: vec![],
        }
    }

    /// Run time (not wrapped) of a stamp, s.
    fn time_of(&self, stamp_ns: u64) -> f64 {
        (stamp_ns as f64 - self.t0_ns as f64) / 1e9
    }

    /// A `robot/state` message.
    pub fn on_state(&mut self, js: &JointState) {
        let m = &self.model;
        self.q = m
            .values_from(
                js.name
                    .iter()
                    .zip(&js.position)
                    .filter(|(n, p)| m.joint_index(n).is_some() && p.is_finite())
                    .map(|(n, p)| (n.as_str(), *p)),
            )
            .ok();
    }

    /// A `safety/status` message.
    pub fn on_safety(&mut self, st: &SafetyStatus) {
        self.safety = Some(st.state);
    }

    /// A `humans` message: one sample at its capture stamp.
    pub fn on_humans(&mut self, h: &HumanSkeletons) {
        let Some(q) = &self.q else {
            return;
        };
        let stamp = h.header.stamp_ns;
        if self.samples.len() >= 100_000 {
            return;
        }
        let partner: Vec<[f64; 3]> = h
            .partner_id
            .and_then(|id| joints_of(h, id))
            .map(<[_]>::to_vec)
            .unwrap_or_default();
        let frame = |f: &str| {
            self.model
                .fk(q, f)
                .map(|p| p.translation.vector.into())
                .unwrap_or([f64::NAN; 3])
        };
        let surface_m = match (&self.body, partner.len()) {
            (Some(body), n) if n >= echo_motion::skeleton::NUM_JOINTS => {
                let j: Vec<Vector3<f64>> = partner.iter().map(|p| (*p).into()).collect();
                echo_retarget::hri::gripper_reach(&self.model, body, q, &Isometry3::identity(), &j)
                    .map(|r| r.surface_m)
                    .unwrap_or(f64::INFINITY)
            }
            _ => f64::INFINITY,
        };
        self.samples.push(Sample {
            t: self.time_of(stamp),
            partner,
            grippers: GRASP.map(frame),
            shoulders: SHOULDER.map(frame),
            surface_m,
            safety: self.safety,
        });
    }

    /// Every interaction played (the mission repeats when the run is longer), scored.
    pub fn reports(&self) -> Vec<InteractionReport> {
        let d = self.mission.duration().max(1e-3);
        let end = self.samples.last().map(|s| s.t).unwrap_or(0.0);
        let mut out = vec![];
        let mut lap = 0.0;
        while lap < end {
            for (i, seg) in self.mission.segments.iter().enumerate() {
                // A response lags the partner: it is scored until the next interaction starts
                // (the transition), or 1 s after the last one ends.
                let until = self
                    .mission
                    .segments
                    .get(i + 1)
                    .map(|n| n.start_s)
                    .unwrap_or(seg.end_s + 1.0);
                let (a, b) = (lap + seg.start_s, lap + until);
                // Only interactions seen from their start to (nearly) their end.
                if a < 0.0 || lap + seg.end_s > end + 0.5 || !self.samples.iter().any(|s| s.t >= a)
                {
                    continue;
                }
                out.push(behaviour::report(
                    seg.interaction,
                    &seg.text,
                    a,
                    b,
                    &self.samples,
                ));
            }
            lap += d;
        }
        out
    }
}

/// Table lines of the per-interaction reports.
pub fn render(reports: &[InteractionReport]) -> String {
    let mut out = String::from("what the robot did:\n");
    for r in reports {
        let mut what = vec![];
        if let (Some(p), Some(w)) = (&r.partner_wave, &r.robot_wave) {
            let onset = match (p.onset_s, w.onset_s) {
                (Some(a), Some(b)) => format!(", raised {:+.1} s after the partner", b - a),
                _ => String::new(),
            };
            what.push(format!(
                "wave back: {} ({:.1} oscillations of {:.2} m, arm raised {:.1} s{onset}; partner {:.1} of {:.2} m)",
                if w.recognisable() { "yes" } else { "no" },
                w.oscillations,
                w.amplitude_m,
                w.raised_s,
                p.oscillations,
                p.amplitude_m,
            ));
        }
        if let Some(c) = &r.contact {
            let ttc = c
                .time_to_contact_s
                .map(|t| format!(", first touch {t:.1} s in"))
                .unwrap_or_default();
            what.push(format!(
                "contact: {} (closest gripper–hand surfaces {:.3} m, held within 1 cm {:.1} s{ttc})",
                if c.made { "made" } else { "not made" },
                c.closest_surface_m,
                c.held_s,
            ));
        }
        let s = &r.safety;
        what.push(format!(
            "safety: {} protective stop(s), limiting {:.1} s, stopping {:.1} s, holding {:.1} s",
            s.stops, s.limiting_s, s.stopping_s, s.holding_s
        ));
        out.push_str(&format!(
            "  {:>5.1}–{:<5.1} s {:<12} {}\n",
            r.start_s,
            r.end_s,
            format!("{:?}", r.interaction),
            what.join("; ")
        ));
    }
    out
}
