//! Bridge configuration (JSON file or defaults).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::joint_map::JointMap;
use crate::one_euro::OneEuroParams;

/// Interaction-partner selection.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PartnerConfig {
    /// Farthest a partner may be from the robot (pelvis, on the floor), metres.
    pub max_distance_m: f64,
    /// Smallest cosine between the person's facing direction and the direction to the robot.
    pub min_facing_cos: f64,
    /// A new candidate must be this much closer than the current partner to take over, metres.
    pub switch_margin_m: f64,
}

impl Default for PartnerConfig {
    fn default() -> Self {
        PartnerConfig {
            max_distance_m: 4.0,
            min_facing_cos: 0.5,
            switch_margin_m: 0.3,
        }
    }
}

/// Everything the bridge can be told. Missing keys take the defaults; unknown keys are an error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BridgeConfig {
    /// Output (model) rate, Hz.
    pub rate_hz: f64,
    /// Frames older than this at arrival (receiver wall clock − capture stamp) are rejected, ms.
    pub max_age_ms: f64,
    /// Frames stamped further than this in the future are rejected (clock skew guard), ms.
    pub max_future_ms: f64,
    /// Largest gap between an image and the robot joint state used to place the camera, ms.
    pub max_state_gap_ms: f64,
    /// Keypoints below this confidence count as missing.
    pub min_confidence: f64,
    /// Fewest observed SMPL-22 joints for a usable detection.
    pub min_observed_joints: usize,
    /// A missing joint is filled from the track's history for at most this long, s.
    pub max_fill_s: f64,
    /// A bone is implausible outside [lo, hi] × the reference length (+ 3 cm slack).
    pub bone_ratio: (f64, f64),
    /// More implausible bones than this rejects the detection.
    pub max_bad_bones: usize,
    /// Fastest plausible pelvis speed (m/s); beyond it a detection is a teleport.
    pub max_speed_mps: f64,
    /// Association gate around a track's predicted pelvis, metres (plus max_speed × Δt).
    pub gate_m: f64,
    /// Consecutive hits before a track is published.
    pub confirm_frames: u32,
    /// A track unseen for this long is dropped, s.
    pub track_timeout_s: f64,
    /// Output grid points may interpolate across input gaps up to this long, s.
    pub max_interp_gap_s: f64,
    /// After a track's last observation, output holds it for this long, s.
    pub hold_s: f64,
    /// Smoothing.
    pub one_euro: OneEuroParams,
    /// Added to sampled depth (surface → joint centre), metres.
    pub depth_bias_m: f64,
    /// Partner selection.
    pub partner: PartnerConfig,
    /// Joint-map overrides by format name ("smpl24", "coco17", "smpl22").
    pub joint_maps: BTreeMap<String, JointMap>,
}

impl Default for BridgeConfig {
    fn default() -> Self {
        BridgeConfig {
            rate_hz: 15.0,
            max_age_ms: 500.0,
            max_future_ms: 100.0,
            max_state_gap_ms: 60.0,
            min_confidence: 0.3,
            min_observed_joints: 10,
            max_fill_s: 0.5,
            bone_ratio: (0.45, 1.6),
            max_bad_bones: 4,
            max_speed_mps: 4.0,
            gate_m: 0.5,
            confirm_frames: 3,
            track_timeout_s: 1.0,
            max_interp_gap_s: 0.5,
            hold_s: 0.2,
            one_euro: OneEuroParams::default(),
            depth_bias_m: 0.0,
            partner: PartnerConfig::default(),
            joint_maps: BTreeMap::new(),
        }
    }
}

impl BridgeConfig {
    /// Load from a JSON file; errors name the file and the key.
    pub fn from_file(path: &std::path::Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let cfg: BridgeConfig =
            serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
        cfg.check()
            .map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(cfg)
    }

    /// Reject values that make no sense.
    pub fn check(&self) -> Result<(), String> {
        let pos = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("{name} must be a positive number, not {v}"))
            }
        };
        pos("rate_hz", self.rate_hz)?;
        pos("max_age_ms", self.max_age_ms)?;
        pos("max_state_gap_ms", self.max_state_gap_ms)?;
        pos("max_speed_mps", self.max_speed_mps)?;
        pos("gate_m", self.gate_m)?;
        pos("track_timeout_s", self.track_timeout_s)?;
        pos("one_euro.min_cutoff_hz", self.one_euro.min_cutoff_hz)?;
        if !(0.0..=1.0).contains(&self.min_confidence) {
            return Err("min_confidence must be in [0, 1]".into());
        }
        for k in self.joint_maps.keys() {
            if !["smpl22", "smpl24", "coco17"].contains(&k.as_str()) {
                return Err(format!(
                    "joint_maps: unknown format '{k}' (smpl22, smpl24, coco17)"
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_keys_and_bad_values_are_named() {
        let e = serde_json::from_str::<BridgeConfig>(r#"{"rate_hz": 15, "rate": 3}"#).unwrap_err();
        assert!(e.to_string().contains("rate"), "{e}");
        let cfg: BridgeConfig = serde_json::from_str(r#"{"rate_hz": -1}"#).unwrap();
        assert!(cfg.check().unwrap_err().contains("rate_hz"));
        let cfg: BridgeConfig = serde_json::from_str(r#"{"gate_m": 0.8}"#).unwrap();
        assert_eq!(cfg.gate_m, 0.8);
        assert_eq!(cfg.rate_hz, 15.0);
    }
}
