//! Config-driven maps from an estimator's joint set onto the 22 SMPL body joints.
//!
//! Each SMPL-22 joint is either a source joint, a weighted blend of source joints (e.g. the
//! pelvis as the midpoint of COCO's hips), or missing. Maps are data: the built-ins below, or a
//! JSON file in the same shape.

use serde::{Deserialize, Serialize};

use echo_msgs::skeleton::{NUM_JOINTS, SMPL22};
use echo_msgs::KeypointFormat;

/// How one SMPL-22 joint is obtained from the source keypoints (by source joint name).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JointSource {
    /// Copy a source joint.
    Joint(String),
    /// Weighted sum of source joints (weights sum to 1).
    Blend(Vec<(String, f64)>),
    /// Not observable from this estimator: always missing (confidence 0).
    Missing,
}

/// A joint map: one source per SMPL-22 joint, in SMPL order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointMap {
    /// Sources, indexed like [`SMPL22`].
    pub joints: Vec<JointSource>,
}

/// A joint map resolved against a concrete keypoint order.
#[derive(Debug, Clone)]
pub struct ResolvedMap {
    /// Per SMPL joint: (source index, weight) pairs; empty = missing.
    ops: Vec<Vec<(usize, f64)>>,
}

/// Errors in a joint map.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JointMapError {
    /// Wrong number of entries.
    #[error("joint map has {0} entries, expected 22")]
    WrongSize(usize),
    /// A source joint no supported estimator provides.
    #[error("joint map for SMPL joint '{smpl}' refers to unknown source joint '{name}'")]
    UnknownSource {
        /// SMPL joint being defined.
        smpl: &'static str,
        /// Unknown name.
        name: String,
    },
    /// Blend weights that do not sum to 1.
    #[error("joint map for SMPL joint '{0}': blend weights must sum to 1")]
    BadWeights(&'static str),
}

impl JointMap {
    /// Built-in map for a format.
    pub fn builtin(format: KeypointFormat) -> JointMap {
        match format {
            KeypointFormat::Smpl22 | KeypointFormat::Smpl24 => JointMap {
                joints: SMPL22
                    .iter()
                    .map(|n| JointSource::Joint(n.to_string()))
                    .collect(),
            },
            KeypointFormat::Coco17 => coco17(),
        }
    }

    /// Resolve against the keypoint names of `format` actually sent (in their order). A name
    /// of the format that was not sent makes the joints that need it missing.
    pub fn resolve(
        &self,
        format: KeypointFormat,
        sent: &[&str],
    ) -> Result<ResolvedMap, JointMapError> {
        if self.joints.len() != NUM_JOINTS {
            return Err(JointMapError::WrongSize(self.joints.len()));
        }
        let known = format.joint_names();
        let mut ops = Vec::with_capacity(NUM_JOINTS);
        for (k, src) in self.joints.iter().enumerate() {
            let smpl = SMPL22[k];
            let terms: Vec<(String, f64)> = match src {
                JointSource::Joint(n) => vec![(n.clone(), 1.0)],
                JointSource::Blend(v) => {
                    if (v.iter().map(|(_, w)| w).sum::<f64>() - 1.0).abs() > 1e-6 {
                        return Err(JointMapError::BadWeights(smpl));
                    }
                    v.clone()
                }
                JointSource::Missing => vec![],
            };
            let mut op = Vec::with_capacity(terms.len());
            for (n, w) in &terms {
                if !known.contains(&n.as_str()) {
                    return Err(JointMapError::UnknownSource {
                        smpl,
                        name: n.clone(),
                    });
                }
                match sent.iter().position(|x| x == n) {
                    Some(i) => op.push((i, *w)),
                    None => {
                        op.clear();
                        break;
                    }
                }
            }
            ops.push(op);
        }
        Ok(ResolvedMap { ops })
    }
}

impl ResolvedMap {
    /// Map source points and confidences onto SMPL-22. Blended joints take the smallest
    /// confidence of their sources; missing joints get confidence 0.
    pub fn apply(
        &self,
        points: &[[f64; 3]],
        conf: &[f64],
    ) -> ([[f64; 3]; NUM_JOINTS], [f64; NUM_JOINTS]) {
        let mut p = [[0.0; 3]; NUM_JOINTS];
        let mut c = [0.0; NUM_JOINTS];
        for (k, op) in self.ops.iter().enumerate() {
            if op.is_empty() {
                continue;
            }
            let mut cmin = f64::INFINITY;
            for &(i, w) in op {
                for d in 0..3 {
                    p[k][d] += w * points[i][d];
                }
                cmin = cmin.min(conf[i]);
            }
            c[k] = cmin;
        }
        (p, c)
    }
}

