//! Regions of interest: the rotated square crop around one person, and the rules that place it
//! (see the crate documentation for why there are rules instead of a detector).

/// A rotated square in image pixels (continuous coordinates: pixel `k` spans `[k, k + 1]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Roi {
    /// Centre x.
    pub cx: f32,
    /// Centre y.
    pub cy: f32,
    /// Side length.
    pub size: f32,
    /// Rotation, radians: the crop's right axis is `(cos, sin)` in the image (y down), so a
    /// positive angle turns the crop clockwise on screen; 0 = upright.
    pub rotation: f32,
}

/// MediaPipe's enlargement of the alignment square (`RectTransformationCalculator` 1.25).
pub const ROI_SCALE: f32 = 1.25;

impl Roi {
    /// The image point (continuous coordinates) of crop point `(u, v)`, each in [0, 1]
    /// from the crop's top-left corner.
    pub fn to_image(&self, u: f32, v: f32) -> [f32; 2] {
        let (sin, cos) = self.rotation.sin_cos();
        let (du, dv) = ((u - 0.5) * self.size, (v - 0.5) * self.size);
        [self.cx + cos * du - sin * dv, self.cy + sin * du + cos * dv]
    }

    /// MediaPipe's alignment rule (`AlignmentPointsRectsCalculator`, then ×1.25): centred on
    /// `centre` (the hip centre), side `2 × 1.25 × |scale − centre|`, turned so that
    /// `centre → scale` points up in the crop. Points in continuous image coordinates.
    pub fn from_alignment(centre: [f32; 2], scale: [f32; 2]) -> Roi {
        let (dx, dy) = (scale[0] - centre[0], scale[1] - centre[1]);
        Roi {
            cx: centre[0],
            cy: centre[1],
            size: 2.0 * ROI_SCALE * dx.hypot(dy),
            rotation: dx.atan2(-dy),
        }
    }

    /// Finite, with a side of at least `min_size` pixels.
    pub fn is_usable(&self, min_size: f32) -> bool {
        [self.cx, self.cy, self.size, self.rotation]
            .iter()
            .all(|v| v.is_finite())
            && self.size >= min_size
    }

    /// Whether two ROIs are the same within `tol` (centre and side relative to the side, and
    /// rotation in radians).
    pub fn close_to(&self, other: &Roi, tol: f32) -> bool {
        let s = self.size.max(other.size);
        (self.cx - other.cx).abs() <= tol * s
            && (self.cy - other.cy).abs() <= tol * s
            && (self.size - other.size).abs() <= tol * s
            && (self.rotation - other.rotation).abs() <= tol
    }
}

/// The first-frame search crops for a `width × height` image, upright: the square around the
/// whole image (centred, long side), then for every fraction `f` of `levels` a row or column of
/// squares of side `f × short side`, overlapping by half (first and last flush with the image
/// edges). Duplicates are dropped.
pub fn search_crops(width: u32, height: u32, levels: &[f32]) -> Vec<Roi> {
    let (w, h) = (width as f32, height as f32);
    let mut out = vec![Roi {
        cx: w / 2.0,
        cy: h / 2.0,
        size: w.max(h),
        rotation: 0.0,
    }];
    for &f in levels {
        let size = f * w.min(h);
        if size.is_nan() || size < 16.0 {
            continue;
        }
        let positions = |extent: f32| -> Vec<f32> {
            let free = (extent - size).max(0.0);
            let n = (free / (size / 2.0)).ceil() as usize + 1;
            (0..n)
                .map(|i| match n {
                    1 => extent / 2.0,
                    _ => size / 2.0 + free * i as f32 / (n - 1) as f32,
                })
                .collect()
        };
        for &cy in &positions(h) {
            for &cx in &positions(w) {
                let r = Roi {
                    cx,
                    cy,
                    size,
                    rotation: 0.0,
                };
                if !out.iter().any(|q| q.close_to(&r, 0.01)) {
                    out.push(r);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_rule_matches_mediapipe() {
        // Upright person: scale point straight above the hips.
        let r = Roi::from_alignment([100.0, 300.0], [100.0, 100.0]);
        assert_eq!((r.cx, r.cy), (100.0, 300.0));
        assert!((r.size - 500.0).abs() < 1e-3);
        assert!(r.rotation.abs() < 1e-6);
        // Leaning to the image's right: the crop turns clockwise (positive angle), and the
        // crop's top centre lands on the scale point's side.
        let r = Roi::from_alignment([100.0, 300.0], [200.0, 200.0]);
        assert!((r.rotation - std::f32::consts::FRAC_PI_4).abs() < 1e-6);
        let top = r.to_image(0.5, 0.5 - 1.0 / (2.0 * ROI_SCALE));
        assert!((top[0] - 200.0).abs() < 1e-3 && (top[1] - 200.0).abs() < 1e-3);
    }

    #[test]
    fn search_crops_cover_the_image() {
        let c = search_crops(640, 480, &[1.0]);
        // The whole image, then two 480-pixel squares flush with the left and right edges.
        assert_eq!(c.len(), 3);
        assert_eq!((c[0].cx, c[0].cy, c[0].size), (320.0, 240.0, 640.0));
        assert_eq!((c[1].cx, c[2].cx), (240.0, 400.0));
        // A square image: the whole-image crop already is the short-side crop.
        assert_eq!(search_crops(512, 512, &[1.0]).len(), 1);
        // Half the short side: 5 × 3 overlapping squares of 240 pixels, plus the whole image.
        let c = search_crops(640, 480, &[0.5]);
        assert_eq!(c.len(), 1 + 5 * 3);
        for r in &c[1..] {
            assert!(r.cx - r.size / 2.0 >= 0.0 && r.cx + r.size / 2.0 <= 640.0);
            assert!(r.cy - r.size / 2.0 >= 0.0 && r.cy + r.size / 2.0 <= 480.0);
        }
    }
}
