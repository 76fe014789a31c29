//! Mock pose estimator.

use echo_motion::scripted::{bystander, demo_partner, ScriptedPerson};
use echo_motion::skeleton::{j, NUM_JOINTS};
use echo_motion::synth::{Clip, FPS};
use echo_msgs::{
    frames, CameraIntrinsics, DetectedPerson, Header, KeypointFormat, KeypointFrame, Keypoints,
};
use nalgebra::{Isometry3, Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// Keypoint layout the mock estimator reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MockFormat {
    /// SMPL-24 3D points in the camera frame (like HybrIK with depth alignment).
    Smpl24Points,
    /// COCO-17 pixels with per-keypoint depth (like YOLO-pose on an RGB-D camera).
    Coco17PixelsDepth,
}

/// Mock perception settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MockPerceptionConfig {
    /// Output format.
    pub format: MockFormat,
    /// Frame rate, Hz.
    pub rate_hz: f64,
    /// Gaussian keypoint noise (σ), metres.
    pub noise_m: f64,
    /// Probability that a joint is reported missing (confidence 0) in a frame.
    pub drop_joint_prob: f64,
    /// Probability that a whole frame is lost.
    pub drop_frame_prob: f64,
    /// Delay between capture and publication, ms.
    pub latency_ms: f64,
    /// Add a bystander walking across the scene.
    pub bystander: bool,
    /// Partner height, metres.
    pub partner_height_m: f64,
    /// Random seed.
    pub seed: u64,
    /// Loop the script.
    pub repeat: bool,
}

impl Default for MockPerceptionConfig {
    fn default() -> Self {
        MockPerceptionConfig {
            format: MockFormat::Smpl24Points,
            rate_hz: 15.0,
            noise_m: 0.01,
            drop_joint_prob: 0.02,
            drop_frame_prob: 0.0,
            latency_ms: 30.0,
            bystander: false,
            partner_height_m: 1.75,
            seed: 7,
            repeat: true,
        }
    }
}

/// The head camera's intrinsics (640 × 480 RGB-D, ~62° horizontal field of view).
pub const CAMERA: CameraIntrinsics = CameraIntrinsics {
    fx: 522.0,
    fy: 522.0,
    cx: 320.0,
    cy: 240.0,
    width: 640,
    height: 480,
};

/// A person the mock estimator watches.
#[derive(Debug, Clone)]
pub enum Actor {
    /// Keyframed behaviour (the demo partner, a bystander).
    Scripted(Box<ScriptedPerson>),
    /// One person of a recorded or generated interaction, replayed.
    Recorded(Recorded),
}

impl Actor {
    fn duration(&self) -> f64 {
        match self {
            Actor::Scripted(p) => p.duration(),
            Actor::Recorded(r) => r.duration(),
        }
    }

    fn joints_at(&self, t: f64) -> [Vector3<f64>; NUM_JOINTS] {
        match self {
            Actor::Scripted(p) => p.joints_at(t),
            Actor::Recorded(r) => r.joints_at(t),
        }
    }
}

/// Joint positions at a fixed rate, already in `base_footprint`; linear in between.
#[derive(Debug, Clone)]
pub struct Recorded {
    fps: f64,
    frames: Vec<[Vector3<f64>; NUM_JOINTS]>,
}

impl Recorded {
    /// Frames at `fps` (an empty recording is one person standing at the origin).
    pub fn new(fps: f64, frames: Vec<[Vector3<f64>; NUM_JOINTS]>) -> Recorded {
        let frames = if frames.is_empty() {
            vec![[Vector3::zeros(); NUM_JOINTS]]
        } else {
            frames
        };
        Recorded {
            fps: if fps > 0.0 { fps } else { 30.0 },
            frames,
        }
    }

    /// The frames.
    pub fn frames(&self) -> &[[Vector3<f64>; NUM_JOINTS]] {
        &self.frames
    }

    /// Length, seconds.
    pub fn duration(&self) -> f64 {
        self.frames.len().saturating_sub(1) as f64 / self.fps
    }

    /// Joints at `t` seconds (clamped to the recording).
    pub fn joints_at(&self, t: f64) -> [Vector3<f64>; NUM_JOINTS] {
        let x = (t * self.fps).clamp(0.0, self.frames.len().saturating_sub(1) as f64);
        let (i, f) = (x.floor() as usize, x.fract());
        let a = &self.frames[i];
        let b = &self.frames[(i + 1).min(self.frames.len() - 1)];
        std::array::from_fn(|k| a[k].lerp(&b[k], f))
    }
}

