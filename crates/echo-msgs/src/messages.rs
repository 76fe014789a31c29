//! The messages, organised by edge of the data flow.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::skeleton::{COCO17, NUM_JOINTS, SMPL22, SMPL24};
use crate::validate::*;
use crate::{Header, Message, ValidationError};

macro_rules! message {
    ($ty:ty, $kind:literal) => {
        impl Message for $ty {
            const KIND: &'static str = $kind;
            fn header(&self) -> &Header {
                &self.header
            }
            fn header_mut(&mut self) -> &mut Header {
                &mut self.header
            }
        }
    };
}

// ---------------------------------------------------------------------------------------------
// pose estimator → perception bridge
// ---------------------------------------------------------------------------------------------

/// Joint layout of an external pose estimator's keypoints.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum KeypointFormat {
    /// Echo's own 22 SMPL body joints.
    Smpl22,
    /// SMPL 24 joints (22 body + 2 hands), e.g. HybrIK.
    Smpl24,
    /// COCO 17 keypoints, e.g. YOLO-pose lifted with depth.
    Coco17,
}

impl KeypointFormat {
    /// Joint names in the format's order.
    pub fn joint_names(self) -> &'static [&'static str] {
        match self {
            KeypointFormat::Smpl22 => &SMPL22,
            KeypointFormat::Smpl24 => &SMPL24,
            KeypointFormat::Coco17 => &COCO17,
        }
    }
}

/// Pinhole intrinsics of the camera that produced pixel keypoints.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraIntrinsics {
    /// Focal length in pixels, x.
    pub fx: f64,
    /// Focal length in pixels, y.
    pub fy: f64,
    /// Principal point x in pixels.
    pub cx: f64,
    /// Principal point y in pixels.
    pub cy: f64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// A depth image aligned to the colour image (row-major, millimetres, 0 = no reading).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DepthImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major depth in millimetres (`width * height` values; 0 = invalid).
    pub depth_mm: Vec<u16>,
}

/// One person's keypoints, in one of two forms.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Keypoints {
    /// 3D points in the camera optical frame, metres.
    #[serde(rename = "points_3d")]
    Points3d {
        /// One point per joint of the frame's format.
        xyz: Vec<[f64; 3]>,
    },
    /// 2D pixels plus depth: per-keypoint depth in metres, or sampled from the frame's depth image.
    PixelsDepth {
        /// Pixel coordinates (u right, v down) per joint.
        uv: Vec<[f64; 2]>,
        /// Per-keypoint depth along the optical axis, metres (omit to sample `depth_image`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        depth_m: Option<Vec<f64>>,
    },
}

/// One detected person.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectedPerson {
    /// The estimator's own id for this detection, if it tracks (used as a hint only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub detection_id: Option<u32>,
    /// Keypoints, one per joint of the frame's format.
    pub keypoints: Keypoints,
    /// Per-joint confidence in [0, 1]; 0 marks a joint the estimator did not see.
    pub confidence: Vec<f64>,
}

/// A pose estimator's output for one camera image. `header.frame_id` is the camera frame
/// (normally `head_front_camera_optical_frame`); `header.stamp_ns` is the image capture time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KeypointFrame {
    /// Header.
    pub header: Header,
    /// Joint layout of every person in `people`.
    pub format: KeypointFormat,
    /// Optional joint order: names from `format` (a permutation or subset) giving the order of
    /// every person's keypoints; absent = the format's own order and all of its joints.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_names: Option<Vec<String>>,
    /// Camera intrinsics; required for pixel keypoints.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraIntrinsics>,
    /// Aligned depth image; used for pixel keypoints without per-keypoint depth.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_image: Option<DepthImage>,
    /// Detected people (may be empty).
    pub people: Vec<DetectedPerson>,
}
message!(KeypointFrame, "keypoint_frame");

/// Most people one keypoint frame may carry.
pub const MAX_PEOPLE: usize = 32;