/// COCO-17 onto SMPL-22: hips, knees, ankles, shoulders, elbows and wrists are direct. The SMPL
/// pelvis, spine and neck lie on the line from the hip midpoint (t = 0) to the shoulder midpoint
/// (t = 1) at the fractions of the reference body: pelvis 0.16, spine1 0.35, spine2 0.60,
/// spine3 0.74, neck 1.16 (the neck joint sits above the shoulder line). Collars are 39 % of
/// the way from the shoulder midpoint to each shoulder; the head is between the ears.
/// COCO has no feet: they stay missing and the tracker places them from the ankles.
fn coco17() -> JointMap {
    let j = |n: &str| JointSource::Joint(n.into());
    let hips_shoulders = |t: f64| {
        JointSource::Blend(vec![
            ("left_hip".into(), 0.5 * (1.0 - t)),
            ("right_hip".into(), 0.5 * (1.0 - t)),
            ("left_shoulder".into(), 0.5 * t),
            ("right_shoulder".into(), 0.5 * t),
        ])
    };
    let pair =
        |a: &str, wa: f64, b: &str| JointSource::Blend(vec![(a.into(), wa), (b.into(), 1.0 - wa)]);
    JointMap {
        joints: vec![
            hips_shoulders(0.16),
            j("left_hip"),
            j("right_hip"),
            hips_shoulders(0.35),
            j("left_knee"),
            j("right_knee"),
            hips_shoulders(0.60),
            j("left_ankle"),
            j("right_ankle"),
            hips_shoulders(0.74),
            JointSource::Missing,
            JointSource::Missing,
            hips_shoulders(1.16),
            pair("left_shoulder", 0.695, "right_shoulder"),
            pair("right_shoulder", 0.695, "left_shoulder"),
            pair("left_ear", 0.5, "right_ear"),
            j("left_shoulder"),
            j("right_shoulder"),
            j("left_elbow"),
            j("right_elbow"),
            j("left_wrist"),
            j("right_wrist"),
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smpl24_maps_the_first_22_joints() {
        let f = KeypointFormat::Smpl24;
        let m = JointMap::builtin(f).resolve(f, f.joint_names()).unwrap();
        let pts: Vec<[f64; 3]> = (0..24).map(|i| [i as f64, 0.0, 0.0]).collect();
        let (p, c) = m.apply(&pts, &[1.0; 24]);
        assert_eq!(p[21][0], 21.0);
        assert_eq!(c[21], 1.0);
    }

    #[test]
    fn coco_derives_pelvis_spine_and_collars() {
        let f = KeypointFormat::Coco17;
        let m = JointMap::builtin(f).resolve(f, f.joint_names()).unwrap();
        let mut pts = vec![[0.0; 3]; 17];
        pts[11] = [0.0, 0.1, 1.0]; // left hip
        pts[12] = [0.0, -0.1, 1.0];
        pts[5] = [0.0, 0.2, 1.5]; // left shoulder
        pts[6] = [0.0, -0.2, 1.5];
        let (p, c) = m.apply(&pts, &[0.9; 17]);
        assert!((p[0][2] - 1.08).abs() < 1e-12);
        assert!((p[12][2] - 1.58).abs() < 1e-12);
        assert!((p[6][2] - 1.30).abs() < 1e-12);
        assert!((p[13][1] - 0.078).abs() < 1e-12);
        assert_eq!(c[10], 0.0, "feet are not observed");
    }

    #[test]
    fn a_subset_makes_dependent_joints_missing() {
        let f = KeypointFormat::Coco17;
        let sent: Vec<&str> = f
            .joint_names()
            .iter()
            .copied()
            .filter(|n| *n != "right_hip")
            .collect();
        let m = JointMap::builtin(f).resolve(f, &sent).unwrap();
        let (_, c) = m.apply(&vec![[0.0; 3]; 16], &[1.0; 16]);
        assert_eq!(c[0], 0.0, "pelvis needs both hips");
        assert_eq!(c[1], 1.0);
    }

    #[test]
    fn unknown_source_joints_are_named() {
        let f = KeypointFormat::Smpl22;
        let mut map = JointMap::builtin(f);
        map.joints[3] = JointSource::Joint("belly".into());
        let err = map.resolve(f, f.joint_names()).unwrap_err();
        assert!(err.to_string().contains("belly"));
    }

    #[test]
    fn maps_load_from_json() {
        let js = serde_json::to_string(&JointMap::builtin(KeypointFormat::Coco17)).unwrap();
        let back: JointMap = serde_json::from_str(&js).unwrap();
        assert_eq!(back, JointMap::builtin(KeypointFormat::Coco17));
    }
}
