//! A typed view of everything on the bus under a key expression, for tools that watch rather
//! than take part (the demo's account, `echoctl monitor`, tests): each sample's key is matched
//! against the robot's [`topics`](crate::topics) and its payload decoded (and validated) as that
//! topic's message. Keys outside Echo's topics (ROS 2 bridges, raw probes) are passed on
//! undecoded.

use echo_msgs::{
    decode, DecodeError, EStop, Forecast, Header, HumanSkeletons, InteractionIntent, JointState,
    KeypointFrame, Message, RobotCommand, RobotPlan, SafetyStatus, ServiceStatus,
};
use std::collections::HashMap;

use zenoh::key_expr::KeyExpr;

use crate::keys::RobotId;
use crate::topics;
use crate::Bus;

/// A decoded message, by the edge it travelled on.
#[derive(Debug, Clone)]
pub enum Seen {
    /// `perception/raw`.
    Keypoints(KeypointFrame),
    /// `humans`.
    Humans(HumanSkeletons),
    /// `robot/state`.
    RobotState(JointState),
    /// `prompt`.
    Prompt(InteractionIntent),
    /// `forecast`.
    Forecast(Box<Forecast>),
    /// `retarget/plan`.
    Retarget(RobotPlan),
    /// `command`.
    Command(RobotCommand),
    /// `safety/status`.
    Safety(SafetyStatus),
    /// `estop`.
    EStop(EStop),
    /// `status/<service>`.
    ServiceStatus(ServiceStatus),
}

impl Seen {
    /// The message's header.
    pub fn header(&self) -> &Header {
        match self {
            Seen::Keypoints(m) => m.header(),
            Seen::Humans(m) => m.header(),
            Seen::RobotState(m) => m.header(),
            Seen::Prompt(m) => m.header(),
            Seen::Forecast(m) => m.header(),
            Seen::Retarget(m) => m.header(),
            Seen::Command(m) => m.header(),
            Seen::Safety(m) => m.header(),
            Seen::EStop(m) => m.header(),
            Seen::ServiceStatus(m) => m.header(),
        }
    }
}

/// Which of a robot's topics a key belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Edge {
    /// [`topics::perception_raw`].
    Keypoints,
    /// [`topics::humans`].
    Humans,
    /// [`topics::robot_state`].
    RobotState,
    /// [`topics::prompt`].
    Prompt,
    /// [`topics::forecast`].
    Forecast,
    /// [`topics::retarget`].
    Retarget,
    /// [`topics::command`].
    Command,
    /// [`topics::safety_status`].
    Safety,
    /// [`topics::estop`].
    EStop,
    /// [`topics::service_status_all`].
    ServiceStatus,
}

/// The robot and edge of `key`, from the robot's topics; `None` for keys that are not Echo's.
pub fn classify(key: &str) -> Option<(RobotId, Edge)> {
    let robot = RobotId::new(key.split('/').nth(1)?).ok()?;
    let r = &robot;
    let exact = [
        (topics::perception_raw(r).key, Edge::Keypoints),
        (topics::humans(r).key, Edge::Humans),
        (topics::robot_state(r).key, Edge::RobotState),
        (topics::prompt(r).key, Edge::Prompt),
        (topics::forecast(r).key, Edge::Forecast),
        (topics::retarget(r).key, Edge::Retarget),
        (topics::command(r).key, Edge::Command),
        (topics::safety_status(r).key, Edge::Safety),
        (topics::estop(r).key, Edge::EStop),
    ];
    if let Some((_, e)) = exact.iter().find(|(k, _)| k == key) {
        return Some((robot, *e));
    }
    let status = KeyExpr::try_from(topics::service_status_all(r).key).ok()?;
    let k = KeyExpr::try_from(key).ok()?;
    status.includes(&k).then_some((robot, Edge::ServiceStatus))
}

/// Decode `payload` as the message of `edge`.
pub fn decode_as(edge: Edge, payload: &[u8]) -> Result<Seen, DecodeError> {
    Ok(match edge {
        Edge::Keypoints => Seen::Keypoints(decode(payload)?),
        Edge::Humans => Seen::Humans(decode(payload)?),
        Edge::RobotState => Seen::RobotState(decode(payload)?),
        Edge::Prompt => Seen::Prompt(decode(payload)?),
        Edge::Forecast => Seen::Forecast(Box::new(decode(payload)?)),
        Edge::Retarget => Seen::Retarget(decode(payload)?),
        Edge::Command => Seen::Command(decode(payload)?),
        Edge::Safety => Seen::Safety(decode(payload)?),
        Edge::EStop => Seen::EStop(decode(payload)?),
        Edge::ServiceStatus => Seen::ServiceStatus(decode(payload)?),
    })
}