impl Validate for KeypointFrame {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.header.frame_id.is_empty() {
            return Err(ValidationError::Other(
                "header.frame_id must name the camera frame".into(),
            ));
        }
        if self.people.len() > MAX_PEOPLE {
            return Err(ValidationError::OutOfRange {
                field: "people".into(),
                value: self.people.len() as f64,
                min: 0.0,
                max: MAX_PEOPLE as f64,
            });
        }
        if let Some(c) = &self.camera {
            check_finite("camera", &[c.fx, c.fy, c.cx, c.cy])?;
            if c.fx <= 0.0 || c.fy <= 0.0 || c.width == 0 || c.height == 0 {
                return Err(ValidationError::Other(
                    "camera: focal lengths and size must be positive".into(),
                ));
            }
        }
        if let Some(d) = &self.depth_image {
            check_len(
                "depth_image.depth_mm",
                d.depth_mm.len(),
                d.width as usize * d.height as usize,
            )?;
            match &self.camera {
                Some(c) if c.width == d.width && c.height == d.height => {}
                _ => {
                    return Err(ValidationError::Other(
                        "depth_image needs camera intrinsics of the same size".into(),
                    ))
                }
            }
        }
        let n = match &self.joint_names {
            Some(names) => {
                check_joint_names("joint_names", names, self.format.joint_names())?;
                names.len()
            }
            None => self.format.joint_names().len(),
        };
        for (p, person) in self.people.iter().enumerate() {
            check_len(
                &format!("people[{p}].confidence"),
                person.confidence.len(),
                n,
            )?;
            for (j, c) in person.confidence.iter().enumerate() {
                check_range(&format!("people[{p}].confidence[{j}]"), *c, 0.0, 1.0)?;
            }
            match &person.keypoints {
                Keypoints::Points3d { xyz } => {
                    check_len(&format!("people[{p}].keypoints.xyz"), xyz.len(), n)?;
                    check_finite3(&format!("people[{p}].keypoints.xyz"), xyz)?;
                }
                Keypoints::PixelsDepth { uv, depth_m } => {
                    check_len(&format!("people[{p}].keypoints.uv"), uv.len(), n)?;
                    check_finite(&format!("people[{p}].keypoints.uv"), uv.as_flattened())?;
                    if self.camera.is_none() {
                        return Err(ValidationError::Other(
                            "pixel keypoints need camera intrinsics".into(),
                        ));
                    }
                    match depth_m {
                        Some(d) => {
                            check_len(&format!("people[{p}].keypoints.depth_m"), d.len(), n)?;
                            check_finite(&format!("people[{p}].keypoints.depth_m"), d)?;
                        }
                        None if self.depth_image.is_none() => {
                            return Err(ValidationError::Other(
                                "pixel keypoints need depth_m or a depth_image".into(),
                            ))
                        }
                        None => {}
                    }
                }
            }
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// perception bridge → forecaster, safety, retargeter
// ---------------------------------------------------------------------------------------------

/// One person's 22-joint pose in `base_footprint`, with what the models need.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HumanPose {
    /// Joint positions in the message frame, metres, SMPL-22 order.
    pub joints: Vec<[f64; 3]>,
    /// Pelvis position in the message frame.
    pub root_position: [f64; 3],
    /// Root (body) orientation as a unit quaternion `[x, y, z, w]`: x = facing direction
    /// on the floor, z = up.
    pub root_orientation: [f64; 4],
    /// Joint positions relative to the root, expressed in the root frame.
    pub local_positions: Vec<[f64; 3]>,
    /// Per-joint rotation relative to the parent joint (`[x, y, z, w]`), SMPL-22 order;
    /// entry 0 is the pelvis rotation relative to the root frame.
    pub local_rotations: Vec<[f64; 4]>,
    /// Per-joint confidence in [0, 1]; joints filled in by the bridge carry a decayed value.
    pub confidence: Vec<f64>,
}

impl HumanPose {
    /// Structural checks with `field` as the error path prefix.
    pub fn validate_at(&self, field: &str) -> Result<(), ValidationError> {
        check_len(&format!("{field}.joints"), self.joints.len(), NUM_JOINTS)?;
        check_finite3(&format!("{field}.joints"), &self.joints)?;
        check_finite(&format!("{field}.root_position"), &self.root_position)?;
        check_unit_quaternion(&format!("{field}.root_orientation"), &self.root_orientation)?;
        check_len(
            &format!("{field}.local_positions"),
            self.local_positions.len(),
            NUM_JOINTS,
        )?;
        check_finite3(&format!("{field}.local_positions"), &self.local_positions)?;
        check_len(
            &format!("{field}.local_rotations"),
            self.local_rotations.len(),
            NUM_JOINTS,
        )?;
        for (i, q) in self.local_rotations.iter().enumerate() {
            check_unit_quaternion(&format!("{field}.local_rotations[{i}]"), q)?;
        }
        check_len(
            &format!("{field}.confidence"),
            self.confidence.len(),
            NUM_JOINTS,
        )?;
        for (i, c) in self.confidence.iter().enumerate() {
            check_range(&format!("{field}.confidence[{i}]"), *c, 0.0, 1.0)?;
        }
        Ok(())
    }
}

/// A tracked person.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HumanTrack {
    /// Stable id while the person stays in view.
    pub track_id: u32,
    /// Current pose.
    pub pose: HumanPose,
    /// Root velocity in the message frame, m/s.
    pub root_velocity: [f64; 3],
    /// Number of output frames this track has existed.
    pub age_frames: u32,
    /// Joints (by SMPL-22 index) whose value was filled in from history in this frame.
    #[serde(default)]
    pub filled_joints: Vec<u8>,
}