/// Both people of a generated interaction placed in front of the robot: the midpoint of their
/// starting pelvises `distance_m` ahead on x, the line between them across the view (along y).
pub fn clip_actors(clip: &Clip, distance_m: f64) -> Vec<Actor> {
    let a0 = clip.joints(0, 0)[0];
    let b0 = clip.joints(0, 1)[0];
    let mid = (a0 + b0) / 2.0;
    let axis = b0 - a0;
    // Rotate the A→B direction onto +y, then move the midpoint to (distance, 0).
    let yaw = std::f64::consts::FRAC_PI_2 - axis.y.atan2(axis.x);
    let rot = nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw);
    let place = |p: Vector3<f64>| {
        let q = rot * Vector3::new(p.x - mid.x, p.y - mid.y, p.z);
        Vector3::new(q.x + distance_m, q.y, q.z)
    };
    (0..2)
        .map(|who| {
            Actor::Recorded(Recorded {
                fps: FPS,
                frames: (0..clip.frames.len())
                    .map(|f| clip.joints(f, who).map(place))
                    .collect(),
            })
        })
        .collect()
}

/// The frame where the two people of a clip are closest (pelvis to pelvis).
pub fn closest_frame(clip: &Clip) -> usize {
    (0..clip.frames.len())
        .min_by(|a, b| {
            let d = |f: usize| (clip.joints(f, 0)[0] - clip.joints(f, 1)[0]).xy().norm();
            d(*a).total_cmp(&d(*b))
        })
        .unwrap_or(0)
}

/// Where the robot stands in a generated interaction's world when it plays person B: on B's
/// pelvis (on the floor) when the two were closest, facing along B's heading — where the HRI
/// data puts it. The robot does not walk: it plays B at the moment of the interaction.
pub fn robot_base_in_clip(clip: &Clip) -> nalgebra::Isometry3<f64> {
    let b0 = clip.joints(closest_frame(clip), 1);
    let yaw = echo_motion::skeleton::heading(&b0).euler_angles().2;
    nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(b0[0].x, b0[0].y, 0.0),
        nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
    )
}

/// Person A of a generated interaction in the robot's frame, the robot standing where
/// [`robot_base_in_clip`] puts it.
pub fn clip_partner_for_robot(clip: &Clip) -> Vec<Actor> {
    let to_robot = robot_base_in_clip(clip).inverse();
    vec![Actor::Recorded(Recorded {
        fps: FPS,
        frames: (0..clip.frames.len())
            .map(|f| {
                clip.joints(f, 0)
                    .map(|p| to_robot.transform_point(&nalgebra::Point3::from(p)).coords)
            })
            .collect(),
    })]
}

/// A mock estimator watching scripted people.
#[derive(Debug, Clone)]
pub struct MockPerception {
    cfg: MockPerceptionConfig,
    people: Vec<Actor>,
    rng: rand::rngs::StdRng,
}

impl MockPerception {
    /// The demo scene: the partner (and a bystander if configured).
    pub fn new(cfg: MockPerceptionConfig) -> Self {
        let mut people = vec![Actor::Scripted(Box::new(demo_partner(
            cfg.partner_height_m,
        )))];
        if cfg.bystander {
            people.push(Actor::Scripted(Box::new(bystander(1.65))));
        }
        Self::with_people(cfg, people)
    }

    /// A scene with the given people.
    pub fn with_people(cfg: MockPerceptionConfig, people: Vec<Actor>) -> Self {
        let rng = rand::rngs::StdRng::seed_from_u64(cfg.seed);
        MockPerception { cfg, people, rng }
    }

    /// Settings.
    pub fn config(&self) -> &MockPerceptionConfig {
        &self.cfg
    }

    /// Script time for wall time `t` since start (wraps when repeating; before the start the
    /// people hold their first pose).
    pub fn script_time(&self, t: f64) -> f64 {
        let d = self.people[0].duration();
        let t = t.max(0.0);
        if self.cfg.repeat && d > 0.0 {
            t.rem_euclid(d)
        } else {
            t
        }
    }

    /// Ground-truth joints of every person at script time `t`, in `base_footprint`.
    pub fn truth(&self, t: f64) -> Vec<[Vector3<f64>; NUM_JOINTS]> {
        self.people.iter().map(|p| p.joints_at(t)).collect()
    }

