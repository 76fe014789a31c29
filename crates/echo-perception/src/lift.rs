//! Lifting 2D keypoints plus depth to 3D points in the camera optical frame
//! (z forward along the optical axis, x right, y down).

use echo_msgs::{CameraIntrinsics, DepthImage};

/// Back-project pixel `(u, v)` at depth `z` (metres along the optical axis).
pub fn back_project(cam: &CameraIntrinsics, u: f64, v: f64, z: f64) -> [f64; 3] {
    [(u - cam.cx) * z / cam.fx, (v - cam.cy) * z / cam.fy, z]
}

/// Half-size of the window sampled around a keypoint in the depth image (5 × 5 pixels).
pub const DEPTH_WINDOW: i64 = 2;

/// Robust depth at pixel `(u, v)`: the median of the valid (non-zero) readings in a 5 × 5
/// window, in metres; `None` when the pixel is outside the image or every reading is invalid.
pub fn sample_depth(img: &DepthImage, u: f64, v: f64) -> Option<f64> {
    let (w, h) = (img.width as i64, img.height as i64);
    let (cu, cv) = (u.round() as i64, v.round() as i64);
    if cu < 0 || cv < 0 || cu >= w || cv >= h {
        return None;
    }
    let mut vals: Vec<u16> = Vec::with_capacity(25);
    for y in (cv - DEPTH_WINDOW).max(0)..=(cv + DEPTH_WINDOW).min(h - 1) {
        for x in (cu - DEPTH_WINDOW).max(0)..=(cu + DEPTH_WINDOW).min(w - 1) {
            let d = img.depth_mm[(y * w + x) as usize];
            if d > 0 {
                vals.push(d);
            }
        }
    }
    if vals.is_empty() {
        return None;
    }
    vals.sort_unstable();
    Some(vals[vals.len() / 2] as f64 / 1000.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    const CAM: CameraIntrinsics = CameraIntrinsics {
        fx: 500.0,
        fy: 400.0,
        cx: 320.0,
        cy: 240.0,
        width: 640,
        height: 480,
    };

    #[test]
    fn back_projection_inverts_the_pinhole() {
        let p = [0.3, -0.2, 2.5];
        let u = CAM.fx * p[0] / p[2] + CAM.cx;
        let v = CAM.fy * p[1] / p[2] + CAM.cy;
        let q = back_project(&CAM, u, v, p[2]);
        for k in 0..3 {
            assert!((p[k] - q[k]).abs() < 1e-12);
        }
    }

    #[test]
    fn depth_sampling_ignores_holes_and_outliers() {
        let mut img = DepthImage {
            width: 10,
            height: 10,
            depth_mm: vec![2000; 100],
        };
        img.depth_mm[5 * 10 + 5] = 0; // hole at the keypoint
        img.depth_mm[5 * 10 + 6] = 9000; // a far outlier
        assert_eq!(sample_depth(&img, 5.0, 5.0), Some(2.0));
        assert_eq!(sample_depth(&img, -1.0, 5.0), None);
        let empty = DepthImage {
            width: 10,
            height: 10,
            depth_mm: vec![0; 100],
        };
        assert_eq!(sample_depth(&empty, 5.0, 5.0), None);
    }
}