impl HumanTrack {
    /// A track from joint positions alone — root at the pelvis, identity orientation, full
    /// confidence, no local pose — for tests and stand-ins.
    pub fn from_joints(track_id: u32, joints: Vec<[f64; 3]>) -> HumanTrack {
        HumanTrack {
            track_id,
            pose: HumanPose {
                root_position: joints.first().copied().unwrap_or([0.0; 3]),
                confidence: vec![1.0; joints.len()],
                joints,
                root_orientation: [0.0, 0.0, 0.0, 1.0],
                local_positions: vec![],
                local_rotations: vec![],
            },
            root_velocity: [0.0; 3],
            age_frames: 1,
            filled_joints: vec![],
        }
    }
}

/// Every tracked person at one instant, at the model rate. Frame: `base_footprint`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HumanSkeletons {
    /// Header (`stamp_ns` = the instant these poses describe).
    pub header: Header,
    /// Output rate of the stream, Hz.
    pub rate_hz: f64,
    /// All tracks.
    pub tracks: Vec<HumanTrack>,
    /// Track id of the interaction partner, if any.
    pub partner_id: Option<u32>,
}
message!(HumanSkeletons, "human_skeletons");

impl Validate for HumanSkeletons {
    fn validate(&self) -> Result<(), ValidationError> {
        check_range("rate_hz", self.rate_hz, 0.1, 1000.0)?;
        if self.tracks.len() > MAX_PEOPLE {
            return Err(ValidationError::OutOfRange {
                field: "tracks".into(),
                value: self.tracks.len() as f64,
                min: 0.0,
                max: MAX_PEOPLE as f64,
            });
        }
        for (i, t) in self.tracks.iter().enumerate() {
            t.pose.validate_at(&format!("tracks[{i}].pose"))?;
            check_finite(&format!("tracks[{i}].root_velocity"), &t.root_velocity)?;
            if let Some(j) = t.filled_joints.iter().find(|j| **j as usize >= NUM_JOINTS) {
                return Err(ValidationError::OutOfRange {
                    field: format!("tracks[{i}].filled_joints"),
                    value: *j as f64,
                    min: 0.0,
                    max: (NUM_JOINTS - 1) as f64,
                });
            }
        }
        if let Some(p) = self.partner_id {
            if !self.tracks.iter().any(|t| t.track_id == p) {
                return Err(ValidationError::Other(format!(
                    "partner_id {p} is not among the tracks"
                )));
            }
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// robot interface → everyone
// ---------------------------------------------------------------------------------------------

/// Planar base pose in the odometry frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BasePose {
    /// x, metres.
    pub x: f64,
    /// y, metres.
    pub y: f64,
    /// Heading about z, radians.
    pub yaw: f64,
}

/// Measured joint state of the robot (like sensor_msgs/JointState: map by name, order is not fixed).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    /// Header.
    pub header: Header,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions, radians or metres (prismatic).
    pub position: Vec<f64>,
    /// Velocities; empty or one per name.
    #[serde(default)]
    pub velocity: Vec<f64>,
    /// Base pose from odometry, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<BasePose>,
}
message!(JointState, "joint_state");

impl JointState {
    /// Position of joint `name`, if present.
    pub fn position_of(&self, name: &str) -> Option<f64> {
        self.name
            .iter()
            .position(|n| n == name)
            .map(|i| self.position[i])
    }
}

impl Validate for JointState {
    fn validate(&self) -> Result<(), ValidationError> {
        check_len("position", self.position.len(), self.name.len())?;
        check_finite("position", &self.position)?;
        if !self.velocity.is_empty() {
            check_len("velocity", self.velocity.len(), self.name.len())?;
            check_finite("velocity", &self.velocity)?;
        }
        if let Some(b) = &self.base {
            check_finite("base", &[b.x, b.y, b.yaw])?;
        }
        for (i, n) in self.name.iter().enumerate() {
            if n.is_empty() || self.name[..i].contains(n) {
                return Err(ValidationError::Other(format!(
                    "name[{i}] '{n}' is empty or repeated"
                )));
            }
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// operator / dialogue → forecaster, safety
// ---------------------------------------------------------------------------------------------

/// Interaction types Echo knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interaction {
    /// Shake hands.
    Handshake,
    /// Wave and wave back.
    Wave,
    /// High five.
    HighFive,
    /// Hand an object over.
    Handover,
    /// Hug.
    Hug,
    /// Bow and bow back.
    Bow,
    /// Point somewhere and look there.
    PointAndLook,
    /// Walk up and greet.
    ApproachGreet,
    /// Tap the other's shoulder.
    ShoulderTap,
    /// Mirror the other's arm motion.
    Imitation,
    /// Clap together.
    Clap,
    /// Walk past each other.
    WalkPast,
    /// No particular interaction.
    Idle,
}

impl Interaction {
    /// Interactions that bring the robot's hand into contact with the person.
    pub fn is_contact(self) -> bool {
        matches!(
            self,
            Interaction::Handshake
                | Interaction::HighFive
                | Interaction::Handover
                | Interaction::Hug
                | Interaction::ShoulderTap
        )
    }
}

/// Where the robot's motion comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ControlMode {
    /// Follow the forecaster's robot plan.
    Forecast,
    /// Mirror the partner through the retargeter.
    Imitation,
    /// Hold still.
    Hold,
}

/// The interaction the robot should take part in: text for the model, a typed intent for safety.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InteractionIntent {
    /// Header.
    pub header: Header,
    /// Natural-language description, e.g. "One person waves, and the other waves back."
    pub text: String,
    /// Typed interaction.
    pub interaction: Interaction,
    /// Control mode.
    pub mode: ControlMode,
}
message!(InteractionIntent, "interaction_intent");

/// Longest prompt accepted, in bytes.
pub const MAX_PROMPT_BYTES: usize = 1024;

impl Validate for InteractionIntent {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.text.len() > MAX_PROMPT_BYTES {
            return Err(ValidationError::OutOfRange {
                field: "text".into(),
                value: self.text.len() as f64,
                min: 0.0,
                max: MAX_PROMPT_BYTES as f64,
            });
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// forecaster / retargeter → safety
// ---------------------------------------------------------------------------------------------

/// One point of a robot plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanPoint {
    /// Seconds after `header.stamp_ns`.
    pub t: f64,
    /// Positions, one per `joint_names` entry.
    pub positions: Vec<f64>,
    /// Base pose in the odometry frame, if the plan moves the base.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<BasePose>,
}

/// A robot trajectory proposal. Not a command: only the safety service turns it into one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotPlan {
    /// Header (`frame_id` = frame of base poses, normally "odom").
    pub header: Header,
    /// Which mode produced it.
    pub mode: ControlMode,
    /// Joint names the plan controls.
    pub joint_names: Vec<String>,
    /// Points with strictly increasing `t`.
    pub points: Vec<PlanPoint>,
}
message!(RobotPlan, "robot_plan");

/// Most points a plan may carry.
pub const MAX_PLAN_POINTS: usize = 256;

impl Validate for RobotPlan {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.points.is_empty() || self.points.len() > MAX_PLAN_POINTS {
            return Err(ValidationError::OutOfRange {
                field: "points".into(),
                value: self.points.len() as f64,
                min: 1.0,
                max: MAX_PLAN_POINTS as f64,
            });
        }
        let times: Vec<f64> = self.points.iter().map(|p| p.t).collect();
        check_increasing("points[].t", &times)?;
        for (i, p) in self.points.iter().enumerate() {
            check_len(
                &format!("points[{i}].positions"),
                p.positions.len(),
                self.joint_names.len(),
            )?;
            check_finite(&format!("points[{i}].positions"), &p.positions)?;
            if let Some(b) = &p.base {
                check_finite(&format!("points[{i}].base"), &[b.x, b.y, b.yaw])?;
            }
        }
        Ok(())
    }
}

