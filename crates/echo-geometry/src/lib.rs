//! Capsules (segments with a radius; a sphere is a capsule of zero length) and the distances
//! between them — the geometry of Echo's robot and human body models.

use nalgebra::Vector3;

/// A capsule in world coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capsule {
    /// Segment start.
    pub a: Vector3<f64>,
    /// Segment end.
    pub b: Vector3<f64>,
    /// Radius.
    pub radius: f64,
}

impl Capsule {
    /// A sphere.
    pub fn sphere(c: Vector3<f64>, radius: f64) -> Capsule {
        Capsule { a: c, b: c, radius }
    }

    /// Surface distance to another capsule (negative when they overlap).
    pub fn distance(&self, o: &Capsule) -> f64 {
        segment_distance(&self.a, &self.b, &o.a, &o.b) - self.radius - o.radius
    }
}

/// Smallest distance between segments `p1–q1` and `p2–q2` (Ericson, Real-Time Collision
/// Detection, §5.1.9), robust to degenerate (zero-length) segments.
pub fn segment_distance(
    p1: &Vector3<f64>,
    q1: &Vector3<f64>,
    p2: &Vector3<f64>,
    q2: &Vector3<f64>,
) -> f64 {
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.dot(&d1);
    let e = d2.dot(&d2);
    let f = d2.dot(&r);
    const EPS: f64 = 1e-12;
    let (s, t);
    if a <= EPS && e <= EPS {
        return r.norm();
    }
    if a <= EPS {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(&r);
        if e <= EPS {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s0 = if denom > EPS {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    ((p1 + d1 * s) - (p2 + d2 * t)).norm()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_distances() {
        let v = Vector3::new;
        // Crossing perpendicular segments 1 apart.
        assert!(
            (segment_distance(
                &v(-1.0, 0.0, 0.0),
                &v(1.0, 0.0, 0.0),
                &v(0.0, -1.0, 1.0),
                &v(0.0, 1.0, 1.0)
            ) - 1.0)
                .abs()
                < 1e-12
        );
        // Parallel, offset along the axis.
        assert!(
            (segment_distance(
                &v(0.0, 0.0, 0.0),
                &v(1.0, 0.0, 0.0),
                &v(2.0, 1.0, 0.0),
                &v(3.0, 1.0, 0.0)
            ) - 2f64.sqrt())
            .abs()
                < 1e-12
        );
        // Points.
        assert!(
            (segment_distance(
                &v(0.0, 0.0, 0.0),
                &v(0.0, 0.0, 0.0),
                &v(3.0, 4.0, 0.0),
                &v(3.0, 4.0, 0.0)
            ) - 5.0)
                .abs()
                < 1e-12
        );
        let c = Capsule::sphere(v(0.0, 0.0, 0.0), 0.5);
        assert!((c.distance(&Capsule::sphere(v(2.0, 0.0, 0.0), 0.5)) - 1.0).abs() < 1e-12);
    }
}
