//! BlazePose's full landmark model (`pose_landmark_full`, converted to ONNX by
//! `scripts/setup`) in an ONNX Runtime session.

use std::path::{Path, PathBuf};

use ort::session::Session;
use ort::value::Tensor;

use crate::image::{sample_crop, Image, CROP};
use crate::roi::Roi;
use crate::PoseError;

/// Landmarks the model gives: 33 body points, then 6 auxiliary ones (33 = hip centre and
/// 34 = scale point, MediaPipe's alignment points for the next crop).
pub const NUM_LANDMARKS: usize = 39;
/// The body points among them (MediaPipe Pose's 33).
pub const BODY_LANDMARKS: usize = 33;
/// Auxiliary landmark at the hip centre.
pub const AUX_HIP: usize = 33;
/// Auxiliary landmark the crop's size and rotation are taken from.
pub const AUX_SCALE: usize = 34;

/// File name `scripts/setup` writes under `.cache/blazepose/`.
pub const MODEL_FILE: &str = "pose_landmark_full.onnx";
/// The model's input and outputs, as the conversion names them.
const INPUT: &str = "input_1";
const OUT_LANDMARKS: &str = "Identity";
const OUT_PRESENCE: &str = "Identity_1";
const OUT_WORLD: &str = "Identity_4";

/// One landmark in the image.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Landmark {
    /// Pixel x (pixel-centre convention: the first column's centre is 0, as in OpenCV/ROS).
    pub x: f32,
    /// Pixel y, down.
    pub y: f32,
    /// Depth relative to the hips, in image pixels (MediaPipe's scale: the crop's side); smaller
    /// is nearer the camera.
    pub z: f32,
    /// Probability that the point is visible (not occluded), in [0, 1].
    pub visibility: f32,
    /// Probability that the point lies inside the crop, in [0, 1].
    pub presence: f32,
}

/// What one run of the model on one crop gives.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseLandmarks {
    /// The crop the model read.
    pub roi: Roi,
    /// Probability that the crop holds a person, in [0, 1].
    pub presence: f32,
    /// The 39 landmarks in image pixels.
    pub image: Vec<Landmark>,
    /// The 39 landmarks in metres, origin at the hip centre, axes as the camera's (x right,
    /// y down, z away from the camera): the model's metric 3D pose.
    pub world: Vec<[f32; 3]>,
}

impl PoseLandmarks {
    /// The MediaPipe tracking crop for the next frame, from auxiliary landmarks 33 and 34.
    pub fn next_roi(&self) -> Roi {
        let p = |i: usize| [self.image[i].x + 0.5, self.image[i].y + 0.5];
        Roi::from_alignment(p(AUX_HIP), p(AUX_SCALE))
    }
}

/// Where the model is looked for: `$ECHO_POSE_MODEL`, then `blazepose/pose_landmark_full.onnx`
/// in every fetched-asset directory ([`echo_assets::cache_dirs`]).
pub fn model_candidates() -> Vec<PathBuf> {
    let mut v = vec![];
    if let Ok(p) = std::env::var("ECHO_POSE_MODEL") {
        v.push(PathBuf::from(p));
    }
    v.extend(
        echo_assets::cache_dirs("blazepose")
            .into_iter()
            .map(|d| d.join(MODEL_FILE)),
    );
    v
}

/// The first candidate that exists, or [`PoseError::ModelNotFound`] naming where it looked.
pub fn locate_model() -> Result<PathBuf, PoseError> {
    let c = model_candidates();
    c.iter()
        .find(|p| p.is_file())
        .cloned()
        .ok_or_else(|| PoseError::ModelNotFound {
            searched: c
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", "),
        })
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

fn runtime<E: std::fmt::Display>(e: E) -> PoseError {
    PoseError::Runtime(e.to_string())
}

/// The landmark model in an ONNX Runtime session.
pub struct BlazePose {
    session: Session,
    input: Vec<f32>,
}

