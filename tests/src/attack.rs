//! A hostile client: floods every input key of a running pipeline with malformed, oversized,
//! non-finite, out-of-range, reordered, far-future, wrong-robot, forged-source and wildcard
//! messages, JSON and ROS 2 CDR, and hostile queries, and counts what it sent per class.
//!
//! Well-formed hostile messages are mutations of real traffic: [`Templates::capture`] records
//! one message of each input key from the running pipeline (or builds one where nothing
//! publishes it), and [`mutations`] turns each into the attack classes.

use std::collections::BTreeMap;
use std::time::Duration;

use anyhow::{anyhow, Result};
use echo_bus::{keys, Bus, RobotId};
use echo_msgs::{ControlMode, EStop, EStopAction, Header, Interaction, InteractionIntent};
use serde_json::Value;

/// Attack classes, in report order.
pub const CLASSES: &[&str] = &[
    "malformed",
    "oversized",
    "non_finite",
    "out_of_range",
    "wrong_size",
    "unknown_joint",
    "reordered",
    "far_future",
    "wrong_robot",
    "forged_source",
    "wildcard",
    "ros2_cdr",
    "query",
];

/// One real message per input key, as JSON.
#[derive(Debug, Clone, Default)]
pub struct Templates {
    /// Key → a message seen (or built) on it.
    pub by_key: BTreeMap<String, Value>,
}

