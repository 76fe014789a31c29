//! The forecaster's per-robot state and batched inference, with no network in sight: the
//! service feeds it decoded messages and publishes what [`ForecastServer::run_batch`] returns.
//! The batch's inputs are assembled in `batch`, the model's output decoded in `response`.

use std::collections::BTreeMap;
use std::time::Instant;

use echo_models::features::{decode, encode_frames, FEATURES};
use echo_models::Backend;
use echo_motion::skeleton::NUM_JOINTS;
use echo_msgs::{
    Forecast, Header, HumanSkeletons, HumanTrack, Interaction, InteractionIntent, JointState,
};
use echo_robot::RobotModel;
use echo_text::SentenceEncoder;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::contact::{ContactConfig, ContactReach};
use crate::gesture::{hand_raised, WaveBack};
use crate::history::{
    Frame, History, HistoryError, Pair, Push, DEFAULT_MAX_AHEAD_MS, DEFAULT_RESYNC_AFTER_MS,
    ROBOT_STATE,
};
use crate::proxy::RobotProxy;

mod batch;
mod response;
use batch::Batch;
use echo_models::robot_agent::{decode_robot, encode_robot, robot_joint_names, ROBOT_FEATURES};
use echo_msgs::{ControlMode, PlanPoint, RobotPlan};

/// Serving settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ServerConfig {
    /// Model rate, Hz (the skeleton stream's rate).
    pub rate_hz: f64,
    /// Longest gap filled by interpolation, frames; longer gaps restart the history.
    pub max_fill_frames: usize,
    /// Prompt used until one arrives on `prompt`.
    pub default_prompt: String,
    /// Another person closer than this to the partner is the second agent; otherwise the robot
    /// is, m.
    pub pair_distance_m: f64,
    /// A person without a `partner_id` is the partner when nearer than this to the robot, m.
    pub partner_range_m: f64,
    /// Skeleton frames stamped further ahead of this host's clock than this are refused
    /// (`from_future`) before they touch any state, ms. The service raises it to the bus's
    /// `--max-clock-skew-ms` when that is larger.
    pub max_future_ms: f64,
    /// When every frame of a robot has been refused as reordered for this long since the last
    /// accepted one (the sender's clock stepped back, or a frame stamped ahead of the stream got
    /// in), its history restarts from the next frame (counted in `resyncs`), ms.
    pub resync_after_ms: f64,
    /// Human–human models: forecast the scene, its mirror image, the scene with the two
    /// people's roles exchanged, and both, and publish the average of the four forecasts mapped
    /// back ([`echo_motion::symmetry::PAIR`]). The forecast then does not depend on which person is called A nor
    /// on left and right, whatever the model learned; four copies share one forward pass.
    /// Meant for prompts that name no role or side (the real-capture descriptions the shipped
    /// forecaster is measured on, docs/RESULTS.md); robot-agent models ignore it (the robot has
    /// no role to exchange).
    pub symmetrize: bool,
}

impl Default for ServerConfig {
    fn default() -> Self {
        ServerConfig {
            rate_hz: 15.0,
            max_fill_frames: 3,
            default_prompt:
                "One person approaches the other and greets them, and the other greets back.".into(),
            pair_distance_m: 2.5,
            partner_range_m: 4.0,
            max_future_ms: DEFAULT_MAX_AHEAD_MS,
            resync_after_ms: DEFAULT_RESYNC_AFTER_MS,
            symmetrize: false,
        }
    }
}

/// Why an input was not used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ServeError {
    /// Out-of-order skeleton frame, or one stamped ahead of this host's clock.
    #[error(transparent)]
    History(#[from] HistoryError),
    /// The model failed on a batch.
    #[error("model: {0}")]
    Model(String),
    /// The prompt could not be embedded.
    #[error("prompt: {0}")]
    Prompt(String),
}

impl ServeError {
    /// Short reason for counters.
    pub fn reason(&self) -> &'static str {
        match self {
            ServeError::History(h) => h.reason(),
            ServeError::Model(_) => "model",
            ServeError::Prompt(_) => "prompt",
        }
    }
}

/// Who the second agent is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Other {
    /// Another tracked person.
    Person(u32),
    /// The robot itself (its kinematic stand-in).
    Robot,
}

