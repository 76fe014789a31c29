//! `sensor_msgs/Image` and `sensor_msgs/CameraInfo`: the head camera's colour and depth
//! streams in CDR, the calibration's intrinsics, and depth as millimetres (colour pixels are
//! read in place by `echo_pose::Image`, which checks their encoding, step and size).
//!
//! Depth rules: `16UC1` (millimetres, 0 = no reading) and `32FC1` (metres, NaN/∞/≤ 0 = no reading; beyond 65.535 m saturates to no
//! reading). `step` may pad rows but never be shorter than a row; `data` must hold exactly
//! `step · height` bytes; images larger than [`MAX_SIDE`] on a side are refused. Big-endian
//! depth (`is_bigendian = 1`) is read as such.

use serde::{Deserialize, Serialize};

use crate::RosHeader;

/// Largest accepted image side, pixels.
pub const MAX_SIDE: u32 = 8192;

/// The TIAGo++ head camera's colour image topic (PAL's ROS 2 driver).
pub const HEAD_RGB_TOPIC: &str = "/head_front_camera/rgb/image_raw";
/// Its calibration.
pub const HEAD_RGB_INFO_TOPIC: &str = "/head_front_camera/rgb/camera_info";
/// Depth registered to the colour image.
pub const HEAD_DEPTH_TOPIC: &str = "/head_front_camera/depth_registered/image_raw";

/// sensor_msgs/msg/Image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct RosImage {
    /// Header (stamp: capture time; frame: the optical frame).
    pub header: RosHeader,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding (`rgb8`, `bgr8`, `16UC1`, `32FC1`, …).
    #[serde(deserialize_with = "crate::bounded::string")]
    pub encoding: String,
    /// 1 when multi-byte values are big-endian.
    pub is_bigendian: u8,
    /// Row length, bytes.
    pub step: u32,
    /// Pixels, row-major.
    #[serde(deserialize_with = "crate::bounded::bytes")]
    pub data: Vec<u8>,
}

/// sensor_msgs/msg/RegionOfInterest.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct RegionOfInterest {
    /// Left column.
    pub x_offset: u32,
    /// Top row.
    pub y_offset: u32,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Rectify the region.
    pub do_rectify: bool,
}

/// sensor_msgs/msg/CameraInfo.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct RosCameraInfo {
    /// Header.
    pub header: RosHeader,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Distortion model name.
    #[serde(deserialize_with = "crate::bounded::string")]
    pub distortion_model: String,
    /// Distortion coefficients.
    pub d: Vec<f64>,
    /// Intrinsic matrix, row-major 3×3.
    pub k: [f64; 9],
    /// Rectification, row-major 3×3.
    pub r: [f64; 9],
    /// Projection, row-major 3×4.
    pub p: [f64; 12],
    /// Horizontal binning.
    pub binning_x: u32,
    /// Vertical binning.
    pub binning_y: u32,
    /// Region of interest.
    pub roi: RegionOfInterest,
}

/// Why an image cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ImageError {
    /// The encoding is not one this reader takes.
    #[error(
        "unsupported encoding '{0}' (colour: rgb8, bgr8, rgba8, bgra8, mono8; depth: 16UC1, 32FC1)"
    )]
    Encoding(String),
    /// Zero or oversized dimensions.
    #[error("image size {width}×{height} outside 1..={MAX_SIDE}")]
    Size {
        /// Columns.
        width: u32,
        /// Rows.
        height: u32,
    },
    /// `step` shorter than a row.
    #[error("step {step} B is shorter than a row of {row} B")]
    Step {
        /// Declared step.
        step: u32,
        /// Bytes a row needs.
        row: u64,
    },
    /// `data` does not hold `step · height` bytes (truncated or padded).
    #[error("{got} B of pixel data, expected step·height = {expected} B")]
    Truncated {
        /// Bytes present.
        got: usize,
        /// Bytes expected.
        expected: u64,
    },
    /// Colour and depth do not share a size.
    #[error("depth {0}×{1} does not match the colour image {2}×{3}")]
    Mismatch(u32, u32, u32, u32),
    /// Camera calibration that cannot be right.
    #[error("camera info: {0}")]
    Calibration(String),
}

/// A depth image in millimetres (0 = no reading), row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthMm {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// `width · height` values.
    pub data: Vec<u16>,
}

