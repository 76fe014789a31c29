//! The bridge: frame checks, lifting, camera transform, tracking, and model-rate output.

use std::collections::{HashMap, VecDeque};

use echo_motion::rotation::quat_to_xyzw;
use echo_motion::skeleton::{self, NUM_JOINTS};
use echo_msgs::{
    frames, Header, HumanPose, HumanSkeletons, HumanTrack, JointState, KeypointFormat,
    KeypointFrame, Keypoints,
};
use echo_robot::RobotModel;
use nalgebra::{Point3, Vector3};

use crate::camera::{CameraPoseError, JointStateHistory};
use crate::config::BridgeConfig;
use crate::joint_map::{JointMap, JointMapError, ResolvedMap};
use crate::lift::{back_project, sample_depth};
use crate::tracker::{Detection, DetectionError, Observation, Tracker};

/// Why a keypoint frame (or one person in it) was rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BridgeError {
    /// Captured too long ago.
    #[error("frame is {age_ms:.0} ms old (limit {limit_ms:.0} ms)")]
    Stale {
        /// Age at arrival.
        age_ms: f64,
        /// Limit.
        limit_ms: f64,
    },
    /// Stamped in the future beyond the skew allowance.
    #[error("frame is stamped {ahead_ms:.0} ms in the future")]
    FromFuture {
        /// How far ahead.
        ahead_ms: f64,
    },
    /// Not after the last processed frame.
    #[error("frame stamp {stamp_ns} is not after the last processed {last_ns}")]
    OutOfOrder {
        /// This frame's stamp.
        stamp_ns: u64,
        /// Last processed stamp.
        last_ns: u64,
    },
    /// Camera frame not in the robot model.
    #[error("camera frame '{0}' is not in the robot model")]
    UnknownFrame(String),
    /// No usable joint state to place the camera.
    #[error(transparent)]
    CameraPose(#[from] CameraPoseError),
    /// The configured joint map does not fit the keypoints sent.
    #[error(transparent)]
    JointMap(#[from] JointMapError),
    /// One person was unusable.
    #[error("person {index}: {error}")]
    Person {
        /// Index in the frame.
        index: usize,
        /// Why.
        error: DetectionError,
    },
}

impl BridgeError {
    /// Short label for counters.
    pub fn reason(&self) -> &'static str {
        match self {
            BridgeError::Stale { .. } => "stale",
            BridgeError::FromFuture { .. } => "from_future",
            BridgeError::OutOfOrder { .. } => "out_of_order",
            BridgeError::UnknownFrame(_) => "unknown_frame",
            BridgeError::CameraPose(CameraPoseError::NoState) => "no_joint_state",
            BridgeError::CameraPose(CameraPoseError::TooFar { .. }) => "joint_state_gap",
            BridgeError::CameraPose(CameraPoseError::UnknownFrame(_)) => "unknown_frame",
            BridgeError::JointMap(_) => "joint_map",
            BridgeError::Person { error, .. } => error.reason(),
        }
    }
}

/// What one accepted frame produced.
#[derive(Debug, Clone, Default)]
pub struct FrameOutput {
    /// Skeleton messages for every model-rate grid point this frame completed (often one,
    /// sometimes zero or several).
    pub skeletons: Vec<HumanSkeletons>,
    /// People in the frame that were not used, with reasons.
    pub rejected_people: Vec<BridgeError>,
}

/// The perception bridge state machine.
#[derive(Debug)]
pub struct PerceptionBridge {
    cfg: BridgeConfig,
    model: RobotModel,
    histories: HashMap<String, JointStateHistory>,
    joint_state_seen: VecDeque<JointState>,
    tracker: Tracker,
    last_stamp_ns: Option<u64>,
    next_grid_ns: Option<u64>,
    maps: HashMap<(KeypointFormat, Option<Vec<String>>), ResolvedMap>,
    prev_output: HashMap<u32, (u64, Vector3<f64>)>,
}

impl PerceptionBridge {
    /// A bridge for `model` with `cfg`.
    pub fn new(cfg: BridgeConfig, model: RobotModel) -> Self {
        PerceptionBridge {
            cfg,
            model,
            histories: HashMap::new(),
            joint_state_seen: VecDeque::new(),
            tracker: Tracker::new(),
            last_stamp_ns: None,
            next_grid_ns: None,
            maps: HashMap::new(),
            prev_output: HashMap::new(),
        }
    }

    /// Configuration in use.
    pub fn config(&self) -> &BridgeConfig {
        &self.cfg
    }