struct Slot {
    history: History,
    pair: Option<(u32, Other)>,
    prompt: String,
    /// The announced interaction (contact refinement applies to contact ones).
    interaction: Option<Interaction>,
    /// The arm the last contact refinement used (left = true).
    contact_arm: Option<bool>,
    /// The arm of the wave back under way (left = true): once started it goes on, with the
    /// same arm, as long as the wave interaction lasts.
    wave_arm: Option<bool>,
    proxy: RobotProxy,
    /// The robot's measured joints (robot-agent models).
    robot_q: [f64; ROBOT_STATE],
    /// Stamp of the newest frame not forecast yet.
    pending: Option<u64>,
    filled: u64,
    restarts: u64,
    resyncs: u64,
}

/// Counters across robots.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Counters {
    /// Frames interpolated into gaps.
    pub filled: u64,
    /// Histories restarted after a long gap or a new partner.
    pub restarts: u64,
    /// Histories restarted because every frame had been refused as reordered for
    /// `resync_after_ms`.
    pub resyncs: u64,
    /// Batches run.
    pub batches: u64,
    /// Forecasts produced.
    pub forecasts: u64,
    /// Robot plans refined to reach the partner's hand ([`crate::contact`]).
    pub contact_refined: u64,
    /// Robot plans given a visible wave ([`crate::gesture`]).
    pub wave_refined: u64,
}

/// Per-robot histories and one backend shared by all robots.
pub struct ForecastServer {
    cfg: ServerConfig,
    backend: Box<dyn Backend>,
    text: Option<SentenceEncoder>,
    model_name: String,
    robot_model: RobotModel,
    /// Closes contact interactions' last centimetres (robot-agent models).
    contact: Option<ContactReach>,
    /// Waving back (with `contact`'s arm model; postures solved once).
    wave: Option<WaveBack>,
    /// The robot agent's joint names (feature order), once.
    robot_names: Vec<String>,
    slots: BTreeMap<String, Slot>,
    counters: Counters,
}

fn v3(p: &[f64; 3]) -> Vector3<f64> {
    Vector3::new(p[0], p[1], p[2])
}

fn joints(t: &HumanTrack) -> [Vector3<f64>; NUM_JOINTS] {
    std::array::from_fn(|k| t.pose.joints.get(k).map(v3).unwrap_or_else(Vector3::zeros))
}

impl ForecastServer {
    /// `text` must be given when the backend's model reads text.
    pub fn new(
        cfg: ServerConfig,
        backend: Box<dyn Backend>,
        text: Option<SentenceEncoder>,
        model_name: &str,
        robot_model: RobotModel,
    ) -> anyhow::Result<ForecastServer> {
        let agent_b = backend.config().agent_features[1];
        anyhow::ensure!(
            agent_b == FEATURES || agent_b == ROBOT_FEATURES,
            "agent B has {agent_b} features: the server runs human–human models ({FEATURES}) and \
             HRI models on joint features ({ROBOT_FEATURES}); frozen-retargeter HRI checkpoints \
             are evaluated offline (echoctl eval --hri)"
        );
        let dim = backend.config().text_dim;
        anyhow::ensure!(
            dim == 0 || text.as_ref().is_some_and(|e| e.dim() == dim),
            "the model reads {dim}-d prompt embeddings: a sentence encoder of that size is needed"
        );
        if let Some(e) = &text {
            // Warm the cache with the default prompt: the first tick stays fast.
            e.embed_one(&cfg.default_prompt)
                .map_err(|e| anyhow::anyhow!("embedding the default prompt: {e}"))?;
        }
        let contact = match agent_b == ROBOT_FEATURES {
            true => Some(ContactReach::new(
                robot_model.clone(),
                ContactConfig::default(),
            )?),
            false => None,
        };
        let wave = contact.as_ref().map(WaveBack::new);
        Ok(ForecastServer {
            contact,
            wave,
            cfg,
            backend,
            text,
            model_name: model_name.to_string(),
            robot_model,
            slots: BTreeMap::new(),
            counters: Counters::default(),
            robot_names: robot_joint_names(),
        })
    }

    /// Settings.
    pub fn config(&self) -> &ServerConfig {
        &self.cfg
    }

    /// Backend name.
    pub fn backend_name(&self) -> String {
        self.backend.name()
    }

