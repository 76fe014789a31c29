//! Safety configuration: every parameter with its default (docs/SAFETY.md explains each).

use std::collections::BTreeMap;

use echo_robot::limits::LimitOverride;
use serde::{Deserialize, Serialize};

/// Speed and separation monitoring (ISO/TS 15066 style).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SeparationConfig {
    /// Human approach speed assumed, m/s (ISO 13855: 1.6 beyond 0.5 m, 2.0 within).
    pub human_speed_mps: f64,
    /// Human speed assumed within 0.5 m.
    pub human_speed_close_mps: f64,
    /// Reaction time of the whole loop (perception age + one control cycle), s.
    pub reaction_time_s: f64,
    /// Intrusion distance C (reach before detection), m.
    pub intrusion_m: f64,
    /// Human position uncertainty Zd, m.
    pub human_uncertainty_m: f64,
    /// Robot position uncertainty Zr, m.
    pub robot_uncertainty_m: f64,
    /// Beyond the protective distance by this much, full speed; in between, linear scaling.
    pub slow_zone_m: f64,
    /// Forecast frames used (the first N future frames).
    pub forecast_frames: usize,
    /// Skeletons older than this are ignored (the person is treated as unseen), s.
    pub human_timeout_s: f64,
    /// Contact mode: speed cap of every robot capsule end near the partner, m/s.
    pub contact_speed_mps: f64,
    /// Contact mode: the speed cap applies within this distance of the partner, m.
    pub contact_zone_m: f64,
    /// Contact mode: every robot part keeps this far from the partner's head, m.
    pub head_clearance_m: f64,
    /// Contact mode: every robot part keeps this far from the partner's regions that are not
    /// meant to be touched (e.g. torso and legs in a handshake), m.
    pub body_clearance_m: f64,
}

impl Default for SeparationConfig {
    fn default() -> Self {
        SeparationConfig {
            human_speed_mps: 1.6,
            human_speed_close_mps: 2.0,
            reaction_time_s: 0.1,
            intrusion_m: 0.1,
            human_uncertainty_m: 0.1,
            robot_uncertainty_m: 0.02,
            slow_zone_m: 0.5,
            forecast_frames: 8,
            human_timeout_s: 0.5,
            contact_speed_mps: 0.25,
            contact_zone_m: 0.5,
            head_clearance_m: 0.3,
            body_clearance_m: 0.1,
        }
    }
}

/// Base (differential drive) limits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BaseConfig {
    /// Move the base at all.
    pub enabled: bool,
    /// Forward speed limit, m/s.
    pub max_linear_mps: f64,
    /// Backward speed limit, m/s.
    pub max_reverse_mps: f64,
    /// Turn rate limit, rad/s.
    pub max_angular_rps: f64,
    /// Linear acceleration limit, m/s².
    pub max_linear_acc: f64,
    /// Angular acceleration limit, rad/s².
    pub max_angular_acc: f64,
}

impl Default for BaseConfig {
    fn default() -> Self {
        BaseConfig {
            enabled: true,
            max_linear_mps: 0.3,
            max_reverse_mps: 0.1,
            max_angular_rps: 0.6,
            max_linear_acc: 0.5,
            max_angular_acc: 1.0,
        }
    }
}