    /// The estimator's output for an image captured at script time `t` (stamped `stamp_ns`)
    /// with the camera at `camera` (camera optical frame in `base_footprint`). `None` when the
    /// frame is lost.
    pub fn frame(
        &mut self,
        robot_id: &str,
        t: f64,
        stamp_ns: u64,
        camera: &Isometry3<f64>,
    ) -> Option<KeypointFrame> {
        if self.rng.random::<f64>() < self.cfg.drop_frame_prob {
            return None;
        }
        let noise = Normal::new(0.0, self.cfg.noise_m.max(0.0)).ok()?;
        let to_cam = camera.inverse();
        let mut people = vec![];
        for (pid, truth) in self.truth(t).into_iter().enumerate() {
            let pts: Vec<Vector3<f64>> = truth
                .iter()
                .map(|p| (to_cam * Point3::from(*p)).coords)
                .collect();
            // Not in front of the camera: not detected.
            if pts[j::PELVIS].z < 0.3 {
                continue;
            }
            let mut noisy = |p: &Vector3<f64>| {
                p + Vector3::new(
                    noise.sample(&mut self.rng),
                    noise.sample(&mut self.rng),
                    noise.sample(&mut self.rng),
                )
            };
            let (keypoints, mut conf) = match self.cfg.format {
                MockFormat::Smpl24Points => {
                    let mut all: Vec<Vector3<f64>> = pts.iter().map(&mut noisy).collect();
                    // SMPL hands: a little beyond the wrists along the forearms.
                    for (w, e) in [(j::L_WRIST, j::L_ELBOW), (j::R_WRIST, j::R_ELBOW)] {
                        let dir = (pts[w] - pts[e]).normalize();
                        all.push(noisy(&(pts[w] + dir * 0.08)));
                    }
                    let xyz = all.iter().map(|p| [p.x, p.y, p.z]).collect();
                    (Keypoints::Points3d { xyz }, vec![0.95; 24])
                }
                MockFormat::Coco17PixelsDepth => {
                    let coco = coco_from_smpl(&pts);
                    let mut uv = vec![];
                    let mut depth = vec![];
                    let mut conf = vec![];
                    for p in &coco {
                        let p = noisy(p);
                        let z = p.z.max(0.05);
                        let (u, v) = (
                            CAMERA.fx * p.x / z + CAMERA.cx,
                            CAMERA.fy * p.y / z + CAMERA.cy,
                        );
                        let inside = (0.0..CAMERA.width as f64).contains(&u)
                            && (0.0..CAMERA.height as f64).contains(&v);
                        uv.push([u, v]);
                        depth.push(z);
                        conf.push(if inside { 0.9 } else { 0.0 });
                    }
                    (
                        Keypoints::PixelsDepth {
                            uv,
                            depth_m: Some(depth),
                        },
                        conf,
                    )
                }
            };
            for c in conf.iter_mut() {
                if self.rng.random::<f64>() < self.cfg.drop_joint_prob {
                    *c = 0.0;
                }
            }
            people.push(DetectedPerson {
                detection_id: Some(pid as u32 + 1),
                keypoints,
                confidence: conf,
            });
        }
        let mut header = Header::new(robot_id, "mock-perception", frames::HEAD_CAMERA_OPTICAL);
        header.stamp_ns = stamp_ns;
        let (format, camera) = match self.cfg.format {
            MockFormat::Smpl24Points => (KeypointFormat::Smpl24, None),
            MockFormat::Coco17PixelsDepth => (KeypointFormat::Coco17, Some(CAMERA)),
        };
        Some(KeypointFrame {
            header,
            format,
            joint_names: None,
            camera,
            depth_image: None,
            people,
        })
    }
}

/// COCO-17 keypoints of a SMPL-22 skeleton (face points from the head joint and heading).
pub fn coco_from_smpl(p: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    let across = (p[j::L_SHOULDER] - p[j::R_SHOULDER]).normalize();
    let up = (p[j::NECK] - p[j::PELVIS]).normalize();
    let fwd = across.cross(&up).normalize();
    let head = p[j::HEAD];
    let nose = head + fwd * 0.10;
    vec![
        nose,
        nose + across * 0.03 + up * 0.03,
        nose - across * 0.03 + up * 0.03,
        head + across * 0.075,
        head - across * 0.075,
        p[j::L_SHOULDER],
        p[j::R_SHOULDER],
        p[j::L_ELBOW],
        p[j::R_ELBOW],
        p[j::L_WRIST],
        p[j::R_WRIST],
        p[j::L_HIP],
        p[j::R_HIP],
        p[j::L_KNEE],
        p[j::R_KNEE],
        p[j::L_ANKLE],
        p[j::R_ANKLE],
    ]
}