impl RosImage {
    /// Check size, step and data length for `bytes_per_pixel`; the rows as slices.
    fn rows(&self, bytes_per_pixel: u64) -> Result<impl Iterator<Item = &[u8]>, ImageError> {
        if self.width == 0 || self.height == 0 || self.width > MAX_SIDE || self.height > MAX_SIDE {
            return Err(ImageError::Size {
                width: self.width,
                height: self.height,
            });
        }
        let row = self.width as u64 * bytes_per_pixel;
        if (self.step as u64) < row {
            return Err(ImageError::Step {
                step: self.step,
                row,
            });
        }
        let expected = self.step as u64 * self.height as u64;
        if self.data.len() as u64 != expected {
            return Err(ImageError::Truncated {
                got: self.data.len(),
                expected,
            });
        }
        let (step, row) = (self.step as usize, row as usize);
        Ok(self.data.chunks_exact(step).map(move |r| &r[..row]))
    }

    /// The image as depth in millimetres.
    pub fn to_depth_mm(&self) -> Result<DepthMm, ImageError> {
        let big = self.is_bigendian != 0;
        let mut data = Vec::with_capacity(self.width as usize * self.height as usize);
        match self.encoding.as_str() {
            "16UC1" | "mono16" => {
                for r in self.rows(2)? {
                    data.extend(r.chunks_exact(2).map(|b| {
                        let b = [b[0], b[1]];
                        if big {
                            u16::from_be_bytes(b)
                        } else {
                            u16::from_le_bytes(b)
                        }
                    }));
                }
            }
            "32FC1" => {
                for r in self.rows(4)? {
                    data.extend(r.chunks_exact(4).map(|b| {
                        let b = [b[0], b[1], b[2], b[3]];
                        let m = if big {
                            f32::from_be_bytes(b)
                        } else {
                            f32::from_le_bytes(b)
                        };
                        let mm = m as f64 * 1000.0;
                        if mm.is_finite() && mm >= 1.0 && mm <= u16::MAX as f64 {
                            mm.round() as u16
                        } else {
                            0
                        }
                    }));
                }
            }
            e => return Err(ImageError::Encoding(e.to_string())),
        }
        Ok(DepthMm {
            width: self.width,
            height: self.height,
            data,
        })
    }

    /// Capture time, ns since the epoch.
    pub fn stamp_ns(&self) -> u64 {
        self.header.stamp.to_ns()
    }
}

