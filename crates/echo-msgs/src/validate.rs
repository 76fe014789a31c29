//! Validation helpers and the [`Validate`] trait.

use crate::ValidationError;

/// Structural validation of a decoded message (finite numbers, sizes, names, quaternions).
/// Checks that need receiver state (sequence order, staleness, robot joint set) live with the
/// receiver ([`crate::SeqTracker`], [`check_joint_names`]).
pub trait Validate {
    /// `Ok` if the message is well formed.
    fn validate(&self) -> Result<(), ValidationError>;
}

/// Every value finite.
pub fn check_finite(field: &str, values: &[f64]) -> Result<(), ValidationError> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(ValidationError::NonFinite {
            field: format!("{field}[{i}]"),
        }),
    }
}

/// Every 3-vector finite.
pub fn check_finite3(field: &str, values: &[[f64; 3]]) -> Result<(), ValidationError> {
    check_finite(field, values.as_flattened())
}

/// Exact length.
pub fn check_len(field: &str, got: usize, expected: usize) -> Result<(), ValidationError> {
    if got == expected {
        Ok(())
    } else {
        Err(ValidationError::WrongSize {
            field: field.to_string(),
            got,
            expected,
        })
    }
}

/// Value in `[min, max]` (and finite).
pub fn check_range(field: &str, value: f64, min: f64, max: f64) -> Result<(), ValidationError> {
    if !value.is_finite() {
        return Err(ValidationError::NonFinite {
            field: field.to_string(),
        });
    }
    if value < min || value > max {
        return Err(ValidationError::OutOfRange {
            field: field.to_string(),
            value,
            min,
            max,
        });
    }
    Ok(())
}

/// Tolerance on quaternion norms (JSON round trips and f32 producers stay well inside it).
pub const UNIT_QUATERNION_TOLERANCE: f64 = 1e-3;

/// Quaternion `[x, y, z, w]` finite and of unit norm within [`UNIT_QUATERNION_TOLERANCE`].
pub fn check_unit_quaternion(field: &str, q: &[f64; 4]) -> Result<(), ValidationError> {
    check_finite(field, q)?;
    let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > UNIT_QUATERNION_TOLERANCE {
        return Err(ValidationError::NotUnitQuaternion {
            field: field.to_string(),
            norm,
        });
    }
    Ok(())
}

/// Identifiers that become part of key expressions: non-empty `[A-Za-z0-9_-]`.
pub fn check_identifier(field: &str, value: &str) -> Result<(), ValidationError> {
    let ok = !value.is_empty()
        && value.len() <= 64
        && value
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-');
    if ok {
        Ok(())
    } else {
        Err(ValidationError::BadIdentifier {
            field: field.to_string(),
            value: value.chars().take(80).collect(),
        })
    }
}

/// Every name in `names` is one of `known`, and none repeats.
pub fn check_joint_names<S: AsRef<str>>(
    field: &str,
    names: &[S],
    known: &[&str],
) -> Result<(), ValidationError> {
    for (i, n) in names.iter().enumerate() {
        let n = n.as_ref();
        if !known.contains(&n) {
            return Err(ValidationError::UnknownJoint {
                field: field.to_string(),
                name: n.chars().take(80).collect(),
            });
        }
        if names[..i].iter().any(|m| m.as_ref() == n) {
            return Err(ValidationError::Other(format!(
                "{field}: joint '{n}' appears twice"
            )));
        }
    }
    Ok(())
}

/// Strictly increasing sequence.
pub fn check_increasing(field: &str, values: &[f64]) -> Result<(), ValidationError> {
    check_finite(field, values)?;
    match values.windows(2).position(|w| w[1] <= w[0]) {
        None => Ok(()),
        Some(i) => Err(ValidationError::NotIncreasing {
            field: field.to_string(),
            index: i + 1,
        }),
    }
}