/// A forecast of the interaction: future partner motion and (in HRI mode) the robot's plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Forecast {
    /// Header (`stamp_ns` = time of the last observed frame; frame `base_footprint`).
    pub header: Header,
    /// Model identifier (checkpoint name).
    pub model: String,
    /// Frame rate of the forecast, Hz.
    pub rate_hz: f64,
    /// Partner track the forecast is about.
    pub partner_id: u32,
    /// Future partner joints, one 22-joint frame per step (step k is at (k+1)/rate_hz s).
    pub human: Vec<Vec<[f64; 3]>>,
    /// The robot's plan, when the model forecasts the robot too.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<RobotPlan>,
    /// Model inference time for this forecast, ms.
    pub inference_ms: f64,
}
message!(Forecast, "forecast");

impl Validate for Forecast {
    fn validate(&self) -> Result<(), ValidationError> {
        check_range("rate_hz", self.rate_hz, 0.1, 1000.0)?;
        check_range("inference_ms", self.inference_ms, 0.0, 1e6)?;
        if self.human.len() > MAX_PLAN_POINTS {
            return Err(ValidationError::OutOfRange {
                field: "human".into(),
                value: self.human.len() as f64,
                min: 0.0,
                max: MAX_PLAN_POINTS as f64,
            });
        }
        for (k, f) in self.human.iter().enumerate() {
            check_len(&format!("human[{k}]"), f.len(), NUM_JOINTS)?;
            check_finite3(&format!("human[{k}]"), f)?;
        }
        if let Some(r) = &self.robot {
            r.header.validate()?;
            r.validate()?;
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// safety → robot interface
// ---------------------------------------------------------------------------------------------

/// One point of a controller trajectory (trajectory_msgs/JointTrajectoryPoint).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrajectoryPoint {
    /// Seconds after the command's stamp.
    pub time_from_start: f64,
    /// Positions.
    pub positions: Vec<f64>,
    /// Velocities (same length as positions).
    pub velocities: Vec<f64>,
    /// Accelerations (same length as positions).
    pub accelerations: Vec<f64>,
}

/// A trajectory for one controller (names all of its joints).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControllerTrajectory {
    /// Controller name, e.g. "arm_left_controller".
    pub controller: String,
    /// The controller's joints.
    pub joint_names: Vec<String>,
    /// Points with strictly increasing `time_from_start`.
    pub points: Vec<TrajectoryPoint>,
}

/// Base velocity (geometry_msgs/Twist restricted to a differential drive).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BaseTwist {
    /// Forward speed, m/s.
    pub linear_x: f64,
    /// Turn rate, rad/s.
    pub angular_z: f64,
}