impl Templates {
    /// Listen on `keys` for up to `wait` and keep the first message of each; keys nobody
    /// publishes get a hand-built message (prompt, e-stop) or stay absent.
    pub async fn capture(bus: &Bus, keys: &[String], wait: Duration) -> Result<Templates> {
        let mut subs = vec![];
        for k in keys {
            let s = bus
                .session()
                .declare_subscriber(k.as_str())
                .await
                .map_err(|e| anyhow!("subscribing {k}: {e}"))?;
            subs.push((k.clone(), s));
        }
        let mut by_key = BTreeMap::new();
        let end = tokio::time::Instant::now() + wait;
        while tokio::time::Instant::now() < end && by_key.len() < keys.len() {
            for (k, s) in &subs {
                if by_key.contains_key(k) {
                    continue;
                }
                if let Ok(Some(sample)) = s.try_recv() {
                    if let Ok(v) = serde_json::from_slice::<Value>(&sample.payload().to_bytes()) {
                        by_key.insert(k.clone(), v);
                    }
                }
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        Ok(Templates { by_key })
    }

    /// Hand-built messages for the operator's keys of `robot`.
    pub fn add_operator_keys(&mut self, robot: &RobotId) {
        let h = || Header::new(robot.as_str(), "operator", "");
        self.by_key.entry(keys::prompt(robot)).or_insert_with(|| {
            serde_json::to_value(InteractionIntent {
                header: h(),
                text: "Two people shake hands.".into(),
                interaction: Interaction::Handshake,
                mode: ControlMode::Forecast,
            })
            .unwrap_or(Value::Null)
        });
        self.by_key.entry(keys::estop(robot)).or_insert_with(|| {
            // A reset: replayed or forged, it must never lift a latched stop it should not.
            serde_json::to_value(EStop {
                header: h(),
                action: EStopAction::Reset,
                reason: "attack".into(),
            })
            .unwrap_or(Value::Null)
        });
    }
}

/// The first number under `v` outside the header.
fn first_number(v: &mut Value) -> Option<&mut Value> {
    match v {
        Value::Object(m) => m
            .iter_mut()
            .filter(|(k, _)| k.as_str() != "header")
            .find_map(|(_, x)| first_number(x)),
        Value::Array(a) => a.iter_mut().find_map(first_number),
        Value::Number(_) => Some(v),
        _ => None,
    }
}

/// Apply `f` to every number of `v` outside the header.
fn map_numbers(v: &mut Value, f: &dyn Fn(f64) -> f64) {
    match v {
        Value::Object(m) => {
            for (k, x) in m.iter_mut() {
                if k != "header" {
                    map_numbers(x, f);
                }
            }
        }
        Value::Array(a) => a.iter_mut().for_each(|x| map_numbers(x, f)),
        Value::Number(n) => {
            if let Some(x) = n.as_f64() {
                if let Some(y) = serde_json::Number::from_f64(f(x)) {
                    *n = y;
                }
            }
        }
        _ => {}
    }
}

/// The first non-empty array under `v` (outside the header) whose elements all pass `is`:
/// numbers (a position vector) or strings (joint names).
fn first_array(v: &mut Value, is: fn(&Value) -> bool) -> Option<&mut Vec<Value>> {
    match v {
        Value::Object(m) => m
            .iter_mut()
            .filter(|(k, _)| k.as_str() != "header")
            .find_map(|(_, x)| first_array(x, is)),
        Value::Array(a) => {
            if !a.is_empty() && a.iter().all(is) {
                Some(a)
            } else {
                a.iter_mut().find_map(|x| first_array(x, is))
            }
        }
        _ => None,
    }
}

fn header_mut(v: &mut Value) -> Option<&mut serde_json::Map<String, Value>> {
    v.get_mut("header").and_then(Value::as_object_mut)
}

fn bytes(v: &Value) -> Vec<u8> {
    serde_json::to_vec(v).unwrap_or_default()
}

/// Payloads that no input may accept, independent of the message type.
pub fn malformed() -> Vec<Vec<u8>> {
    vec![
        b"{".to_vec(),
        b"not json".to_vec(),
        b"null".to_vec(),
        b"[1,2,3]".to_vec(),
        br#"{"header":{"schema":1}}"#.to_vec(),
        br#"{"header":"x","position":"NaN"}"#.to_vec(),
        [vec![b'['; 50_000], vec![b']'; 50_000]].concat(),
        vec![0xff, 0xfe, 0x00, 0x01],
    ]
}

/// An oversized payload (4 MiB).
pub fn oversized() -> Vec<u8> {
    vec![b' '; 4 << 20]
}

/// Hostile variants of one real message `t` (class, payload). `round` varies sequence numbers
/// so that replays and forged sources keep coming. With `impersonate`, out-of-range joint
/// states also come under the real sender's name with sequence numbers ahead of it (a second
/// publisher posing as the robot: it locks the real sender out of every receiver's order check
/// while it lasts, and for `SeqTracker::EXPIRY` after).
pub fn mutations(t: &Value, round: u64, impersonate: bool) -> Vec<(&'static str, Vec<u8>)> {
    let mut out = vec![];
    let real_source = t
        .get("header")
        .and_then(|h| h.get("source"))
        .and_then(Value::as_str)
        .unwrap_or("")
        .to_string();
    let real_seq = t
        .get("header")
        .and_then(|h| h.get("seq"))
        .and_then(Value::as_u64)
        .unwrap_or(0);
    // A fresh sender per round, with increasing sequence numbers: it passes the order checks,
    // so what follows is judged on content.
    let fresh = |v: &mut Value, tag: &str| {
        if let Some(h) = header_mut(v) {
            h.insert("source".into(), format!("attacker-{tag}").into());
            h.insert("seq".into(), (round + 1).into());
            h.insert("stamp_ns".into(), echo_msgs::now_ns().into());
        }
    };

    // Non-finite: JSON cannot carry NaN; an overflowing literal is how one arrives.
    let mut v = t.clone();
    fresh(&mut v, "nf");
    if let Some(x) = first_number(&mut v) {
        *x = Value::String("__NF__".into());
        let s = serde_json::to_string(&v)
            .unwrap_or_default()
            .replacen("\"__NF__\"", "1e999", 1);
        out.push(("non_finite", s.into_bytes()));
    }

    // Out of range: every number far away; and the joint values that once got through.
    for scale in [1e6, -1e9] {
        let mut v = t.clone();
        fresh(&mut v, "oor");
        map_numbers(&mut v, &|x| if x == 0.0 { scale } else { x * scale });
        out.push(("out_of_range", bytes(&v)));
    }
    let names: Vec<String> = t
        .get("name")
        .and_then(Value::as_array)
        .map(|a| {
            a.iter()
                .filter_map(|x| x.as_str().map(String::from))
                .collect()
        })
        .unwrap_or_default();
    for (joint, bad) in [
        ("arm_right_1_joint", 2.5),
        ("arm_right_1_joint", 1e9),
        ("torso_lift_joint", 50.0),
    ] {
        if let Some(i) = names.iter().position(|n| n == joint) {
            // From the real source with sequence numbers ahead of it (a second publisher
            // impersonating the robot), and from a fresh source.
            for forged in [true, false] {
                if forged && !impersonate {
                    continue;
                }
                let mut v = t.clone();
                if forged {
                    if let Some(h) = header_mut(&mut v) {
                        // Far enough ahead of the real sender to pass its order check.
                        h.insert("seq".into(), (real_seq + 50_000 + round).into());
                        h.insert("stamp_ns".into(), echo_msgs::now_ns().into());
                    }
                } else {
                    fresh(&mut v, "oor-state");
                }
                if let Some(p) = v.get_mut("position").and_then(Value::as_array_mut) {
                    if let Some(n) = serde_json::Number::from_f64(bad) {
                        p[i] = Value::Number(n);
                    }
                }
                out.push(("out_of_range", bytes(&v)));
            }
        }
    }

    // Wrong size: one number missing.
    let mut v = t.clone();
    fresh(&mut v, "size");
    if let Some(a) = first_array(&mut v, Value::is_number) {
        a.pop();
        out.push(("wrong_size", bytes(&v)));
    }

    // Unknown joint.
    let mut v = t.clone();
    fresh(&mut v, "joint");
    if let Some(a) = first_array(&mut v, Value::is_string) {
        a[0] = Value::String("warp_drive_joint".into());
        out.push(("unknown_joint", bytes(&v)));
    }

    // Reordered: the real sender's message replayed with an old sequence number.
    let mut v = t.clone();
    if let Some(h) = header_mut(&mut v) {
        h.insert("seq".into(), (round % 3).into());
    }
    out.push(("reordered", bytes(&v)));

    // Far future: the largest stamp there is, from a fresh sender and from the real one.
    for forged in [false, true] {
        let mut v = t.clone();
        if forged {
            if let Some(h) = header_mut(&mut v) {
                h.insert("seq".into(), (real_seq + 2 + round).into());
                h.insert("source".into(), real_source.clone().into());
            }
        } else {
            fresh(&mut v, "future");
        }
        if let Some(h) = header_mut(&mut v) {
            h.insert("stamp_ns".into(), u64::MAX.into());
        }
        out.push(("far_future", bytes(&v)));
    }

    // Another robot's message on this robot's key.
    let mut v = t.clone();
    fresh(&mut v, "robot");
    if let Some(h) = header_mut(&mut v) {
        h.insert("robot_id".into(), "someone-else".into());
    }
    out.push(("wrong_robot", bytes(&v)));

    // The real sender's name with a sequence number far ahead (it must not lock the real
    // sender out).
    let mut v = t.clone();
    if let Some(h) = header_mut(&mut v) {
        h.insert("seq".into(), (u64::MAX - round).into());
        h.insert("stamp_ns".into(), echo_msgs::now_ns().into());
    }
    out.push(("forged_source", bytes(&v)));
    out
}

/// ROS 2 CDR joint states that must be refused: out of range, non-finite, wrong sizes,
/// garbage. `names`: the robot's joints; `q`: plausible positions.
pub fn ros2_joint_states(names: &[String], q: &[f64]) -> Vec<Vec<u8>> {
    use echo_ros2::{encode, RosHeader, RosJointState, Time};
    let js = |position: Vec<f64>, name: Vec<String>| RosJointState {
        header: RosHeader {
            stamp: Time::from_ns(echo_msgs::now_ns()),
            frame_id: String::new(),
        },
        name,
        position,
        velocity: vec![],
        effort: vec![],
    };
    let with = |joint: &str, x: f64| {
        let mut p = q.to_vec();
        if let Some(i) = names.iter().position(|n| n == joint) {
            p[i] = x;
        }
        p
    };
    let mut out = vec![];
    for (j, x) in [
        ("arm_right_1_joint", 2.5),
        ("arm_right_1_joint", 1e9),
        ("torso_lift_joint", 50.0),
        ("arm_left_2_joint", f64::NAN),
        ("head_1_joint", f64::INFINITY),
    ] {
        if let Ok(b) = encode(&js(with(j, x), names.to_vec())) {
            out.push(b);
        }
    }
    if let Ok(b) = encode(&js(q[..q.len().saturating_sub(1)].to_vec(), names.to_vec())) {
        out.push(b);
    }
    out.push(vec![0u8, 1, 0, 0, 9, 9]);
    out.push(vec![0u8, 1, 0, 0, 0xff, 0xff, 0xff, 0x7f]);
    out
}

/// What was sent, per class.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Sent {
    /// Messages per class.
    pub per_class: BTreeMap<String, u64>,
    /// Puts the client's own session refused (e.g. a key it may not use).
    pub put_errors: u64,
}

impl Sent {
    fn add(&mut self, class: &str) {
        *self.per_class.entry(class.to_string()).or_default() += 1;
    }

