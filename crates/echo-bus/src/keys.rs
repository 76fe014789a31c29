//! Key expressions. Every key Echo uses is built here, by one function, and nowhere else.
//!
//! Layout: `echo/<robot>/<plane>/...` so a fleet shares one Zenoh network and a subscriber to
//! `echo/<robot>/**` sees one robot's whole traffic.

use echo_msgs::validate::check_identifier;
use echo_msgs::ValidationError;

/// Root of every Echo key.
pub const ROOT: &str = "echo";

/// A validated robot id (`[A-Za-z0-9_-]{1,64}`): safe to place in a key expression.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct RobotId(String);

impl RobotId {
    /// Validate and wrap a robot id.
    pub fn new(id: &str) -> Result<Self, ValidationError> {
        check_identifier("robot_id", id)?;
        Ok(RobotId(id.to_string()))
    }

    /// The id as text.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl std::fmt::Display for RobotId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// `echo/<robot>/perception/raw` — pose-estimator keypoints (KeypointFrame).
pub fn perception_raw(robot: &RobotId) -> String {
    format!("{ROOT}/{robot}/perception/raw")
}

/// `echo/<robot>/humans` — tracked skeletons in base_footprint (HumanSkeletons).
pub fn humans(robot: &RobotId) -> String {
    format!("{ROOT}/{robot}/humans")
}

/// `echo/<robot>/robot/state` — measured joint state (JointState).
pub fn robot_state(robot: &RobotId) -> String {
    format!("{ROOT}/{robot}/robot/state")
}

/// `echo/<robot>/prompt` — interaction intent and text (InteractionIntent).
pub fn prompt(robot: &RobotId) -> String {
    format!("{ROOT}/{robot}/prompt")
}

/// `echo/<robot>/forecast` — forecasts of partner and robot (Forecast).
pub fn forecast(robot: &RobotId) -> String {
    format!("{ROOT}/{robot}/forecast")
}

/// `echo/<robot>/retarget` — retargeted robot poses in imitation mode (RobotPlan).
pub fn retarget(robot: &RobotId) -> String {
    format!("{ROOT}/{robot}/retarget")
}

/// `echo/<robot>/retarget/batch` — queryable: retarget a batch of poses (JSON request/reply).
pub fn retarget_batch(robot: &RobotId) -> String {
    format!("{ROOT}/{robot}/retarget/batch")
}

/// `echo/<robot>/command` — the filtered robot command (RobotCommand); safety service only.
pub fn command(robot: &RobotId) -> String {
    format!("{ROOT}/{robot}/command")
}

/// `echo/<robot>/safety/status` — safety filter state (SafetyStatus).
pub fn safety_status(robot: &RobotId) -> String {
    format!("{ROOT}/{robot}/safety/status")
}

/// `echo/<robot>/estop` — emergency stop engage/reset (EStop).
pub fn estop(robot: &RobotId) -> String {
    format!("{ROOT}/{robot}/estop")
}

/// `echo/<robot>/status/<service>` — a service's counters and health (ServiceStatus).
pub fn service_status(robot: &RobotId, service: &str) -> String {
    format!("{ROOT}/{robot}/status/{service}")
}

/// `echo/<robot>/status/*` — every service's status.
pub fn service_status_all(robot: &RobotId) -> String {
    format!("{ROOT}/{robot}/status/*")
}

/// `echo/<robot>/alive/<service>` — liveliness token of a running service.
pub fn alive(robot: &RobotId, service: &str) -> String {
    format!("{ROOT}/{robot}/alive/{service}")
}

/// `echo/<robot>/alive/*` — every liveliness token of one robot.
pub fn alive_all(robot: &RobotId) -> String {
    format!("{ROOT}/{robot}/alive/*")
}

/// `echo/*/alive/*` — every liveliness token of the fleet.
pub fn alive_fleet() -> String {
    format!("{ROOT}/*/alive/*")
}

/// `echo/<robot>/**` — everything about one robot.
pub fn robot_all(robot: &RobotId) -> String {
    format!("{ROOT}/{robot}/**")
}

/// Split a liveliness key `echo/<robot>/alive/<service>` into (robot, service).
pub fn parse_alive(key: &str) -> Option<(&str, &str)> {
    let mut it = key.split('/');
    match (it.next(), it.next(), it.next(), it.next(), it.next()) {
        (Some(ROOT), Some(robot), Some("alive"), Some(service), None) => Some((robot, service)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_are_namespaced_and_valid() {
        let r = RobotId::new("tiago-7").unwrap();
        assert_eq!(humans(&r), "echo/tiago-7/humans");
        assert_eq!(alive(&r, "safety"), "echo/tiago-7/alive/safety");
        for k in [
            perception_raw(&r),
            command(&r),
            estop(&r),
            robot_all(&r),
            alive_fleet(),
        ] {
            zenoh::key_expr::KeyExpr::try_from(k.as_str()).unwrap();
        }
        assert_eq!(
            parse_alive("echo/tiago-7/alive/safety"),
            Some(("tiago-7", "safety"))
        );
        assert_eq!(parse_alive("echo/tiago-7/humans"), None);
    }

    #[test]
    fn robot_ids_cannot_inject_wildcards() {
        for bad in ["", "a/b", "*", "**", "a$*", "tiago 1"] {
            assert!(RobotId::new(bad).is_err(), "{bad}");
        }
    }
}