    /// Counters.
    pub fn counters(&self) -> Counters {
        let mut c = self.counters.clone();
        c.filled = self.slots.values().map(|s| s.filled).sum();
        c.restarts = self.slots.values().map(|s| s.restarts).sum();
        c.resyncs = self.slots.values().map(|s| s.resyncs).sum();
        c
    }

    /// Robots with a history.
    pub fn robots(&self) -> Vec<String> {
        self.slots.keys().cloned().collect()
    }

    /// The current pairing of `robot`: (partner track, second agent).
    pub fn pairing(&self, robot: &str) -> Option<(u32, Other)> {
        self.slots.get(robot).and_then(|s| s.pair)
    }

    fn slot(&mut self, robot: &str) -> &mut Slot {
        let obs = self.backend.config().obs;
        let (rate, fill, prompt) = (
            self.cfg.rate_hz,
            self.cfg.max_fill_frames,
            self.cfg.default_prompt.clone(),
        );
        let (ahead, resync) = (self.cfg.max_future_ms, self.cfg.resync_after_ms);
        let (model, names) = (&self.robot_model, &self.robot_names);
        self.slots.entry(robot.to_string()).or_insert_with(|| Slot {
            history: History::new(rate, 2 * obs, fill).with_guards(ahead, resync),
            pair: None,
            prompt,
            interaction: None,
            contact_arm: None,
            wave_arm: None,
            proxy: RobotProxy::new(model.clone()),
            robot_q: {
                let home = echo_robot::home_pose();
                std::array::from_fn(|k| {
                    home.iter()
                        .find(|(n, _)| *n == names[k])
                        .map(|(_, v)| *v)
                        .unwrap_or(0.0)
                })
            },
            pending: None,
            filled: 0,
            restarts: 0,
            resyncs: 0,
        })
    }

    /// A robot's measured joints (for its stand-in as the second agent).
    pub fn on_joint_state(&mut self, robot: &str, js: &JointState) {
        self.slot(robot);
        let Some(slot) = self.slots.get_mut(robot) else {
            return;
        };
        slot.proxy.update(js);
        for (k, n) in self.robot_names.iter().enumerate() {
            if let Some(v) = js.position_of(n).filter(|v| v.is_finite()) {
                slot.robot_q[k] = v;
            }
        }
    }

    /// Whether the model's second agent is the robot itself (an HRI model): its forecasts carry
    /// a robot plan.
    pub fn robot_agent(&self) -> bool {
        self.backend.config().agent_features[1] == ROBOT_FEATURES
    }

    /// A new prompt for `robot`; it is embedded now so the next tick does not wait for it.
    pub fn on_prompt(&mut self, robot: &str, intent: &InteractionIntent) -> Result<(), ServeError> {
        let text = if intent.text.trim().is_empty() {
            self.cfg.default_prompt.clone()
        } else {
            intent.text.clone()
        };
        if let Some(e) = &self.text {
            e.embed_one(&text)
                .map_err(|e| ServeError::Prompt(e.to_string()))?;
        }
        let slot = self.slot(robot);
        slot.prompt = text;
        slot.interaction = Some(intent.interaction);
        Ok(())
    }