impl RosCameraInfo {
    /// The pinhole intrinsics (from `k`): focal lengths must be positive and finite, the
    /// principal point inside the image.
    pub fn intrinsics(&self) -> Result<echo_msgs::CameraIntrinsics, ImageError> {
        let (fx, cx, fy, cy) = (self.k[0], self.k[2], self.k[4], self.k[5]);
        if ![fx, fy, cx, cy].iter().all(|v| v.is_finite()) || fx <= 0.0 || fy <= 0.0 {
            return Err(ImageError::Calibration(format!(
                "focal lengths must be positive and finite (fx {fx}, fy {fy}, cx {cx}, cy {cy})"
            )));
        }
        if self.width == 0 || self.height == 0 || self.width > MAX_SIDE || self.height > MAX_SIDE {
            return Err(ImageError::Size {
                width: self.width,
                height: self.height,
            });
        }
        if !(0.0..=self.width as f64).contains(&cx) || !(0.0..=self.height as f64).contains(&cy) {
            return Err(ImageError::Calibration(format!(
                "principal point ({cx}, {cy}) outside the {}×{} image",
                self.width, self.height
            )));
        }
        Ok(echo_msgs::CameraIntrinsics {
            fx,
            fy,
            cx,
            cy,
            width: self.width,
            height: self.height,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{decode, encode, Time};

    fn image(encoding: &str, w: u32, h: u32, step: u32, data: Vec<u8>) -> RosImage {
        RosImage {
            header: RosHeader {
                stamp: Time { sec: 3, nanosec: 7 },
                frame_id: "head_front_camera_rgb_optical_frame".into(),
            },
            height: h,
            width: w,
            encoding: encoding.into(),
            is_bigendian: 0,
            step,
            data,
        }
    }

    #[test]
    fn image_cdr_layout_follows_the_idl() {
        let img = image("rgb8", 1, 1, 3, vec![10, 20, 30]);
        let b = encode(&img).unwrap();
        // encapsulation, stamp (8), frame_id (4 + 36 incl. NUL, padded to 4), height, width,
        // encoding (4 + 5), is_bigendian (1), pad to 4, step, data (4 + 3).
        let mut want = vec![0u8, 1, 0, 0];
        want.extend(3i32.to_le_bytes());
        want.extend(7u32.to_le_bytes());
        let frame = b"head_front_camera_rgb_optical_frame\0";
        want.extend((frame.len() as u32).to_le_bytes());
        want.extend(frame);
        while (want.len() - 4) % 4 != 0 {
            want.push(0);
        }
        want.extend(1u32.to_le_bytes());
        want.extend(1u32.to_le_bytes());
        want.extend(5u32.to_le_bytes());
        want.extend(b"rgb8\0");
        want.push(0); // is_bigendian
        while (want.len() - 4) % 4 != 0 {
            want.push(0);
        }
        want.extend(3u32.to_le_bytes());
        want.extend(3u32.to_le_bytes());
        want.extend([10, 20, 30]);
        assert_eq!(b, want);
        assert_eq!(decode::<RosImage>(&b).unwrap(), img);
    }

    #[test]
    fn camera_info_round_trips_and_gives_intrinsics() {
        let mut info = RosCameraInfo {
            width: 640,
            height: 480,
            distortion_model: "plumb_bob".into(),
            d: vec![0.0; 5],
            ..Default::default()
        };
        info.k = [522.0, 0.0, 320.5, 0.0, 522.0, 240.5, 0.0, 0.0, 1.0];
        let back: RosCameraInfo = decode(&encode(&info).unwrap()).unwrap();
        assert_eq!(back, info);
        let k = back.intrinsics().unwrap();
        assert_eq!((k.fx, k.cy, k.width), (522.0, 240.5, 640));
        info.k[0] = 0.0;
        assert!(matches!(info.intrinsics(), Err(ImageError::Calibration(_))));
        info.k[0] = f64::NAN;
        assert!(info.intrinsics().is_err());
        info.k[0] = 522.0;
        info.k[2] = 900.0;
        assert!(info.intrinsics().is_err(), "principal point outside");
    }

    #[test]
    fn depth_row_padding_is_skipped() {
        // 2×2 16UC1 with rows padded to 6 bytes.
        let data = vec![1, 0, 2, 0, 9, 9, 3, 0, 4, 0, 9, 9];
        let d = image("16UC1", 2, 2, 6, data).to_depth_mm().unwrap();
        assert_eq!(d.data, vec![1, 2, 3, 4]);
    }

    #[test]
    fn bad_images_are_named() {
        let e = |img: RosImage| img.to_depth_mm().unwrap_err();
        assert!(matches!(
            e(image("yuv422", 2, 2, 4, vec![0; 8])),
            ImageError::Encoding(_)
        ));
        assert!(matches!(
            e(image("16UC1", 0, 2, 0, vec![])),
            ImageError::Size { .. }
        ));
        assert!(matches!(
            e(image("16UC1", 9000, 1, 18000, vec![0; 18000])),
            ImageError::Size { .. }
        ));
        assert!(matches!(
            e(image("16UC1", 2, 2, 3, vec![0; 6])),
            ImageError::Step { .. }
        ));
        assert!(matches!(
            e(image("16UC1", 2, 2, 4, vec![0; 7])),
            ImageError::Truncated { .. }
        ));
        assert!(matches!(
            image("rgb8", 2, 2, 6, vec![0; 12]).to_depth_mm(),
            Err(ImageError::Encoding(_))
        ));
        // Truncated CDR never panics.
        let b = encode(&image("rgb8", 2, 2, 6, vec![0; 12])).unwrap();
        for n in 0..b.len() {
            let _ = decode::<RosImage>(&b[..n]);
        }
        // A forged length (4 GiB of pixels in a 70-byte sample) is an error, not an allocation.
        let mut forged = b.clone();
        let at = forged.len() - 12 - 4;
        forged[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode::<RosImage>(&forged).is_err());
    }

    #[test]
    fn depth_in_both_encodings_and_endianness() {
        let mm = image(
            "16UC1",
            2,
            1,
            4,
            [1500u16, 0].iter().flat_map(|v| v.to_le_bytes()).collect(),
        );
        assert_eq!(mm.to_depth_mm().unwrap().data, vec![1500, 0]);
        let mut be = image("16UC1", 1, 1, 2, 1500u16.to_be_bytes().to_vec());
        be.is_bigendian = 1;
        assert_eq!(be.to_depth_mm().unwrap().data, vec![1500]);
        let m: Vec<u8> = [1.5f32, f32::NAN, -1.0, 70.0, f32::INFINITY]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let d = image("32FC1", 5, 1, 20, m).to_depth_mm().unwrap();
        assert_eq!(d.data, vec![1500, 0, 0, 0, 0]);
    }
}