/// One sample as an observer sees it.
#[derive(Debug)]
pub struct Observation {
    /// Its key.
    pub key: String,
    /// The robot and edge of the key, when it is one of Echo's topics.
    pub edge: Option<(RobotId, Edge)>,
    /// The payload as received.
    pub payload: Vec<u8>,
    /// Receive time on this host's wall clock, ns since the UNIX epoch.
    pub received_ns: u64,
    /// The decoded message (`None` for keys outside Echo's topics).
    pub message: Option<Result<Seen, DecodeError>>,
}

impl Observation {
    /// `key`, `payload` received at `received_ns`, classified and decoded.
    pub fn new(key: &str, payload: Vec<u8>, received_ns: u64) -> Observation {
        Self::classified(key, classify(key), payload, received_ns)
    }

    /// As [`Observation::new`], with the key's classification already known.
    fn classified(
        key: &str,
        edge: Option<(RobotId, Edge)>,
        payload: Vec<u8>,
        received_ns: u64,
    ) -> Observation {
        let message = edge.as_ref().map(|(_, e)| decode_as(*e, &payload));
        Observation {
            key: key.to_string(),
            edge,
            payload,
            received_ns,
            message,
        }
    }

    /// The decoded message, if it decoded.
    pub fn seen(&self) -> Option<&Seen> {
        self.message.as_ref().and_then(|m| m.as_ref().ok())
    }

    /// The key below `echo/<robot>/` (the key itself for keys outside Echo's topics).
    pub fn short_key(&self) -> &str {
        match &self.edge {
            Some(_) => self.key.splitn(3, '/').nth(2).unwrap_or(&self.key),
            None => &self.key,
        }
    }

    /// Age at receipt, ms (receive time − the sender's stamp), for decoded messages.
    pub fn age_ms(&self) -> Option<f64> {
        self.seen()
            .map(|s| (i128::from(self.received_ns) - i128::from(s.header().stamp_ns)) as f64 / 1e6)
    }
}

/// Call `f` with every sample under `key_expr` (e.g. `keys::robot_all(robot)`), classified and
/// decoded, until the returned subscriber is dropped. Each distinct key is classified once.
pub async fn observe(
    bus: &Bus,
    key_expr: &str,
    f: impl Fn(Observation) + Send + Sync + 'static,
) -> anyhow::Result<zenoh::pubsub::Subscriber<()>> {
    let known: std::sync::Mutex<HashMap<String, Option<(RobotId, Edge)>>> = Default::default();
    bus.session()
        .declare_subscriber(key_expr.to_string())
        .callback(move |sample| {
            let now = echo_msgs::now_ns();
            let key = sample.key_expr().as_str();
            let edge = {
                let mut known = known.lock().unwrap_or_else(|e| e.into_inner());
                if known.len() > 4096 {
                    // Keys from a flood of made-up names: stop remembering them.
                    known.clear();
                }
                known
                    .entry(key.to_string())
                    .or_insert_with(|| classify(key))
                    .clone()
            };
            f(Observation::classified(
                key,
                edge,
                sample.payload().to_bytes().into_owned(),
                now,
            ))
        })
        .await
        .map_err(|e| anyhow::anyhow!("subscribing to {key_expr}: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use echo_msgs::{encode, EStopAction};

    #[test]
    fn keys_are_classified_through_the_topics_and_payloads_decoded() {
        let r = RobotId::new("tiago").unwrap();
        assert_eq!(
            classify(&topics::humans(&r).key),
            Some((r.clone(), Edge::Humans))
        );
        assert_eq!(
            classify(&topics::service_status(&r, "safety").key),
            Some((r.clone(), Edge::ServiceStatus))
        );
        assert_eq!(classify("echo/tiago/ros2/joint_states"), None);
        assert_eq!(classify("elsewhere"), None);

        let e = EStop {
            header: Header::new("tiago", "operator", ""),
            action: EStopAction::Engage,
            reason: "test".into(),
        };
        let o = Observation::new(
            &topics::estop(&r).key,
            encode(&e),
            e.header.stamp_ns + 2_000_000,
        );
        assert!(matches!(o.seen(), Some(Seen::EStop(x)) if x.reason == "test"));
        assert_eq!(o.short_key(), "estop");
        assert!((o.age_ms().unwrap() - 2.0).abs() < 1e-9);

        // A payload that is not the topic's message is an error, not a guess.
        let bad = Observation::new(&topics::humans(&r).key, encode(&e), 0);
        assert!(matches!(bad.message, Some(Err(_))));
        assert!(bad.seen().is_none());
        let other = Observation::new("echo/tiago/ros2/cmd_vel", vec![1, 2, 3], 0);
        assert!(other.message.is_none());
    }
}