impl BlazePose {
    /// Load the model from [`locate_model`] with `threads` intra-op threads (0: ONNX Runtime's
    /// choice). ONNX Runtime itself is found as `echo_onnx` finds it (`$ECHO_ORT_DYLIB`, or the
    /// library `scripts/setup` unpacks).
    pub fn load_default(threads: usize) -> Result<BlazePose, PoseError> {
        BlazePose::load(&locate_model()?, threads)
    }

    /// Load the model at `path`.
    pub fn load(path: &Path, threads: usize) -> Result<BlazePose, PoseError> {
        if !path.is_file() {
            return Err(PoseError::ModelNotFound {
                searched: path.display().to_string(),
            });
        }
        let env = echo_onnx::runtime::environment().map_err(runtime)?;
        let mut b = Session::builder(env).map_err(runtime)?;
        if threads > 0 {
            b = b.with_intra_threads(threads).map_err(runtime)?;
        }
        let session = b
            .commit_from_file(path)
            .map_err(|e| PoseError::Runtime(format!("{}: {e}", path.display())))?;
        let has = |names: Vec<&str>, want: &str| names.contains(&want);
        let inputs: Vec<&str> = session.inputs().iter().map(|o| o.name()).collect();
        let outputs: Vec<&str> = session.outputs().iter().map(|o| o.name()).collect();
        if !has(inputs, INPUT)
            || ![OUT_LANDMARKS, OUT_PRESENCE, OUT_WORLD]
                .iter()
                .all(|o| has(outputs.clone(), o))
        {
            return Err(PoseError::ModelOutput(format!(
                "{} is not the converted pose_landmark_full (input {INPUT}, outputs \
                 {OUT_LANDMARKS}, {OUT_PRESENCE}, {OUT_WORLD})",
                path.display()
            )));
        }
        Ok(BlazePose {
            session,
            input: vec![0.0; 3 * CROP * CROP],
        })
    }

    /// Run the model on crop `roi` of `img`.
    pub fn run(&mut self, img: &Image, roi: &Roi) -> Result<PoseLandmarks, PoseError> {
        sample_crop(img, roi, &mut self.input);
        let x =
            Tensor::from_array(([1usize, 3, CROP, CROP], self.input.clone())).map_err(runtime)?;
        let out = self
            .session
            .run(ort::inputs![INPUT => x])
            .map_err(runtime)?;
        let get = |name: &str, len: usize| -> Result<Vec<f32>, PoseError> {
            let (_, v) = out[name].try_extract_tensor::<f32>().map_err(runtime)?;
            if v.len() != len {
                return Err(PoseError::ModelOutput(format!(
                    "output {name} has {} values, expected {len}",
                    v.len()
                )));
            }
            Ok(v.to_vec())
        };
        let lm = get(OUT_LANDMARKS, NUM_LANDMARKS * 5)?;
        let presence = get(OUT_PRESENCE, 1)?[0];
        let world = get(OUT_WORLD, NUM_LANDMARKS * 3)?;
        let n = CROP as f32;
        let (sin, cos) = roi.rotation.sin_cos();
        let image = lm
            .chunks_exact(5)
            .map(|l| {
                let [x, y] = roi.to_image(l[0] / n, l[1] / n);
                Landmark {
                    x: x - 0.5,
                    y: y - 0.5,
                    z: l[2] / n * roi.size,
                    visibility: sigmoid(l[3]),
                    presence: sigmoid(l[4]),
                }
            })
            .collect();
        // World points come in the crop's axes: turn them as the crop is turned.
        let world = world
            .chunks_exact(3)
            .map(|w| [cos * w[0] - sin * w[1], sin * w[0] + cos * w[1], w[2]])
            .collect();
        Ok(PoseLandmarks {
            roi: *roi,
            presence: if presence.is_finite() { presence } else { 0.0 },
            image,
            world,
        })
    }
}
