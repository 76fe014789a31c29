//! [`SceneBuilder`]: keeps the latest message of each input and turns them into a [`Scene`].

use std::collections::BTreeMap;

use echo_msgs::{
    decode, DecodeError, Forecast, HumanSkeletons, InteractionIntent, JointState, Message,
    SafetyState, SafetyStatus,
};
use echo_robot::collision::RobotBody;
use echo_robot::{JointValues, RobotModel};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use crate::geometry::closest_points;
use crate::scene::{Caption, Entity, EntityKind, Primitive, Rgba, Scene};
use crate::style;
use crate::SceneError;

/// The SMPL-22 bones (child, parent), from `echo_motion::PARENTS`.
fn bones() -> impl Iterator<Item = (usize, usize)> {
    echo_motion::PARENTS
        .iter()
        .enumerate()
        .filter_map(|(c, p)| usize::try_from(*p).ok().map(|p| (c, p)))
}

/// How a scene is drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneOptions {
    /// People, forecasts, the separation line and the safety state that arrived longer than this
    /// before the scene time are left out; the robot stays at its last known state. Default 1 s.
    pub max_age_ns: u64,
    /// Forecast frames drawn as ghosts, evenly spaced up to the last one. Default 5.
    pub forecast_ghosts: usize,
    /// Head camera field of view, horizontal and vertical, radians. Default 58° × 45° (the
    /// TIAGo++ head's RGB-D camera).
    pub camera_fov: (f64, f64),
    /// How far the camera frustum is drawn, m. Default 1.0.
    pub frustum_depth_m: f64,
}

impl Default for SceneOptions {
    fn default() -> Self {
        SceneOptions {
            max_age_ns: 1_000_000_000,
            forecast_ghosts: 5,
            camera_fov: (58f64.to_radians(), 45f64.to_radians()),
            frustum_depth_m: 1.0,
        }
    }
}

/// The camera pose used when the robot model has no head camera frame: 1.1 m up and 0.2 m
/// forward of the base origin, looking straight ahead (optical frame: z forward, x right, y down).
pub fn fixed_camera_pose() -> Isometry3<f64> {
    // Columns: optical x → base −y, optical y → base −z, optical z → base +x.
    let r = nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
        0.0, 0.0, 1.0, //
        -1.0, 0.0, 0.0, //
        0.0, -1.0, 0.0,
    ));
    Isometry3::from_parts(
        Translation3::new(0.2, 0.0, 1.1),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

/// Which input a message updated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Input {
    /// `echo/<robot>/humans` (HumanSkeletons).
    Humans,
    /// `echo/<robot>/forecast` (Forecast).
    Forecast,
    /// `echo/<robot>/robot/state` (JointState).
    RobotState,
    /// `echo/<robot>/safety/status` (SafetyStatus).
    SafetyStatus,
    /// `echo/<robot>/prompt` (InteractionIntent).
    Prompt,
}

impl Input {
    /// The input a key expression carries (`echo/<robot>/<suffix>`), with the robot id.
    pub fn from_key(key: &str) -> Option<(&str, Input)> {
        let rest = key.strip_prefix("echo/")?;
        let (robot, suffix) = rest.split_once('/')?;
        let input = match suffix {
            "humans" => Input::Humans,
            "forecast" => Input::Forecast,
            "robot/state" => Input::RobotState,
            "safety/status" => Input::SafetyStatus,
            "prompt" => Input::Prompt,
            _ => return None,
        };
        Some((robot, input))
    }

    /// A short name for counters.
    pub fn name(self) -> &'static str {
        match self {
            Input::Humans => "humans",
            Input::Forecast => "forecast",
            Input::RobotState => "robot/state",
            Input::SafetyStatus => "safety/status",
            Input::Prompt => "prompt",
        }
    }
}

/// What the builder did with the messages it was given.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct InputStats {
    /// Messages used, per input.
    pub accepted: BTreeMap<&'static str, u64>,
    /// Messages refused (malformed or invalid), per input.
    pub rejected: BTreeMap<&'static str, u64>,
    /// Messages on keys that are not scene inputs, or of another robot.
    pub ignored: u64,
    /// The most recent refusal, with its reason.
    pub last_error: Option<String>,
}

impl InputStats {
    /// Refused messages in total.
    pub fn rejected_total(&self) -> u64 {
        self.rejected.values().sum()
    }
}