/// The only message that moves the robot; published by the safety service alone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotCommand {
    /// Header.
    pub header: Header,
    /// One trajectory per controller that moves.
    pub trajectories: Vec<ControllerTrajectory>,
    /// Base velocity, when the base moves (absent = zero).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_twist: Option<BaseTwist>,
}
message!(RobotCommand, "robot_command");

impl Validate for RobotCommand {
    fn validate(&self) -> Result<(), ValidationError> {
        for (c, tr) in self.trajectories.iter().enumerate() {
            let n = tr.joint_names.len();
            if tr.points.is_empty() || tr.points.len() > MAX_PLAN_POINTS {
                return Err(ValidationError::OutOfRange {
                    field: format!("trajectories[{c}].points"),
                    value: tr.points.len() as f64,
                    min: 1.0,
                    max: MAX_PLAN_POINTS as f64,
                });
            }
            let times: Vec<f64> = tr.points.iter().map(|p| p.time_from_start).collect();
            check_increasing(
                &format!("trajectories[{c}].points[].time_from_start"),
                &times,
            )?;
            for (i, p) in tr.points.iter().enumerate() {
                let f = format!("trajectories[{c}].points[{i}]");
                check_len(&format!("{f}.positions"), p.positions.len(), n)?;
                check_len(&format!("{f}.velocities"), p.velocities.len(), n)?;
                check_len(&format!("{f}.accelerations"), p.accelerations.len(), n)?;
                check_finite(&format!("{f}.positions"), &p.positions)?;
                check_finite(&format!("{f}.velocities"), &p.velocities)?;
                check_finite(&format!("{f}.accelerations"), &p.accelerations)?;
            }
        }
        if let Some(t) = &self.base_twist {
            check_finite("base_twist", &[t.linear_x, t.angular_z])?;
        }
        Ok(())
    }
}

