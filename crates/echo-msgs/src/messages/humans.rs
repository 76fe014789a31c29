//! Messages on the edge perception bridge → forecaster, safety, retargeter.

use super::*;

/// One person's 22-joint pose in `base_footprint`, with what the models need.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HumanPose {
    /// Joint positions in the message frame, metres, SMPL-22 order.
    pub joints: Vec<[f64; 3]>,
    /// Pelvis position in the message frame.
    pub root_position: [f64; 3],
    /// Root (body) orientation as a unit quaternion `[x, y, z, w]`: x = facing direction
    /// on the floor, z = up.
    pub root_orientation: [f64; 4],
    /// Joint positions relative to the root, expressed in the root frame.
    pub local_positions: Vec<[f64; 3]>,
    /// Per-joint rotation relative to the parent joint (`[x, y, z, w]`), SMPL-22 order;
    /// entry 0 is the pelvis rotation relative to the root frame.
    pub local_rotations: Vec<[f64; 4]>,
    /// Per-joint confidence in [0, 1]; joints filled in by the bridge carry a decayed value.
    pub confidence: Vec<f64>,
}

impl HumanPose {
    /// Structural checks with `field` as the error path prefix.
    pub fn validate_at(&self, field: &str) -> Result<(), ValidationError> {
        check_len(&format!("{field}.joints"), self.joints.len(), NUM_JOINTS)?;
        check_finite3(&format!("{field}.joints"), &self.joints)?;
        check_finite(&format!("{field}.root_position"), &self.root_position)?;
        check_unit_quaternion(&format!("{field}.root_orientation"), &self.root_orientation)?;
        check_len(
            &format!("{field}.local_positions"),
            self.local_positions.len(),
            NUM_JOINTS,
        )?;
        check_finite3(&format!("{field}.local_positions"), &self.local_positions)?;
        check_len(
            &format!("{field}.local_rotations"),
            self.local_rotations.len(),
            NUM_JOINTS,
        )?;
        for (i, q) in self.local_rotations.iter().enumerate() {
            check_unit_quaternion(&format!("{field}.local_rotations[{i}]"), q)?;
        }
        check_len(
            &format!("{field}.confidence"),
            self.confidence.len(),
            NUM_JOINTS,
        )?;
        for (i, c) in self.confidence.iter().enumerate() {
            check_range(&format!("{field}.confidence[{i}]"), *c, 0.0, 1.0)?;
        }
        Ok(())
    }
}

/// A tracked person.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HumanTrack {
    /// Stable id while the person stays in view.
    pub track_id: u32,
    /// Current pose.
    pub pose: HumanPose,
    /// Root velocity in the message frame, m/s.
    pub root_velocity: [f64; 3],
    /// Number of output frames this track has existed.
    pub age_frames: u32,
    /// Joints (by SMPL-22 index) whose value was filled in from history in this frame.
    #[serde(default)]
    pub filled_joints: Vec<u8>,
}

impl HumanTrack {
    /// A track from joint positions alone — root at the pelvis, identity orientation, full
    /// confidence, no local pose — for tests and stand-ins.
    pub fn from_joints(track_id: u32, joints: Vec<[f64; 3]>) -> HumanTrack {
        HumanTrack {
            track_id,
            pose: HumanPose {
                root_position: joints.first().copied().unwrap_or([0.0; 3]),
                confidence: vec![1.0; joints.len()],
                joints,
                root_orientation: [0.0, 0.0, 0.0, 1.0],
                local_positions: vec![],
                local_rotations: vec![],
            },
            root_velocity: [0.0; 3],
            age_frames: 1,
            filled_joints: vec![],
        }
    }
}

/// Every tracked person at one instant, at the model rate. Frame: `base_footprint`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HumanSkeletons {
    /// Header (`stamp_ns` = the instant these poses describe).
    pub header: Header,
    /// Output rate of the stream, Hz.
    pub rate_hz: f64,
    /// All tracks.
    pub tracks: Vec<HumanTrack>,
    /// Track id of the interaction partner, if any.
    pub partner_id: Option<u32>,
}
message!(HumanSkeletons, "human_skeletons");

impl Validate for HumanSkeletons {
    fn validate(&self) -> Result<(), ValidationError> {
        check_range("rate_hz", self.rate_hz, 0.1, 1000.0)?;
        if self.tracks.len() > MAX_PEOPLE {
            return Err(ValidationError::OutOfRange {
                field: "tracks".into(),
                value: self.tracks.len() as f64,
                min: 0.0,
                max: MAX_PEOPLE as f64,
            });
        }
        for (i, t) in self.tracks.iter().enumerate() {
            t.pose.validate_at(&format!("tracks[{i}].pose"))?;
            check_finite(&format!("tracks[{i}].root_velocity"), &t.root_velocity)?;
            if let Some(j) = t.filled_joints.iter().find(|j| **j as usize >= NUM_JOINTS) {
                return Err(ValidationError::OutOfRange {
                    field: format!("tracks[{i}].filled_joints"),
                    value: *j as f64,
                    min: 0.0,
                    max: (NUM_JOINTS - 1) as f64,
                });
            }
        }
        if let Some(p) = self.partner_id {
            if !self.tracks.iter().any(|t| t.track_id == p) {
                return Err(ValidationError::Other(format!(
                    "partner_id {p} is not among the tracks"
                )));
            }
        }
        Ok(())
    }
}