/// Keeps the latest of each input and builds scenes from them.
///
/// ```
/// let mut b = echo_scene::SceneBuilder::new();
/// assert!(b.on_message("echo/r1/humans", b"not json").is_none());
/// assert_eq!(b.stats().rejected_total(), 1);
/// let scene = b.scene(0);
/// assert!(scene.entity("robot").is_some());
/// ```
#[derive(Debug, Clone)]
pub struct SceneBuilder {
    model: RobotModel,
    body: RobotBody,
    opts: SceneOptions,
    robot: Option<String>,
    humans: Option<HumanSkeletons>,
    forecast: Option<Forecast>,
    safety: Option<SafetyStatus>,
    intent: Option<InteractionIntent>,
    /// When each input last arrived (ns), for the freshness rule.
    arrived: BTreeMap<Input, u64>,
    q: JointValues,
    stats: InputStats,
}

impl Default for SceneBuilder {
    fn default() -> Self {
        Self::new()
    }
}

impl SceneBuilder {
    /// A builder for Echo's TIAGo++ (the embedded URDF) with default options; it follows the
    /// first robot it hears of.
    pub fn new() -> SceneBuilder {
        let model = RobotModel::tiago_dual();
        // The embedded model has every link the capsule model names (echo-robot tests it).
        Self::with_model(model, SceneOptions::default())
            .expect("the embedded TIAGo++ model has the capsule links")
    }

    /// A builder for another description of the robot (it must have the TIAGo++ capsule links).
    pub fn with_model(model: RobotModel, opts: SceneOptions) -> Result<SceneBuilder, SceneError> {
        let body = RobotBody::tiago(&model).map_err(SceneError::Robot)?;
        let q = initial_pose(&model);
        Ok(SceneBuilder {
            model,
            body,
            opts,
            robot: None,
            humans: None,
            forecast: None,
            safety: None,
            intent: None,
            arrived: BTreeMap::new(),
            q,
            stats: InputStats::default(),
        })
    }

    /// Only take messages of robot `id` (by default the first robot heard of).
    pub fn for_robot(mut self, id: &str) -> SceneBuilder {
        self.robot = Some(id.to_string());
        self
    }

    /// The robot model.
    pub fn model(&self) -> &RobotModel {
        &self.model
    }

    /// The options.
    pub fn options(&self) -> &SceneOptions {
        &self.opts
    }

    /// Counters of what was accepted, refused and ignored.
    pub fn stats(&self) -> &InputStats {
        &self.stats
    }

    /// The current joint values (from the latest `robot/state`; the home pose before any).
    pub fn joint_values(&self) -> &JointValues {
        &self.q
    }

    /// Take one bus message (its key and JSON payload), arrived at its own `header.stamp_ns`.
    /// Returns the input it updated, or `None` when the key is not a scene input (ignored) or
    /// the payload was refused (counted, with the reason in [`InputStats::last_error`]). Never
    /// panics.
    pub fn on_message(&mut self, key: &str, payload: &[u8]) -> Option<Input> {
        self.on_message_at(key, payload, None)
    }

    /// [`Self::on_message`] with the time the message arrived (a recording's log time, or the
    /// receiver's clock): freshness is judged by it rather than by the sender's stamp.
    pub fn on_message_at(
        &mut self,
        key: &str,
        payload: &[u8],
        received_ns: Option<u64>,
    ) -> Option<Input> {
        let Some((robot, input)) = Input::from_key(key) else {
            self.stats.ignored += 1;
            return None;
        };
        match &self.robot {
            Some(r) if r != robot => {
                self.stats.ignored += 1;
                return None;
            }
            Some(_) => {}
            None => self.robot = Some(robot.to_string()),
        }
        let stamp = match input {
            Input::Humans => keep(payload, &mut self.humans),
            Input::Forecast => keep(payload, &mut self.forecast),
            Input::SafetyStatus => keep(payload, &mut self.safety),
            Input::Prompt => keep(payload, &mut self.intent),
            Input::RobotState => decode::<JointState>(payload).map(|m| {
                self.apply_state(&m);
                m.header.stamp_ns
            }),
        };
        match stamp {
            Ok(stamp) => {
                self.arrived.insert(input, received_ns.unwrap_or(stamp));
                *self.stats.accepted.entry(input.name()).or_insert(0) += 1;
                Some(input)
            }
            Err(e) => self.reject(input, key, &e),
        }
    }