    /// All messages.
    pub fn total(&self) -> u64 {
        self.per_class.values().sum()
    }
}

/// Send one round of every class to every key of `templates` (and `raw_keys`, which carry no
/// template), ROS 2 joint states to `ros_states`, wildcard puts under `robot`; `impersonate`:
/// see [`mutations`].
#[allow(clippy::too_many_arguments)]
pub async fn round(
    bus: &Bus,
    templates: &Templates,
    raw_keys: &[String],
    ros_states: Option<(&str, &[Vec<u8>])>,
    robot: &RobotId,
    n: u64,
    impersonate: bool,
    sent: &mut Sent,
) {
    let put = |key: String, payload: Vec<u8>| async move {
        bus.session().put(key.as_str(), payload).await.is_ok()
    };
    let mut all_keys: Vec<String> = templates.by_key.keys().cloned().collect();
    all_keys.extend(raw_keys.iter().cloned());
    for k in &all_keys {
        for p in malformed() {
            if put(k.clone(), p).await {
                sent.add("malformed");
            } else {
                sent.put_errors += 1;
            }
        }
        if n.is_multiple_of(10) {
            if put(k.clone(), oversized()).await {
                sent.add("oversized");
            } else {
                sent.put_errors += 1;
            }
        }
    }
    for (k, t) in &templates.by_key {
        for (class, p) in mutations(t, n, impersonate) {
            if put(k.clone(), p).await {
                sent.add(class);
            } else {
                sent.put_errors += 1;
            }
        }
    }
    if let Some((key, payloads)) = ros_states {
        for p in payloads {
            if put(key.to_string(), p.clone()).await {
                sent.add("ros2_cdr");
            } else {
                sent.put_errors += 1;
            }
        }
    }
    // Queries: hostile requests to the retargeter's batch queryable (every 10th round: each
    // waits for its answer, at most 2 s).
    if n.is_multiple_of(10) {
        let key = keys::retarget_batch(robot);
        for p in [
            b"{\"poses\": \"no\"}".to_vec(),
            b"{".to_vec(),
            br#"{"poses":[[[1e999,0,0]]]}"#.to_vec(),
            vec![b'['; 20_000],
        ] {
            match bus
                .session()
                .get(key.as_str())
                .payload(p)
                .timeout(Duration::from_secs(2))
                .await
            {
                Ok(replies) => {
                    let _ = replies.recv_async().await;
                    sent.add("query");
                }
                Err(_) => sent.put_errors += 1,
            }
        }
    }
    // Wildcards: one key expression reaching every robot's inputs at once (not the command key:
    // only the safety service may speak to the robot, which the router's access control enforces).
    let r = robot.as_str();
    for k in [
        "echo/*/robot/state".to_string(),
        "echo/*/humans".to_string(),
        format!("echo/{r}/perception/*"),
    ] {
        for p in malformed().into_iter().take(3) {
            if put(k.clone(), p).await {
                sent.add("wildcard");
            } else {
                sent.put_errors += 1;
            }
        }
    }
}
