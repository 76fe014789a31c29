//! Camera pose estimation for the perception bridge: a colour image (plus, optionally, the
//! aligned depth image and the camera intrinsics) in, the bridge's
//! [`echo_msgs::KeypointFrame`] (COCO-17) out.
//!
//! # Model
//!
//! BlazePose GHUM 3D's full landmark model (`pose_landmark_full.tflite` from PyPI mediapipe
//! 0.10.21, Apache-2.0), converted to ONNX by `scripts/setup` into
//! `.cache/blazepose/pose_landmark_full.onnx` (or `$ECHO_POSE_MODEL`), run by ONNX Runtime
//! through `ort` with the library `echo_onnx::runtime` finds. Input: a person-centred square
//! crop, 256 × 256 RGB in [0, 1], NCHW. Outputs used: 39 landmarks (x, y, z, visibility,
//! presence) in crop pixels, a presence score for the crop, and 39 world landmarks (metres,
//! origin at the hip centre). The first 33 are MediaPipe Pose's body points; 33 and 34 are the
//! hip centre and a scale point from which MediaPipe derives the next frame's crop.
//!
//! # Finding people: rules instead of a detector
//!
//! MediaPipe seeds the crop with a person detector, which does not convert to ONNX with the
//! same tool (DENSIFY and DEPTH_TO_SPACE operators). The crop is instead placed by rules:
//!
//! 1. **Tracking** (a person found in the previous frame): MediaPipe's own rule. The crop is
//!    centred on landmark 33 (hip centre), its side is 2 × 1.25 × the distance from 33 to 34,
//!    and it is turned so that 33 → 34 points up. A crop whose presence score falls under 0.5
//!    loses the person.
//! 2. **Search** (the first frame, when no one is tracked, and every 30 frames for newcomers):
//!    the model runs on upright square crops: the square around the whole image, and squares of
//!    the short side overlapping by half (a 640 × 480 image: 3 crops). Each crop with a
//!    presence score of at least 0.5 is refined, best first, in two steps:
//!    - *face-anchored crop*: the landmark model puts the hips near the crop centre whenever they
//!      are not in view (a person cut off at the waist, as a robot's head camera often sees
//!      them), and the tracking rule alone then settles on crops that are too small, which
//!      pulls the shoulders towards the head. The head points (nose, eyes, ears, mouth) are
//!      precise whatever the crop, so the model's metric pose is fitted to them (scale and
//!      shift in x, y), the world hip centre is projected with that fit, and the crop is a
//!      square of 2.3 m (at the fitted scale) centred there;
//!    - then the tracking rule once on that result.
//!
//!    A refined result that still scores 0.5 or more is a person unless it is the same person
//!    as one already found (nose, shoulder centre and hip centre on average within 10 % of the
//!    crop side): one person gives one detection, several people several.
//! 3. Depth blobs are not used to seed crops (yet): the depth image only places keypoints.
//!
//! # Output
//!
//! COCO-17 keypoints ([`keypoints::COCO17_FROM_BLAZEPOSE`]), the track id as `detection_id`,
//! and as confidence the model's visibility × presence, or 0 for a keypoint outside the image
//! (guessed, not seen). With intrinsics, each keypoint is a pixel
//! plus a depth: the depth image's reading where it agrees with the model, else the model's
//! metric pose placed at the hip depth measured from the depth image or, without one, at the
//! distance that makes the metric pose's projection fit the pixels (the person's pixel size
//! against the model's metric size). Without intrinsics: 3D points in the optical frame from a
//! nominal 62° camera. See [`keypoints::detected_person`].
//!
//! Inputs are checked ([`Image::new`], [`keypoints::check_inputs`]); bad ones are
//! [`PoseError`]s, never panics.

pub mod estimator;
pub mod image;
pub mod keypoints;
pub mod model;
pub mod roi;

pub use estimator::{EstimatorConfig, Person, PoseEstimator};
pub use image::{Image, PixelFormat};
pub use keypoints::{keypoint_frame, COCO17_FROM_BLAZEPOSE};
pub use model::{BlazePose, Landmark, PoseLandmarks};
pub use roi::Roi;

/// What can go wrong.
#[derive(Debug, thiserror::Error)]
pub enum PoseError {
    /// The converted model is nowhere.
    #[error("BlazePose model not found (looked for {searched}); run scripts/setup or set ECHO_POSE_MODEL")]
    ModelNotFound {
        /// Where it was looked for.
        searched: String,
    },
    /// ONNX Runtime is missing or failed.
    #[error("ONNX Runtime: {0}")]
    Runtime(String),
    /// The model file is not the expected model.
    #[error("unexpected model: {0}")]
    ModelOutput(String),
    /// Width or height is zero.
    #[error("empty image ({width} × {height})")]
    EmptyImage {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// Width or height beyond [`image::MAX_SIDE`].
    #[error("image too large ({width} × {height})")]
    ImageTooLarge {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// The buffer does not hold the image its size and format describe.
    #[error("image buffer of {got} bytes, expected {expected} ({width} × {height} × {channels} channels)")]
    BufferSize {
        /// Bytes expected.
        expected: usize,
        /// Bytes given.
        got: usize,
        /// Width.
        width: u32,
        /// Height.
        height: u32,
        /// Bytes per pixel.
        channels: usize,
    },
    /// Rows shorter than a row of pixels.
    #[error("row step of {step} bytes, shorter than a row ({min} bytes)")]
    RowStride {
        /// Step given.
        step: usize,
        /// Bytes in one row of pixels.
        min: usize,
    },
    /// A pixel encoding the estimator does not read.
    #[error("unsupported image encoding {0:?} (rgb8, bgr8, rgba8, bgra8 or mono8)")]
    UnsupportedEncoding(String),
    /// Intrinsics that are not finite or have a non-positive focal length.
    #[error("camera intrinsics must be finite with positive focal lengths")]
    InvalidIntrinsics,
    /// Intrinsics for another image size.
    #[error("camera intrinsics are for {camera:?}, the image is {image:?}")]
    IntrinsicsSize {
        /// (width, height) of the intrinsics.
        camera: (u32, u32),
        /// (width, height) of the image.
        image: (u32, u32),
    },
    /// A depth image that is not aligned to the colour image.
    #[error("depth image of {depth:?} with {values} values does not match the {image:?} image")]
    DepthSize {
        /// (width, height) of the depth image.
        depth: (u32, u32),
        /// Values it holds.
        values: usize,
        /// (width, height) of the colour image.
        image: (u32, u32),
    },
    /// A depth image without intrinsics (its readings cannot be used).
    #[error("a depth image needs the camera intrinsics")]
    DepthWithoutIntrinsics,
}