    fn reject(&mut self, input: Input, key: &str, e: &DecodeError) -> Option<Input> {
        *self.stats.rejected.entry(input.name()).or_insert(0) += 1;
        self.stats.last_error = Some(format!("{key}: {e}"));
        None
    }

    fn apply_state(&mut self, m: &JointState) {
        for (name, q) in m.name.iter().zip(&m.position) {
            if let Some(i) = self.model.joint_index(name) {
                self.q.0[i] = *q;
            }
        }
    }

    /// Whether `input` arrived no longer than `max_age_ns` before `t_ns`.
    fn fresh(&self, input: Input, t_ns: u64) -> bool {
        self.arrived
            .get(&input)
            .is_some_and(|a| t_ns <= a.saturating_add(self.opts.max_age_ns))
    }

    /// Poses of every robot link in the base frame at the current joint values, by link name.
    pub fn link_poses(&self) -> Vec<(&str, Isometry3<f64>)> {
        let poses = self.model.fk_all(&self.q);
        self.model
            .link_names()
            .iter()
            .map(String::as_str)
            .zip(poses)
            .collect()
    }

    /// The head camera's optical frame in the base frame: from the URDF when the model has it,
    /// else [`fixed_camera_pose`].
    pub fn camera_pose(&self) -> Isometry3<f64> {
        self.model
            .fk(&self.q, echo_robot::frames::HEAD_CAMERA_OPTICAL)
            .unwrap_or_else(|_| fixed_camera_pose())
    }

    /// The scene at `t_ns` (ns since the Unix epoch) from the latest inputs.
    pub fn scene(&self, t_ns: u64) -> Scene {
        let mut entities = vec![];
        let robot = self.body.at(&self.model, &self.q);
        entities.push(Entity {
            id: "robot".into(),
            kind: EntityKind::Robot,
            primitives: robot
                .iter()
                .map(|(part, c)| Primitive::Capsule {
                    a: c.a.into(),
                    b: c.b.into(),
                    radius: c.radius,
                    color: style::robot_part(*part),
                })
                .collect(),
        });
        entities.push(self.camera_entity());
        let mut closest: Option<(f64, Vector3<f64>, Vector3<f64>)> = None;
        if let Some(h) = self
            .humans
            .as_ref()
            .filter(|_| self.fresh(Input::Humans, t_ns))
        {
            for track in &h.tracks {
                let partner = h.partner_id == Some(track.track_id);
                let (id, kind, color) = if partner {
                    ("partner".to_string(), EntityKind::Partner, style::PARTNER)
                } else {
                    (
                        format!("person/{}", track.track_id),
                        EntityKind::Person,
                        style::PERSON,
                    )
                };
                entities.push(Entity {
                    id,
                    kind,
                    primitives: skeleton(&track.pose.joints, color),
                });
                let joints: Vec<Vector3<f64>> = track
                    .pose
                    .joints
                    .iter()
                    .map(|p| Vector3::from(*p))
                    .collect();
                for (_, hc) in echo_motion::sensors::body_capsules(&joints) {
                    for (_, rc) in &robot {
                        let (pr, ph) = closest_points(&rc.a, &rc.b, &hc.a, &hc.b);
                        let d = (ph - pr).norm() - rc.radius - hc.radius;
                        if closest.is_none_or(|(best, _, _)| d < best) {
                            let dir = (ph - pr).try_normalize(1e-9).unwrap_or_else(Vector3::x);
                            let (a, b) = if d > 0.0 {
                                (pr + dir * rc.radius, ph - dir * hc.radius)
                            } else {
                                (pr, ph)
                            };
                            closest = Some((d, a, b));
                        }
                    }
                }
            }
        }
        if let Some(f) = self
            .forecast
            .as_ref()
            .filter(|_| self.fresh(Input::Forecast, t_ns))
        {
            entities.extend(self.forecast_entities(f));
        }
        let safety = self
            .safety
            .as_ref()
            .filter(|_| self.fresh(Input::SafetyStatus, t_ns));
        let state_color = safety.map_or(style::UNKNOWN, |s| style::safety(s.state));
        if let Some((d, a, b)) = closest {
            let mid = (a + b) / 2.0 + Vector3::new(0.0, 0.0, 0.08);
            entities.push(Entity {
                id: "separation".into(),
                kind: EntityKind::Separation,
                primitives: vec![
                    Primitive::LineStrip {
                        points: vec![a.into(), b.into()],
                        width: 0.015,
                        color: state_color,
                    },
                    Primitive::Text {
                        position: mid.into(),
                        text: format!("{d:.2} m"),
                        size: 0.08,
                        color: state_color,
                    },
                ],
            });
        }
        let caption = safety_caption(safety, self.safety.is_some());
        let ring: Vec<[f64; 3]> = (0..=32)
            .map(|i| {
                let a = i as f64 / 32.0 * std::f64::consts::TAU;
                [0.42 * a.cos(), 0.42 * a.sin(), 0.01]
            })
            .collect();
        entities.push(Entity {
            id: "safety".into(),
            kind: EntityKind::Safety,
            primitives: vec![
                Primitive::LineStrip {
                    points: ring,
                    width: 0.03,
                    color: state_color,
                },
                Primitive::Text {
                    position: [0.0, 0.0, 1.75],
                    text: caption.clone(),
                    size: 0.1,
                    color: state_color,
                },
            ],
        });
        let mut captions = vec![Caption {
            text: caption,
            color: state_color,
        }];
        if let Some(i) = &self.intent {
            captions.push(Caption {
                text: format!("{:?}: {}", i.interaction, i.text),
                color: style::TEXT,
            });
        }
        Scene {
            time_ns: t_ns,
            frame_id: echo_msgs::frames::BASE_FOOTPRINT.into(),
            captions,
            entities,
        }
    }

