//! Closest points between segments.

use nalgebra::Vector3;

/// The closest points of segments `p1–q1` and `p2–q2` (Ericson, Real-Time Collision Detection,
/// §5.1.9), robust to zero-length segments.
pub fn closest_points(
    p1: &Vector3<f64>,
    q1: &Vector3<f64>,
    p2: &Vector3<f64>,
    q2: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    const EPS: f64 = 1e-12;
    let (d1, d2, r) = (q1 - p1, q2 - p2, p1 - p2);
    let (a, e, f) = (d1.dot(&d1), d2.dot(&d2), d2.dot(&r));
    let (s, t) = if a <= EPS && e <= EPS {
        (0.0, 0.0)
    } else if a <= EPS {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(&r);
        if e <= EPS {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let s = if denom > EPS {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let t = (b * s + f) / e;
            if t < 0.0 {
                ((-c / a).clamp(0.0, 1.0), 0.0)
            } else if t > 1.0 {
                (((b - c) / a).clamp(0.0, 1.0), 1.0)
            } else {
                (s, t)
            }
        }
    };
    (p1 + d1 * s, p2 + d2 * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_points_agree_with_the_segment_distance() {
        let v = Vector3::new;
        let cases = [
            (
                v(-1.0, 0.0, 0.0),
                v(1.0, 0.0, 0.0),
                v(0.0, -1.0, 1.0),
                v(0.0, 1.0, 1.0),
            ),
            (
                v(0.0, 0.0, 0.0),
                v(1.0, 0.0, 0.0),
                v(2.0, 1.0, 0.0),
                v(3.0, 1.0, 0.0),
            ),
            (
                v(0.0, 0.0, 0.0),
                v(0.0, 0.0, 0.0),
                v(3.0, 4.0, 0.0),
                v(3.0, 4.0, 0.0),
            ),
            (
                v(0.0, 0.0, 0.0),
                v(0.0, 0.0, 2.0),
                v(1.0, 0.0, 1.0),
                v(1.0, 0.0, 1.0),
            ),
        ];
        for (p1, q1, p2, q2) in cases {
            let (a, b) = closest_points(&p1, &q1, &p2, &q2);
            let d = echo_geometry::segment_distance(&p1, &q1, &p2, &q2);
            assert!(((a - b).norm() - d).abs() < 1e-12);
        }
        let (a, b) = closest_points(&cases[3].0, &cases[3].1, &cases[3].2, &cases[3].3);
        assert_eq!((a, b), (v(0.0, 0.0, 1.0), v(1.0, 0.0, 1.0)));
    }
}
