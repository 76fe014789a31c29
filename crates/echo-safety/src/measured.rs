//! The measured joint state as evidence, not as truth: one source per robot, positions inside the
//! hard limits, motion no faster than the joint can move.
//!
//! A sample that breaks a rule is a **sensor fault**: it is rejected (counted by reason), it never
//! becomes the filter's state or limits, and it latches a fault that stops the robot until the
//! accepted source has reported only plausible samples for `fault_clear_ms`.
//!
//! Rules, per sample of the accepted source, per joint the robot model knows:
//! * non-finite → `non_finite`;
//! * outside the URDF hard limits by more than `measured_tolerance` → `out_of_limits`;
//! * further from the previous sample of that joint than `V·(Δt + state_jitter_s)·1.5 +
//!   measured_tolerance` (Δt on the receiver's clock, V the joint's velocity limit) →
//!   `jump`. The previous sample is the last one received, plausible or not, so a second stream
//!   interleaved with the real one jumps on every sample.
//!
//! Source: the configured `state_source`, or the first source heard; another source is rejected
//! (`foreign_source`) while the accepted one has been heard within `state_source_timeout_ms`.
//! After that silence the next source heard becomes the accepted one (a restarted driver); its
//! samples pass the same rules, and the tracking-tolerance rule keeps the robot stopped if it
//! reports a position other than the commanded one.

use std::time::Instant;

use echo_msgs::JointState;

/// Why a measured sample was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StateFault {
    /// Another sender than the accepted one.
    #[error("joint state from '{got}' while '{accepted}' is the robot's state source")]
    ForeignSource {
        /// Sender of this sample.
        got: String,
        /// The accepted sender.
        accepted: String,
    },
    /// A position that is not a number.
    #[error("{joint} measured {value}: not a finite number")]
    NonFinite {
        /// Joint.
        joint: String,
        /// Value.
        value: f64,
    },
    /// A position beyond the hard limits.
    #[error("{joint} measured {value:.4} outside its hard limits [{lower:.4}, {upper:.4}]")]
    OutOfLimits {
        /// Joint.
        joint: String,
        /// Value.
        value: f64,
        /// Hard lower limit.
        lower: f64,
        /// Hard upper limit.
        upper: f64,
    },
    /// A change faster than the joint can move.
    #[error("{joint} jumped {delta:.4} in {dt_ms:.0} ms (at most {allowed:.4} possible)")]
    Jump {
        /// Joint.
        joint: String,
        /// Change.
        delta: f64,
        /// Time since the previous sample, ms.
        dt_ms: f64,
        /// Largest plausible change.
        allowed: f64,
    },
}

impl StateFault {
    /// Short reason for counters.
    pub fn reason(&self) -> &'static str {
        match self {
            StateFault::ForeignSource { .. } => "foreign_source",
            StateFault::NonFinite { .. } => "non_finite",
            StateFault::OutOfLimits { .. } => "out_of_limits",
            StateFault::Jump { .. } => "jump",
        }
    }

    /// Whether the fault says the robot's own sensors are wrong (everything but a foreign
    /// source, which is refused without stopping the robot).
    pub fn is_sensor_fault(&self) -> bool {
        !matches!(self, StateFault::ForeignSource { .. })
    }
}

/// One joint the monitor checks.
#[derive(Debug, Clone)]
pub struct CheckedJoint {
    /// Name.
    pub name: String,
    /// Hard lower limit.
    pub lower: f64,
    /// Hard upper limit.
    pub upper: f64,
    /// Velocity limit (for the jump rule).
    pub velocity: f64,
}

/// Parameters of the rules.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MonitorParams {
    /// Slack beyond the hard limits and on every jump, in the joint's units.
    pub tolerance: f64,
    /// Receipt jitter allowed on top of the time between samples, s.
    pub jitter_s: f64,
    /// The accepted source is released after this long without a sample, s.
    pub source_timeout_s: f64,
}

/// Source lock and plausibility checks of measured joint states.
#[derive(Debug, Clone)]
pub struct StateMonitor {
    joints: Vec<CheckedJoint>,
    params: MonitorParams,
    configured: Option<String>,
    accepted: Option<(String, Instant)>,
    previous: Vec<Option<(f64, Instant)>>,
}

impl StateMonitor {
    /// A monitor over `joints`; `source`: the only sender accepted, or `None` for the first heard.
    pub fn new(joints: Vec<CheckedJoint>, params: MonitorParams, source: Option<String>) -> Self {
        let n = joints.len();
        StateMonitor {
            joints,
            params,
            configured: source,
            accepted: None,
            previous: vec![None; n],
        }
    }

    /// The accepted source, if any.
    pub fn source(&self) -> Option<&str> {
        self.accepted.as_ref().map(|(s, _)| s.as_str())
    }