    fn camera_entity(&self) -> Entity {
        let pose = self.camera_pose();
        let (h, v) = self.opts.camera_fov;
        let d = self.opts.frustum_depth_m;
        let (x, y) = ((h / 2.0).tan() * d, (v / 2.0).tan() * d);
        let apex: [f64; 3] = pose.translation.vector.into();
        let corner = |sx: f64, sy: f64| -> [f64; 3] {
            (pose * Point3::new(sx * x, sy * y, d)).coords.into()
        };
        let c = [
            corner(-1.0, -1.0),
            corner(1.0, -1.0),
            corner(1.0, 1.0),
            corner(-1.0, 1.0),
        ];
        let strip = |points: Vec<[f64; 3]>| Primitive::LineStrip {
            points,
            width: 0.01,
            color: style::CAMERA,
        };
        Entity {
            id: "camera".into(),
            kind: EntityKind::Camera,
            primitives: vec![
                strip(vec![c[0], c[1], c[2], c[3], c[0]]),
                strip(vec![c[0], apex, c[1]]),
                strip(vec![c[2], apex, c[3]]),
            ],
        }
    }

    fn forecast_entities(&self, f: &Forecast) -> Vec<Entity> {
        let mut out = vec![];
        let n = self.opts.forecast_ghosts;
        let frames = ghost_indices(f.human.len(), n);
        let mut prims = vec![];
        for (i, k) in frames.iter().enumerate() {
            let color = style::FORECAST.with_alpha(ghost_alpha(i, frames.len()));
            prims.extend(bone_lines(&f.human[*k], color));
        }
        if !prims.is_empty() {
            out.push(Entity {
                id: "forecast".into(),
                kind: EntityKind::Forecast,
                primitives: prims,
            });
        }
        if let Some(plan) = &f.robot {
            let idx: Vec<Option<usize>> = plan
                .joint_names
                .iter()
                .map(|n| self.model.joint_index(n))
                .collect();
            let frames = ghost_indices(plan.points.len(), n);
            let mut prims = vec![];
            for (i, k) in frames.iter().enumerate() {
                let mut q = self.q.clone();
                for (j, v) in idx.iter().zip(&plan.points[*k].positions) {
                    if let Some(j) = j {
                        q.0[*j] = *v;
                    }
                }
                let color = style::ROBOT_PLAN.with_alpha(ghost_alpha(i, frames.len()));
                for (part, c) in self.body.at(&self.model, &q) {
                    if part.side().is_some() {
                        prims.push(Primitive::LineStrip {
                            points: vec![c.a.into(), c.b.into()],
                            width: 0.03,
                            color,
                        });
                    }
                }
            }
            if !prims.is_empty() {
                out.push(Entity {
                    id: "robot_plan".into(),
                    kind: EntityKind::RobotPlan,
                    primitives: prims,
                });
            }
        }
        out
    }
}