    /// Record a robot joint state (for the camera pose at capture time).
    pub fn on_joint_state(&mut self, js: &JointState) {
        for h in self.histories.values_mut() {
            h.push(js);
        }
        // Kept briefly so a camera frame seen for the first time gets the recent history too.
        self.joint_state_seen.push_back(js.clone());
        if self.joint_state_seen.len() > 200 {
            self.joint_state_seen.pop_front();
        }
    }

    /// Create the joint-state history of a camera frame seen for the first time.
    fn ensure_history(&mut self, frame: &str) -> Result<(), BridgeError> {
        if !self.histories.contains_key(frame) {
            let mut h = JointStateHistory::new(&self.model, frame)
                .map_err(|_| BridgeError::UnknownFrame(frame.to_string()))?;
            for js in &self.joint_state_seen {
                h.push(js);
            }
            self.histories.insert(frame.to_string(), h);
        }
        Ok(())
    }

    fn resolved_map(&mut self, frame: &KeypointFrame) -> Result<ResolvedMap, BridgeError> {
        let key = (frame.format, frame.joint_names.clone());
        if let Some(m) = self.maps.get(&key) {
            return Ok(m.clone());
        }
        let name = serde_json::to_value(frame.format)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default();
        let map = self
            .cfg
            .joint_maps
            .get(&name)
            .cloned()
            .unwrap_or_else(|| JointMap::builtin(frame.format));
        let sent: Vec<&str> = match &frame.joint_names {
            Some(n) => n.iter().map(String::as_str).collect(),
            None => frame.format.joint_names().to_vec(),
        };
        let resolved = map.resolve(frame.format, &sent)?;
        self.maps.insert(key, resolved.clone());
        Ok(resolved)
    }

    /// Process one keypoint frame that arrived when the receiver's wall clock read `now_ns`.
    pub fn on_keypoints(
        &mut self,
        frame: &KeypointFrame,
        now_ns: u64,
    ) -> Result<FrameOutput, BridgeError> {
        let stamp = frame.header.stamp_ns;
        let age_ms = (now_ns as f64 - stamp as f64) / 1e6;
        if age_ms > self.cfg.max_age_ms {
            return Err(BridgeError::Stale {
                age_ms,
                limit_ms: self.cfg.max_age_ms,
            });
        }
        if -age_ms > self.cfg.max_future_ms {
            return Err(BridgeError::FromFuture { ahead_ms: -age_ms });
        }
        if let Some(last) = self.last_stamp_ns {
            if stamp <= last {
                return Err(BridgeError::OutOfOrder {
                    stamp_ns: stamp,
                    last_ns: last,
                });
            }
        }
        let map = self.resolved_map(frame)?;
        let max_gap = self.cfg.max_state_gap_ms;
        let cam_frame = frame.header.frame_id.clone();
        self.ensure_history(&cam_frame)?;
        let cam =
            self.histories[&cam_frame].camera_pose(&self.model, &cam_frame, stamp, max_gap)?;
        self.last_stamp_ns = Some(stamp);

        // Lift every person to 3D in the camera frame, map to SMPL-22, move to base_footprint.
        let mut detections = Vec::with_capacity(frame.people.len());
        let mut out = FrameOutput::default();
        for person in &frame.people {
            let n = person.confidence.len();
            let mut pts = vec![[0.0; 3]; n];
            let mut conf = person.confidence.clone();
            match &person.keypoints {
                Keypoints::Points3d { xyz } => pts.copy_from_slice(xyz),
                Keypoints::PixelsDepth { uv, depth_m } => {
                    // Validation guarantees intrinsics and a depth source.
                    let Some(c) = frame.camera.as_ref() else {
                        continue;
                    };
                    for i in 0..n {
                        let z = match (depth_m, &frame.depth_image) {
                            (Some(d), _) => Some(d[i]),
                            (None, Some(img)) => sample_depth(img, uv[i][0], uv[i][1]),
                            (None, None) => None,
                        };
                        match z {
                            Some(z) if z > 0.1 && z < 20.0 => {
                                pts[i] =
                                    back_project(c, uv[i][0], uv[i][1], z + self.cfg.depth_bias_m)
                            }
                            _ => conf[i] = 0.0,
                        }
                    }
                }
            }
            let (smpl, c22) = map.apply(&pts, &conf);
            let joints = smpl.map(|p| (cam * Point3::from(p)).coords);
            detections.push(Detection {
                detection_id: person.detection_id,
                joints,
                confidence: c22,
            });
        }
        for (index, error) in self.tracker.update(&self.cfg, stamp, detections) {
            out.rejected_people
                .push(BridgeError::Person { index, error });
        }

        // Emit every model-rate grid point up to this frame's stamp. The grid is anchored at the
        // first frame, so an input at the model rate maps one to one without added delay; a grid
        // point up to a quarter period after the newest frame is extrapolated from the last two.
        let period = (1e9 / self.cfg.rate_hz) as u64;
        let mut g = *self.next_grid_ns.get_or_insert(stamp);
        if g + (self.cfg.max_interp_gap_s * 1e9) as u64 <= stamp {
            // A long input gap: skip the grid points nobody can fill, keep the phase.
            g += (stamp - g) / period * period;
        }
        while g <= stamp + period / 4 {
            out.skeletons.push(self.output_at(g, &frame.header));
            g += period;
        }
        self.next_grid_ns = Some(g);
        Ok(out)
    }