/// State of the safety filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SafetyState {
    /// Following a valid plan unchanged.
    Following,
    /// Following, but a limit or separation scaled the motion down.
    Limiting,
    /// Executing a controlled stop.
    Stopping,
    /// Stopped and holding.
    Holding,
    /// Latched emergency stop: needs an explicit reset.
    EStopped,
}

/// Safety filter status, published every cycle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SafetyStatus {
    /// Header.
    pub header: Header,
    /// Current state.
    pub state: SafetyState,
    /// Why the state is what it is (empty when following).
    pub reasons: Vec<String>,
    /// Speed scale applied this cycle, [0, 1].
    pub speed_scale: f64,
    /// Smallest robot–human distance seen this cycle, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_separation_m: Option<f64>,
    /// Rejections and events by reason since start.
    pub counters: BTreeMap<String, u64>,
}
message!(SafetyStatus, "safety_status");

impl Validate for SafetyStatus {
    fn validate(&self) -> Result<(), ValidationError> {
        check_range("speed_scale", self.speed_scale, 0.0, 1.0)?;
        if let Some(d) = self.min_separation_m {
            check_finite("min_separation_m", &[d])?;
        }
        Ok(())
    }
}

/// E-stop action.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EStopAction {
    /// Stop now and latch.
    Engage,
    /// Release a latched stop.
    Reset,
}

/// Emergency stop request (latched until an explicit reset).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EStop {
    /// Header.
    pub header: Header,
    /// Engage or reset.
    pub action: EStopAction,
    /// Who and why.
    pub reason: String,
}
message!(EStop, "estop");

impl Validate for EStop {
    fn validate(&self) -> Result<(), ValidationError> {
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// every service → operators
// ---------------------------------------------------------------------------------------------

/// Latency summary.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LatencySummary {
    /// Median, ms.
    pub median_ms: f64,
    /// 99th percentile, ms.
    pub p99_ms: f64,
    /// Samples in the window.
    pub samples: u64,
}

/// A service's health and counters, published once per second and on shutdown.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ServiceStatus {
    /// Header.
    pub header: Header,
    /// Service name.
    pub service: String,
    /// Seconds since start.
    pub uptime_s: f64,
    /// Messages received per input.
    pub received: BTreeMap<String, u64>,
    /// Messages published per output.
    pub published: BTreeMap<String, u64>,
    /// Rejected inputs by reason ("<input>/<reason>").
    pub rejected: BTreeMap<String, u64>,
    /// Messages dropped by queue policy per input.
    pub dropped: BTreeMap<String, u64>,
    /// Most recent rejection, with its full reason.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub last_error: Option<String>,
    /// Processing latency per message.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub latency: Option<LatencySummary>,
    /// Free-form state notes (e.g. "forecasting human only").
    #[serde(default)]
    pub notes: Vec<String>,
}
message!(ServiceStatus, "service_status");

impl Validate for ServiceStatus {
    fn validate(&self) -> Result<(), ValidationError> {
        check_identifier("service", &self.service)?;
        check_finite("uptime_s", &[self.uptime_s])
    }
}