    /// Choose the partner and the second agent of a skeleton frame.
    fn choose(&self, msg: &HumanSkeletons) -> Option<(u32, Other)> {
        let partner = match msg.partner_id {
            Some(id) => msg.tracks.iter().find(|t| t.track_id == id)?,
            None => msg
                .tracks
                .iter()
                .filter(|t| v3(&t.pose.root_position).xy().norm() < self.cfg.partner_range_m)
                .min_by(|a, b| {
                    let da = v3(&a.pose.root_position).xy().norm();
                    let db = v3(&b.pose.root_position).xy().norm();
                    da.total_cmp(&db)
                })?,
        };
        if self.robot_agent() {
            return Some((partner.track_id, Other::Robot));
        }
        let p = v3(&partner.pose.root_position);
        let other = msg
            .tracks
            .iter()
            .filter(|t| t.track_id != partner.track_id)
            .map(|t| (t.track_id, (v3(&t.pose.root_position) - p).xy().norm()))
            .filter(|(_, d)| *d < self.cfg.pair_distance_m)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(id, _)| Other::Person(id))
            .unwrap_or(Other::Robot);
        Some((partner.track_id, other))
    }

    /// A skeleton frame of `robot` (validated by the bus), received now. Returns what happened
    /// to the history, or `None` when nobody is there to forecast.
    pub fn on_skeletons(
        &mut self,
        robot: &str,
        msg: &HumanSkeletons,
    ) -> Result<Option<Push>, ServeError> {
        self.on_skeletons_at(robot, msg, echo_msgs::now_ns(), Instant::now())
    }

    /// [`on_skeletons`](Self::on_skeletons) received at `now_ns` on this host's wall clock and
    /// `now` on its monotonic clock. A frame stamped further than `max_future_ms` ahead of
    /// `now_ns` is refused before it touches anything (pairing, history, pending forecast).
    pub fn on_skeletons_at(
        &mut self,
        robot: &str,
        msg: &HumanSkeletons,
        now_ns: u64,
        now: Instant,
    ) -> Result<Option<Push>, ServeError> {
        let obs = self.backend.config().obs;
        let choice = self.choose(msg);
        let slot = self.slot(robot);
        slot.history.check_ahead(msg.header.stamp_ns, now_ns)?;
        let Some((pid, other)) = choice else {
            slot.history.clear();
            slot.pair = None;
            slot.pending = None;
            return Ok(None);
        };
        if slot.pair != Some((pid, other)) {
            if slot.pair.is_some() {
                slot.restarts += 1;
            }
            slot.history.clear();
            slot.pair = Some((pid, other));
        }
        let track = |id: u32| msg.tracks.iter().find(|t| t.track_id == id);
        let a = joints(track(pid).expect("chosen from these tracks"));
        let b = match other {
            Other::Person(id) => joints(track(id).expect("chosen from these tracks")),
            Other::Robot => slot.proxy.joints(),
        };
        let pair: Pair = [a, b];
        let frame = Frame {
            pair,
            robot: slot.robot_q,
        };
        let push = slot
            .history
            .push_at(msg.header.stamp_ns, frame, now_ns, now)?;
        match push {
            Push::Filled { filled } => slot.filled += filled as u64,
            Push::Restarted { .. } => slot.restarts += 1,
            Push::Resynced { .. } => slot.resyncs += 1,
            Push::Appended => {}
        }
        if slot.history.len() >= obs {
            slot.pending = Some(msg.header.stamp_ns);
        }
        Ok(Some(push))
    }

    /// Robots waiting for a forecast.
    pub fn pending(&self) -> usize {
        self.slots.values().filter(|s| s.pending.is_some()).count()
    }

    /// One forward pass for every robot with a new frame; a forecast per robot.
    pub fn run_batch(&mut self) -> Vec<(String, Result<Forecast, ServeError>)> {
        let cfg = self.backend.config().clone();
        let robot_agent = self.robot_agent();
        let [fa, fb] = cfg.agent_features;
        // Copies of each scene in the batch: the four symmetries, or the scene alone.
        let group = echo_motion::symmetry::PAIR;
        let copies = match self.cfg.symmetrize && !robot_agent {
            true => group.len(),
            false => 1,
        };
        let Batch {
            scenes: robots,
            canon,
            obs,
            prompts,
            measured,
        } = self.assemble(&cfg, &group[..copies], robot_agent);
        if robots.is_empty() {
            return vec![];
        }
        let b = robots.len() * copies;
        let text: Vec<f32> = match (&self.text, cfg.text_dim > 0) {
            (Some(e), true) => {
                // Every copy of a scene reads its prompt unchanged.
                let refs: Vec<&str> = prompts
                    .iter()
                    .flat_map(|s| std::iter::repeat_n(s.as_str(), copies))
                    .collect();
                match e.embed(&refs) {
                    Ok(v) => v.concat(),
                    Err(err) => {
                        return robots
                            .into_iter()
                            .map(|s| (s.robot, Err(ServeError::Prompt(err.to_string()))))
                            .collect()
                    }
                }
            }
            _ => vec![],
        };
        let started = Instant::now();
        let out = self.backend.predict(b, &obs, &text);
        let ms = started.elapsed().as_secs_f64() * 1e3;
        self.counters.batches += 1;
        let out = match out {
            Ok(v) if v.len() == b * cfg.pred * (fa + fb) && v.iter().all(|x| x.is_finite()) => v,
            Ok(v) => {
                let msg = format!(
                    "{} values (finite: {})",
                    v.len(),
                    v.iter().all(|x| x.is_finite())
                );
                return robots
                    .into_iter()
                    .map(|s| (s.robot, Err(ServeError::Model(msg.clone()))))
                    .collect();
            }
            Err(e) => {
                return robots
                    .into_iter()
                    .map(|s| (s.robot, Err(ServeError::Model(e.to_string()))))
                    .collect()
            }
        };
        let mut res = Vec::with_capacity(robots.len());
        let names = &self.robot_names;
        for (
            i,
            batch::Scene {
                robot,
                stamp,
                partner,
                interaction,
                arm,
            },
        ) in robots.into_iter().enumerate()
        {
            let c = &canon[i * copies];
            let human = response::people(&cfg, &out, &canon, &group[..copies], i);
            let mut header = Header::new(&robot, "", "base_footprint");
            header.stamp_ns = stamp;
            // A robot-agent model forecasts the robot too: its plan starts at the measured
            // joints and follows the forecast frames at the model rate.
            let mut plan = robot_agent.then(|| {
                let mut h = Header::new(&robot, "forecaster", "odom");
                h.stamp_ns = stamp;
                response::plan(&cfg, &out, c, i, &measured[i], h, names, self.cfg.rate_hz)
            });
            if let (Some(p), Some(reach), Some(wave), Some(kind)) =
                (&mut plan, &self.contact, &self.wave, interaction)
            {
                // A wave back, once started (the partner's hand or the learned plan raised),
                // goes on with the same arm while the interaction is a wave: the regressed plan
                // dips now and then, and a wave that stops with it is no wave.
                let under_way = self.slots.get(&robot).and_then(|s| s.wave_arm);
                let partner_raised = human.first().is_some_and(|f| hand_raised(f));
                let waved = wave.refine(
                    reach,
                    p,
                    stamp as f64 / 1e9,
                    kind,
                    partner_raised || under_way.is_some(),
                    under_way,
                );
                if let Some(w) = &waved {
                    tracing::debug!(?w, "wave back");
                    self.counters.wave_refined += 1;
                }
                if let Some(slot) = self.slots.get_mut(&robot) {
                    slot.wave_arm = waved.map(|w| w.left_arm);
                }
                let done = reach.refine(p, &human, kind, arm);
                if let Some(d) = &done {
                    tracing::debug!(?d, "contact refinement");
                    self.counters.contact_refined += 1;
                }
                if let Some(slot) = self.slots.get_mut(&robot) {
                    slot.contact_arm = done.map(|d| d.left_arm).or(slot.contact_arm);
                }
            }
            self.counters.forecasts += 1;
            res.push((
                robot,
                Ok(Forecast {
                    header,
                    model: self.model_name.clone(),
                    rate_hz: self.cfg.rate_hz,
                    partner_id: partner,
                    human,
                    robot: plan,
                    inference_ms: ms,
                }),
            ));
        }
        res
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use echo_models::model::ForecasterConfig;

    /// Zero velocity, with a NaN in its output when asked.
    struct Broken(echo_models::ZeroVelocityBackend);

    impl Backend for Broken {
        fn name(&self) -> String {
            "broken".into()
        }
        fn config(&self) -> &ForecasterConfig {
            self.0.config()
        }
        fn predict(&mut self, b: usize, obs: &[f32], text: &[f32]) -> anyhow::Result<Vec<f32>> {
            let mut v = self.0.predict(b, obs, text)?;
            v[0] = f32::NAN;
            Ok(v)
        }
    }

    fn server(nan: bool) -> ForecastServer {
        let zv = echo_models::ZeroVelocityBackend::new(ForecasterConfig::default());
        let backend: Box<dyn Backend> = if nan {
            Box::new(Broken(zv))
        } else {
            Box::new(zv)
        };
        ForecastServer::new(
            ServerConfig::default(),
            backend,
            None,
            "zero-velocity",
            RobotModel::tiago_dual(),
        )
        .unwrap()
    }

    fn person(id: u32, x: f64, y: f64) -> HumanTrack {
        let clip = echo_motion::synth::generate(&echo_motion::synth::Split::Test.clip(1));
        let j = clip.joints(0, 0);
        let root = j[0];
        let joints: Vec<[f64; 3]> = j
            .iter()
            .map(|p| [p.x - root.x + x, p.y - root.y + y, p.z])
            .collect();
        HumanTrack::from_joints(id, joints)
    }

    fn frame(robot: &str, k: u64, tracks: Vec<HumanTrack>, partner: Option<u32>) -> HumanSkeletons {
        let mut header = Header::new(robot, "test", "base_footprint");
        header.stamp_ns = 1_000_000_000 + k * 66_666_667;
        HumanSkeletons {
            header,
            rate_hz: 15.0,
            tracks,
            partner_id: partner,
        }
    }

    /// Zero velocity that also moves person A sideways (towards +y in A's own frame): a model
    /// that is not mirror-symmetric.
    struct Lopsided(echo_models::ZeroVelocityBackend);

    impl Backend for Lopsided {
        fn name(&self) -> String {
            "lopsided".into()
        }
        fn config(&self) -> &ForecasterConfig {
            self.0.config()
        }
        fn predict(&mut self, b: usize, obs: &[f32], text: &[f32]) -> anyhow::Result<Vec<f32>> {
            let mut v = self.0.predict(b, obs, text)?;
            let cfg = self.0.config();
            let per = cfg.pred * (cfg.agent_features[0] + cfg.agent_features[1]);
            for n in 0..b {
                for k in 0..cfg.pred {
                    // Feature 67: the root's y in the window frame.
                    v[n * per + k * cfg.agent_features[0] + 67] += 0.02 * (k + 1) as f32;
                }
            }
            Ok(v)
        }
    }

    #[test]
    fn a_symmetrized_forecast_of_a_mirrored_scene_is_the_mirrored_forecast() {
        let scene = vec![person(1, 1.5, 0.3), person(2, 2.3, -0.4)];
        let mirrored: Vec<HumanTrack> = scene
            .iter()
            .map(|t| {
                let j: [Vector3<f64>; NUM_JOINTS] = joints(t);
                let m = echo_motion::skeleton::mirror(&j);
                HumanTrack::from_joints(t.track_id, m.iter().map(|p| [p.x, p.y, p.z]).collect())
            })
            .collect();
        let forecasts = |symmetrize: bool| {
            let mut s = ForecastServer::new(
                ServerConfig {
                    symmetrize,
                    ..ServerConfig::default()
                },
                Box::new(Lopsided(echo_models::ZeroVelocityBackend::new(
                    ForecasterConfig::default(),
                ))),
                None,
                "lopsided",
                RobotModel::tiago_dual(),
            )
            .unwrap();
            for k in 0..8 {
                s.on_skeletons("r", &frame("r", k, scene.clone(), Some(1)))
                    .unwrap();
                s.on_skeletons("m", &frame("m", k, mirrored.clone(), Some(1)))
                    .unwrap();
            }
            assert_eq!(s.pairing("r"), Some((1, Other::Person(2))));
            let out: BTreeMap<String, Forecast> = s
                .run_batch()
                .into_iter()
                .map(|(r, f)| (r, f.unwrap()))
                .collect();
            assert_eq!(s.counters().batches, 1, "all copies in one forward pass");
            (out["r"].human.clone(), out["m"].human.clone())
        };
        // Largest distance between the mirrored scene's forecast and the forecast mirrored.
        type Forecasts = Vec<Vec<[f64; 3]>>;
        let gap = |(r, m): (Forecasts, Forecasts)| {
            let mut worst = 0.0f64;
            for (fr, fm) in r.iter().zip(&m) {
                let a: [Vector3<f64>; NUM_JOINTS] = std::array::from_fn(|j| v3(&fr[j]));
                for (p, q) in echo_motion::skeleton::mirror(&a).iter().zip(fm) {
                    worst = worst.max((p - v3(q)).norm());
                }
            }
            worst
        };
        let plain = gap(forecasts(false));
        assert!(plain > 0.1, "the model itself is lopsided ({plain:.3} m)");
        let sym = gap(forecasts(true));
        assert!(sym < 1e-5, "symmetrized: {sym:.2e} m");
    }

    #[test]
    fn robots_that_advance_together_share_one_forward_pass() {
        let mut s = server(false);
        for k in 0..8 {
            for r in ["r1", "r2", "r3"] {
                s.on_skeletons(r, &frame(r, k, vec![person(7, 1.5, 0.0)], None))
                    .unwrap();
            }
            if k < 7 {
                assert!(s.run_batch().is_empty(), "not enough history yet");
            }
        }
        assert_eq!(s.pending(), 3);
        let out = s.run_batch();
        assert_eq!(out.len(), 3);
        assert_eq!(s.counters().batches, 1, "one forward pass for three robots");
        for (r, f) in out {
            let f = f.unwrap();
            assert_eq!(f.header.robot_id, r);
            assert_eq!(
                f.header.stamp_ns,
                frame(&r, 7, vec![], None).header.stamp_ns
            );
            assert_eq!(f.human.len(), 23);
            assert_eq!(f.partner_id, 7);
            // Zero velocity repeats the last frame: decoding gives back the partner's joints.
            let last = person(7, 1.5, 0.0);
            for (p, q) in f.human[22].iter().zip(&last.pose.joints) {
                for d in 0..3 {
                    assert!((p[d] - q[d]).abs() < 1e-4, "{p:?} vs {q:?}");
                }
            }
        }
        assert_eq!(s.pending(), 0, "each frame is forecast once");
    }

    #[test]
    fn pairs_the_partner_with_a_nearby_person_or_else_the_robot() {
        let mut s = server(false);
        s.on_skeletons("r", &frame("r", 0, vec![person(1, 1.5, 0.0)], None))
            .unwrap();
        assert_eq!(s.pairing("r"), Some((1, Other::Robot)));
        let two = vec![
            person(1, 1.5, 0.0),
            person(2, 2.5, 0.5),
            person(3, 9.0, 0.0),
        ];
        s.on_skeletons("r", &frame("r", 1, two.clone(), Some(2)))
            .unwrap();
        assert_eq!(s.pairing("r"), Some((2, Other::Person(1))));
        // Nobody in range: the history is dropped, nothing is pending.
        s.on_skeletons("r", &frame("r", 2, vec![person(3, 9.0, 0.0)], None))
            .unwrap();
        assert_eq!(s.pairing("r"), None);
        assert_eq!(s.pending(), 0);
    }

    #[test]
    fn reordered_frames_are_refused_and_gaps_are_filled() {
        let mut s = server(false);
        for k in [0, 1, 2, 5, 6] {
            s.on_skeletons("r", &frame("r", k, vec![person(1, 1.5, 0.0)], None))
                .unwrap();
        }
        let e = s
            .on_skeletons("r", &frame("r", 4, vec![person(1, 1.5, 0.0)], None))
            .unwrap_err();
        assert_eq!(e.reason(), "reordered");
        // 0,1,2,(3,4 filled),5,6 = 7 frames; one more makes the 8 the model observes.
        assert_eq!(s.pending(), 0);
        s.on_skeletons("r", &frame("r", 7, vec![person(1, 1.5, 0.0)], None))
            .unwrap();
        assert_eq!(s.pending(), 1);
        assert_eq!(s.run_batch().len(), 1);
        assert_eq!(s.counters().filled, 2);
    }

    #[test]
    fn a_frame_stamped_at_the_end_of_time_does_not_stop_forecasts() {
        let mut s = server(false);
        let me = vec![person(1, 1.5, 0.0)];
        for k in 0..8 {
            s.on_skeletons("r", &frame("r", k, me.clone(), None))
                .unwrap();
        }
        assert_eq!(s.run_batch().len(), 1);
        // Another source, stamped 2^64 − 1 ns, with someone else in view.
        let mut forged = frame("r", 8, vec![person(9, 0.8, 0.3)], Some(9));
        forged.header.source = "forger".into();
        forged.header.stamp_ns = u64::MAX;
        let refused = s.on_skeletons("r", &forged);
        // The real stream goes on and every frame is forecast.
        for k in 8..20 {
            s.on_skeletons("r", &frame("r", k, me.clone(), None))
                .unwrap();
            let out = s.run_batch();
            assert_eq!(out.len(), 1, "frame {k}");
            assert_eq!(
                out[0].1.as_ref().unwrap().header.stamp_ns,
                frame("r", k, vec![], None).header.stamp_ns
            );
        }
        // The forged frame was refused before it touched anything.
        assert_eq!(refused.unwrap_err().reason(), "from_future");
        assert_eq!(s.pairing("r"), Some((1, Other::Robot)));
        assert_eq!(s.counters().restarts, 0);
    }

    #[test]
    fn a_robot_refused_as_reordered_for_too_long_resyncs() {
        let mut s = server(false);
        let me = vec![person(1, 1.5, 0.0)];
        let now_ns = echo_msgs::now_ns();
        let t0 = Instant::now();
        let at = |k: u64| t0 + std::time::Duration::from_nanos(k * 66_666_667);
        for k in 0..8 {
            s.on_skeletons_at("r", &frame("r", k, me.clone(), None), now_ns, at(k))
                .unwrap();
        }
        assert_eq!(s.run_batch().len(), 1);
        // A frame stamped a minute ahead of the stream, though not of this host's clock (the
        // sender's clock stepped, or a forger), gets in: a long gap restarts the history.
        let mut ahead = frame("r", 8 + 900, me.clone(), None);
        ahead.header.source = "forger".into();
        assert!(matches!(
            s.on_skeletons_at("r", &ahead, now_ns, at(8)),
            Ok(Some(Push::Restarted { .. }))
        ));
        // The real stream is refused as reordered until no frame has been accepted for
        // `resync_after_ms` (500 ms: 8 frames at 15 Hz); then it restarts from the real stream
        // and forecasts resume once the model's 8 frames are held again.
        let mut forecasts = vec![];
        for k in 9..30 {
            let r = s.on_skeletons_at("r", &frame("r", k, me.clone(), None), now_ns, at(k));
            match k {
                9..=15 => assert_eq!(r.unwrap_err().reason(), "reordered", "frame {k}"),
                16 => assert!(matches!(r, Ok(Some(Push::Resynced { stalled_ms: 533 })))),
                _ => assert_eq!(r, Ok(Some(Push::Appended)), "frame {k}"),
            }
            if !s.run_batch().is_empty() {
                forecasts.push(k);
            }
        }
        assert_eq!(forecasts, (23..30).collect::<Vec<_>>());
        assert_eq!(s.counters().resyncs, 1);
    }

    #[test]
    fn a_model_that_returns_garbage_publishes_nothing() {
        let mut s = server(true);
        for k in 0..8 {
            s.on_skeletons("r", &frame("r", k, vec![person(1, 1.5, 0.0)], None))
                .unwrap();
        }
        let out = s.run_batch();
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].1.as_ref().unwrap_err().reason(), "model");
    }

    #[test]
    fn models_with_other_agent_features_are_refused() {
        let cfg = ForecasterConfig {
            pred: 15,
            agent_features: [FEATURES, 42],
            ..Default::default()
        };
        let e = ForecastServer::new(
            ServerConfig::default(),
            Box::new(echo_models::ZeroVelocityBackend::new(cfg)),
            None,
            "frozen",
            RobotModel::tiago_dual(),
        )
        .err()
        .expect("refused");
        assert!(e.to_string().contains("42 features"), "{e}");
    }

    #[test]
    fn a_robot_agent_model_sends_a_plan_from_the_measured_state() {
        let cfg = ForecasterConfig {
            pred: 15,
            agent_features: [FEATURES, ROBOT_FEATURES],
            ..Default::default()
        };
        let mut s = ForecastServer::new(
            ServerConfig::default(),
            Box::new(echo_models::ZeroVelocityBackend::new(cfg)),
            None,
            "hri",
            RobotModel::tiago_dual(),
        )
        .unwrap();
        assert!(s.robot_agent());
        let names = robot_joint_names();
        let js = JointState {
            header: Header::new("r", "t", "base_footprint"),
            name: names.clone(),
            position: (0..names.len()).map(|k| 0.01 * k as f64).collect(),
            velocity: vec![],
            base: None,
        };
        s.on_joint_state("r", &js);
        // Two people in view: the second agent is still the robot.
        for k in 0..8 {
            s.on_skeletons(
                "r",
                &frame(
                    "r",
                    k,
                    vec![person(1, 1.5, 0.0), person(2, 1.8, 0.4)],
                    Some(1),
                ),
            )
            .unwrap();
        }
        assert_eq!(s.pairing("r"), Some((1, Other::Robot)));
        let out = s.run_batch();
        let f = out[0].1.as_ref().unwrap();
        assert_eq!(f.human.len(), 15);
        let plan = f.robot.as_ref().expect("a plan");
        assert_eq!(plan.points.len(), 16);
        assert_eq!(plan.joint_names, names);
        for p in &plan.points {
            for (a, b) in p.positions.iter().zip(&js.position) {
                assert!(
                    (a - b).abs() < 1e-5,
                    "zero velocity holds the measured pose"
                );
            }
        }
        assert!(plan.points.windows(2).all(|w| w[1].t > w[0].t));
    }
}