/// Decode `payload` into `slot`; the message's stamp.
fn keep<M: Message>(payload: &[u8], slot: &mut Option<M>) -> Result<u64, DecodeError> {
    let m = decode::<M>(payload)?;
    let stamp = m.header().stamp_ns;
    *slot = Some(m);
    Ok(stamp)
}

/// The home pose: what the robot is drawn in before its first joint state.
fn initial_pose(model: &RobotModel) -> JointValues {
    let mut q = model.zero();
    for (n, v) in echo_robot::home_pose() {
        if let Some(i) = model.joint_index(&n) {
            q.0[i] = v;
        }
    }
    q
}

/// `n` frame indices out of `len`, evenly spaced, ending at the last.
fn ghost_indices(len: usize, n: usize) -> Vec<usize> {
    if len == 0 || n == 0 {
        return vec![];
    }
    let n = n.min(len);
    let mut v: Vec<usize> = (1..=n).map(|i| (i * len).div_ceil(n) - 1).collect();
    v.dedup();
    v
}

/// Opacity of ghost `i` of `n`: 0.6 for the first, falling to 0.15 for the last.
fn ghost_alpha(i: usize, n: usize) -> f32 {
    if n <= 1 {
        return 0.6;
    }
    0.6 - 0.45 * i as f32 / (n - 1) as f32
}

/// A person's skeleton: a capsule per bone and a ball for the head.
fn skeleton(joints: &[[f64; 3]], color: Rgba) -> Vec<Primitive> {
    let mut p: Vec<Primitive> = bones()
        .filter(|(c, p)| *c < joints.len() && *p < joints.len())
        .map(|(c, p)| Primitive::Capsule {
            a: joints[p],
            b: joints[c],
            radius: 0.03,
            color,
        })
        .collect();
    if let Some(h) = joints.get(echo_motion::skeleton::j::HEAD) {
        p.push(Primitive::Sphere {
            centre: *h,
            radius: 0.1,
            color,
        });
    }
    p
}

/// A skeleton as thin lines (a ghost).
fn bone_lines(joints: &[[f64; 3]], color: Rgba) -> Vec<Primitive> {
    echo_motion::skeleton::CHAINS
        .iter()
        .filter(|chain| chain.iter().all(|j| *j < joints.len()))
        .map(|chain| Primitive::LineStrip {
            points: chain.iter().map(|j| joints[*j]).collect(),
            width: 0.025,
            color,
        })
        .collect()
}

fn safety_caption(s: Option<&SafetyStatus>, ever: bool) -> String {
    let Some(s) = s else {
        return if ever {
            "safety: no recent status".into()
        } else {
            "safety: no status".into()
        };
    };
    let mut t = format!(
        "{} {:.0}%",
        state_word(s.state),
        (s.speed_scale * 100.0).clamp(0.0, 100.0)
    );
    if let Some(d) = s.min_separation_m {
        t.push_str(&format!(", separation {d:.2} m"));
    }
    t
}

/// The state as an upper-case word.
pub fn state_word(s: SafetyState) -> &'static str {
    match s {
        SafetyState::Following => "FOLLOWING",
        SafetyState::Limiting => "LIMITING",
        SafetyState::Stopping => "STOPPING",
        SafetyState::Holding => "HOLDING",
        SafetyState::EStopped => "E-STOPPED",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ghost_frames_are_spread_and_end_at_the_last() {
        assert_eq!(ghost_indices(23, 5), vec![4, 9, 13, 18, 22]);
        assert_eq!(ghost_indices(3, 5), vec![0, 1, 2]);
        assert!(ghost_indices(0, 5).is_empty());
        assert!(ghost_alpha(0, 5) > ghost_alpha(4, 5));
    }

    #[test]
    fn keys_map_to_inputs() {
        assert_eq!(
            Input::from_key("echo/r1/robot/state"),
            Some(("r1", Input::RobotState))
        );
        assert_eq!(Input::from_key("echo/r1/status/safety"), None);
        assert_eq!(Input::from_key("other/r1/humans"), None);
    }

    #[test]
    fn fixed_camera_looks_forward() {
        let p = fixed_camera_pose();
        let ahead = p * Point3::new(0.0, 0.0, 1.0);
        assert!((ahead.x - 1.2).abs() < 1e-9 && ahead.y.abs() < 1e-9);
        let right = p * Point3::new(1.0, 0.0, 0.0);
        assert!(right.y < -0.9, "optical x points to the robot's right");
    }
}