    /// Check `js` received at `now`. `Ok` with the sample's source changes (true when a new
    /// source was just accepted); `Err` with the first rule it breaks.
    pub fn check(&mut self, js: &JointState, now: Instant) -> Result<bool, StateFault> {
        let src = js.header.source.as_str();
        let mut switched = false;
        if let Some(want) = &self.configured {
            if src != want {
                return Err(StateFault::ForeignSource {
                    got: src.chars().take(80).collect(),
                    accepted: want.clone(),
                });
            }
        }
        match &self.accepted {
            Some((s, _)) if s == src => {}
            Some((s, seen))
                if now.saturating_duration_since(*seen).as_secs_f64()
                    < self.params.source_timeout_s =>
            {
                return Err(StateFault::ForeignSource {
                    got: src.chars().take(80).collect(),
                    accepted: s.clone(),
                });
            }
            _ => {
                switched = self.accepted.is_some();
                self.accepted = Some((src.to_string(), now));
                // The new source is judged on its own: no jump against the old one's samples.
                self.previous.iter_mut().for_each(|p| *p = None);
            }
        }
        if let Some((_, seen)) = &mut self.accepted {
            *seen = now;
        }
        let mut fault = None;
        for (n, &q) in js.name.iter().zip(&js.position) {
            let Some(i) = self.joints.iter().position(|j| &j.name == n) else {
                continue;
            };
            let j = &self.joints[i];
            let tol = self.params.tolerance;
            let f = if !q.is_finite() {
                Some(StateFault::NonFinite {
                    joint: n.clone(),
                    value: q,
                })
            } else if q < j.lower - tol || q > j.upper + tol {
                Some(StateFault::OutOfLimits {
                    joint: n.clone(),
                    value: q,
                    lower: j.lower,
                    upper: j.upper,
                })
            } else {
                self.previous[i].and_then(|(q0, t0)| {
                    let dt = now.saturating_duration_since(t0).as_secs_f64();
                    let allowed = j.velocity * (dt + self.params.jitter_s) * 1.5 + tol;
                    let delta = (q - q0).abs();
                    (delta > allowed).then(|| StateFault::Jump {
                        joint: n.clone(),
                        delta,
                        dt_ms: dt * 1e3,
                        allowed,
                    })
                })
            };
            if q.is_finite() {
                self.previous[i] = Some((q, now));
            }
            if fault.is_none() {
                fault = f;
            }
        }
        match fault {
            Some(f) => Err(f),
            None => Ok(switched),
        }
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use echo_msgs::Header;

    use super::*;

    fn monitor() -> StateMonitor {
        StateMonitor::new(
            vec![CheckedJoint {
                name: "j".into(),
                lower: -1.0,
                upper: 1.0,
                velocity: 1.0,
            }],
            MonitorParams {
                tolerance: 0.01,
                jitter_s: 0.05,
                source_timeout_s: 1.0,
            },
            None,
        )
    }

    fn js(source: &str, q: f64) -> JointState {
        JointState {
            header: Header::new("r", source, ""),
            name: vec!["j".into()],
            position: vec![q],
            velocity: vec![],
            base: None,
        }
    }

    #[test]
    fn out_of_limits_non_finite_and_jumps_are_faults() {
        let mut m = monitor();
        let t = Instant::now();
        assert_eq!(m.check(&js("robot", 0.0), t), Ok(false));
        assert_eq!(
            m.check(&js("robot", 1.005), t + Duration::from_secs(2)),
            Ok(false),
            "inside the tolerance"
        );
        let e = m.check(&js("robot", f64::NAN), t + Duration::from_secs(3));
        assert_eq!(e.unwrap_err().reason(), "non_finite");
        let t2 = t + Duration::from_secs(4);
        let e = m.check(&js("robot", 2.5), t2);
        assert_eq!(e.unwrap_err().reason(), "out_of_limits");
        // 10 ms later: at most 1·0.06·1.5 + 0.01 = 0.1 of change, from the last sample (2.5).
        let e = m.check(&js("robot", 0.0), t2 + Duration::from_millis(10));
        assert_eq!(e.unwrap_err().reason(), "jump");
        assert!(m
            .check(&js("robot", 0.09), t2 + Duration::from_millis(20))
            .is_ok());
        let e = m
            .check(&js("robot", 0.3), t2 + Duration::from_millis(30))
            .unwrap_err();
        assert_eq!(e.reason(), "jump");
        assert!(e.is_sensor_fault());
    }

    #[test]
    fn one_source_until_it_falls_silent() {
        let mut m = monitor();
        let t = Instant::now();
        m.check(&js("robot", 0.0), t).unwrap();
        let e = m
            .check(&js("intruder", 0.0), t + Duration::from_millis(500))
            .unwrap_err();
        assert_eq!(e.reason(), "foreign_source");
        assert!(!e.is_sensor_fault());
        assert_eq!(m.source(), Some("robot"));
        // The robot keeps talking: the intruder stays refused.
        m.check(&js("robot", 0.0), t + Duration::from_millis(900))
            .unwrap();
        assert!(m
            .check(&js("intruder", 0.0), t + Duration::from_millis(1800))
            .is_err());
        // Silent for longer than the timeout: a restarted driver takes over.
        assert_eq!(
            m.check(&js("robot-2", 0.5), t + Duration::from_millis(3000)),
            Ok(true)
        );
        assert_eq!(m.source(), Some("robot-2"));
    }

    #[test]
    fn a_configured_source_is_the_only_one() {
        let mut m = StateMonitor::new(monitor().joints, monitor().params, Some("ros2".into()));
        let t = Instant::now();
        assert!(m.check(&js("robot", 0.0), t).is_err());
        assert!(m.check(&js("ros2", 0.0), t).is_ok());
    }
}
