//! Messages on the edge pose estimator → perception bridge.

use super::*;

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