/// Everything the safety service can be told.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SafetyConfig {
    /// Control cycle rate, Hz (one command per cycle).
    pub rate_hz: f64,
    /// Use the URDF soft limits (true) or the hard limits.
    pub soft_limits: bool,
    /// Per-joint limit overrides.
    pub limits: BTreeMap<String, LimitOverride>,
    /// Tracking part of each command, s (a stop to rest always follows it).
    pub horizon_s: f64,
    /// Spacing of trajectory points in a command, in control cycles.
    pub point_every: usize,
    /// Time constant of position tracking, s.
    pub tracking_time_constant_s: f64,
    /// No valid plan for this long (receiver's clock) → stop, ms.
    pub plan_deadline_ms: f64,
    /// No joint state for this long → stop, ms.
    pub state_deadline_ms: f64,
    /// A plan whose first point is further than this from the measured state is rejected, rad (m for the torso).
    pub start_tolerance: f64,
    /// Commanded and measured positions further apart than this → stop and hold until they
    /// agree again (or an operator's e-stop reset re-anchors at rest), rad (m for the torso).
    pub tracking_tolerance: f64,
    /// Measured positions may exceed the URDF hard limits by this much (encoder noise at a
    /// mechanical stop); beyond it a sample is a sensor fault. Also the slack of the jump rule.
    /// In the joint's units (rad, m).
    pub measured_tolerance: f64,
    /// Receipt jitter allowed by the jump rule on top of the time between samples, s.
    pub state_jitter_s: f64,
    /// The only sender (`header.source`) whose joint states are accepted; `None`: the first one
    /// heard (ROS 2 joint states arrive as source `ros2`).
    pub state_source: Option<String>,
    /// The accepted joint-state source is released after this long without a sample, ms.
    pub state_source_timeout_ms: f64,
    /// A sensor fault clears after this long with only plausible samples, ms.
    pub fault_clear_ms: f64,
    /// Speed scale of a group while a joint of it is outside its soft range, moving inward.
    pub recovery_speed_scale: f64,
    /// Self-collision: capsules may not come closer than this while approaching, m.
    pub self_collision_margin_m: f64,
    /// Liveliness tokens that must be present (lost → stop): e.g. the robot interface.
    pub required_alive: Vec<String>,
    /// Separation monitoring.
    pub separation: SeparationConfig,
    /// Base limits.
    pub base: BaseConfig,
}

impl Default for SafetyConfig {
    fn default() -> Self {
        SafetyConfig {
            rate_hz: 50.0,
            soft_limits: true,
            limits: BTreeMap::new(),
            horizon_s: 0.2,
            point_every: 2,
            tracking_time_constant_s: 0.15,
            plan_deadline_ms: 200.0,
            state_deadline_ms: 100.0,
            start_tolerance: 0.35,
            tracking_tolerance: 0.25,
            measured_tolerance: 0.01,
            state_jitter_s: 0.05,
            state_source: None,
            state_source_timeout_ms: 1000.0,
            fault_clear_ms: 500.0,
            recovery_speed_scale: 0.2,
            self_collision_margin_m: 0.01,
            required_alive: vec![],
            separation: SeparationConfig::default(),
            base: BaseConfig::default(),
        }
    }
}

impl SafetyConfig {
    /// Control period, s.
    pub fn dt(&self) -> f64 {
        1.0 / self.rate_hz
    }

    /// Load from a JSON file; errors name the file and the key.
    pub fn from_file(path: &std::path::Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let c: SafetyConfig =
            serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
        c.check().map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(c)
    }

    /// Reject nonsense.
    pub fn check(&self) -> Result<(), String> {
        for (n, v) in [
            ("rate_hz", self.rate_hz),
            ("horizon_s", self.horizon_s),
            ("tracking_time_constant_s", self.tracking_time_constant_s),
            ("plan_deadline_ms", self.plan_deadline_ms),
            ("state_deadline_ms", self.state_deadline_ms),
            ("start_tolerance", self.start_tolerance),
            ("tracking_tolerance", self.tracking_tolerance),
            ("measured_tolerance", self.measured_tolerance),
            ("state_jitter_s", self.state_jitter_s),
            ("state_source_timeout_ms", self.state_source_timeout_ms),
            ("fault_clear_ms", self.fault_clear_ms),
            ("recovery_speed_scale", self.recovery_speed_scale),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{n} must be a positive number, not {v}"));
            }
        }
        if self.recovery_speed_scale > 1.0 {
            return Err("recovery_speed_scale must be at most 1".into());
        }
        if self.point_every == 0 {
            return Err("point_every must be at least 1".into());
        }
        if self.self_collision_margin_m.is_nan() || self.self_collision_margin_m < 0.0 {
            return Err("self_collision_margin_m must be ≥ 0".into());
        }
        Ok(())
    }
}