    /// The skeletons message for grid time `g`.
    fn output_at(&mut self, g: u64, input: &Header) -> HumanSkeletons {
        let max_gap = (self.cfg.max_interp_gap_s * 1e9) as u64;
        let hold = (self.cfg.hold_s * 1e9) as u64;
        let mut tracks = vec![];
        let mut candidates = vec![];
        let mut ids = vec![];
        for t in self.tracker.tracks().iter().filter(|t| t.confirmed) {
            let lead = (1e9 / self.cfg.rate_hz) as u64 / 4;
            let obs = match t.history.as_slice() {
                [.., a, b]
                    if a.stamp_ns <= g
                        && g <= b.stamp_ns + lead
                        && b.stamp_ns - a.stamp_ns <= max_gap =>
                {
                    interpolate(a, b, g)
                }
                [.., b] if b.stamp_ns <= g && g - b.stamp_ns <= hold => b.clone(),
                [.., b] if g < b.stamp_ns && t.history.len() == 1 => b.clone(),
                _ => continue,
            };
            let heading = skeleton::heading(&obs.joints);
            let root = obs.joints[0];
            let velocity = match self.prev_output.get(&t.id) {
                Some((tp, rp)) if g > *tp => (root - rp) / ((g - tp) as f64 / 1e9),
                _ => Vector3::zeros(),
            };
            ids.push((t.id, g, root));
            let (_, pose) = skeleton::inverse(&obs.joints);
            candidates.push((t.id, root, heading));
            tracks.push(HumanTrack {
                track_id: t.id,
                pose: HumanPose {
                    joints: obs.joints.iter().map(|p| [p.x, p.y, p.z]).collect(),
                    root_position: [root.x, root.y, root.z],
                    root_orientation: quat_to_xyzw(&heading),
                    local_positions: obs
                        .joints
                        .iter()
                        .map(|p| {
                            let l = heading.inverse() * (p - root);
                            [l.x, l.y, l.z]
                        })
                        .collect(),
                    local_rotations: pose.local.iter().map(quat_to_xyzw).collect(),
                    confidence: obs.confidence.iter().map(|c| c.clamp(0.0, 1.0)).collect(),
                },
                root_velocity: [velocity.x, velocity.y, velocity.z],
                age_frames: t.age_frames,
                filled_joints: obs.filled.clone(),
            });
        }
        for (id, g, root) in ids {
            self.prev_output.insert(id, (g, root));
        }
        let live: Vec<u32> = self.tracker.tracks().iter().map(|t| t.id).collect();
        self.prev_output.retain(|id, _| live.contains(id));
        self.tracker.bump_ages(tracks.iter().map(|t| t.track_id));
        let partner_id = self.tracker.choose_partner(&self.cfg, &candidates);
        let mut header = Header::new(&input.robot_id, "perception-bridge", frames::BASE_FOOTPRINT);
        header.stamp_ns = g;
        HumanSkeletons {
            header,
            rate_hz: self.cfg.rate_hz,
            tracks,
            partner_id,
        }
    }
}

/// Linear interpolation between two observations (w ∈ [0, 1]), or a short extrapolation
/// past `b` (w > 1) for grid points just after the newest frame.
fn interpolate(a: &Observation, b: &Observation, g: u64) -> Observation {
    let w = if b.stamp_ns > a.stamp_ns {
        (g as f64 - a.stamp_ns as f64) / (b.stamp_ns - a.stamp_ns) as f64
    } else {
        1.0
    };
    let mut joints = b.joints;
    let mut confidence = b.confidence;
    for k in 0..NUM_JOINTS {
        joints[k] = a.joints[k].lerp(&b.joints[k], w);
        confidence[k] = a.confidence[k] + w * (b.confidence[k] - a.confidence[k]);
    }
    Observation {
        stamp_ns: g,
        joints,
        confidence,
        filled: if w < 0.5 {
            a.filled.clone()
        } else {
            b.filled.clone()
        },
    }
}
