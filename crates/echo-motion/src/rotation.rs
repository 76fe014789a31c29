//! Rotation conversions between quaternions, matrices, the 6D representation and axis-angle.

use nalgebra::{Matrix3, Rotation3, Unit, UnitQuaternion, Vector3};

/// 6D representation: the first two columns of the rotation matrix, flattened row-wise
/// `[R00, R01, R10, R11, R20, R21]`.
pub fn to_6d(r: &Rotation3<f64>) -> [f64; 6] {
    let m = r.matrix();
    [
        m[(0, 0)],
        m[(0, 1)],
        m[(1, 0)],
        m[(1, 1)],
        m[(2, 0)],
        m[(2, 1)],
    ]
}

/// Back from the 6D representation by Gram-Schmidt (tolerates non-orthogonal input).
pub fn from_6d(v: &[f64; 6]) -> Rotation3<f64> {
    let a = Vector3::new(v[0], v[2], v[4]);
    let b = Vector3::new(v[1], v[3], v[5]);
    let x = a.normalize();
    let y = (b - x * x.dot(&b)).normalize();
    let z = x.cross(&y);
    Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]))
}

/// Axis-angle vector (axis × angle) of a rotation.
pub fn to_axis_angle(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    q.scaled_axis()
}

/// Rotation from an axis-angle vector.
pub fn from_axis_angle(v: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_scaled_axis(*v)
}

/// `[x, y, z, w]` array of a quaternion (the wire order).
pub fn quat_to_xyzw(q: &UnitQuaternion<f64>) -> [f64; 4] {
    [q.i, q.j, q.k, q.w]
}

/// Quaternion from `[x, y, z, w]` (normalised).
pub fn quat_from_xyzw(v: &[f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(v[3], v[0], v[1], v[2]))
}

/// The smallest rotation taking direction `from` onto direction `to` (identity if either is ~0).
pub fn swing(from: &Vector3<f64>, to: &Vector3<f64>) -> UnitQuaternion<f64> {
    match (Unit::try_new(*from, 1e-9), Unit::try_new(*to, 1e-9)) {
        (Some(a), Some(b)) => UnitQuaternion::rotation_between_axis(&a, &b).unwrap_or_else(|| {
            // Opposite directions: half turn about any axis perpendicular to `a`.
            let perp = a.cross(&Vector3::x());
            let perp = if perp.norm() < 1e-6 {
                a.cross(&Vector3::y())
            } else {
                perp
            };
            UnitQuaternion::from_axis_angle(&Unit::new_normalize(perp), std::f64::consts::PI)
        }),
        _ => UnitQuaternion::identity(),
    }
}

/// A rotation whose y axis is along `across` and z axis is as close as possible to `up`.
pub fn frame_from_across_up(across: &Vector3<f64>, up: &Vector3<f64>) -> Option<Rotation3<f64>> {
    let y = Unit::try_new(*across, 1e-9)?;
    let z = Unit::try_new(up - y.into_inner() * y.dot(up), 1e-9)?;
    let x = y.cross(&z);
    Some(Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[
        x,
        y.into_inner(),
        z.into_inner(),
    ])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn six_d_and_axis_angle_round_trip() {
        let q = UnitQuaternion::from_euler_angles(0.3, -1.1, 2.5);
        let r = q.to_rotation_matrix();
        assert!((from_6d(&to_6d(&r)).matrix() - r.matrix()).norm() < 1e-12);
        assert!((from_axis_angle(&to_axis_angle(&q)).coords - q.coords).norm() < 1e-12);
        assert!((quat_from_xyzw(&quat_to_xyzw(&q)).coords - q.coords).norm() < 1e-12);
    }

    #[test]
    fn swing_handles_opposite_vectors() {
        let a = Vector3::new(0.0, 0.0, 1.0);
        let s = swing(&a, &-a);
        assert!((s * a + a).norm() < 1e-12);
        let b = Vector3::new(1.0, 2.0, -0.5);
        assert!(((swing(&a, &b) * a) - b.normalize()).norm() < 1e-12);
    }
}
