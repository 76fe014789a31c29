//! Multi-person tracking in `base_footprint`: association by pelvis distance, bone-length and
//! teleport plausibility, short-gap filling, One-Euro smoothing, and partner selection.

use echo_motion::skeleton::{self, j, Body, NUM_JOINTS, PARENTS};
use nalgebra::{UnitQuaternion, Vector3};

use crate::config::BridgeConfig;
use crate::one_euro::OneEuro3;

/// One person's joints in `base_footprint` from one image, before tracking.
#[derive(Debug, Clone)]
pub struct Detection {
    /// The estimator's id hint.
    pub detection_id: Option<u32>,
    /// SMPL-22 joints.
    pub joints: [Vector3<f64>; NUM_JOINTS],
    /// Per-joint confidence.
    pub confidence: [f64; NUM_JOINTS],
}

/// Why a detection was not used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DetectionError {
    /// Too few joints seen, or no pelvis.
    #[error("only {observed} joints observed (need {needed})")]
    TooFewJoints {
        /// Joints seen.
        observed: usize,
        /// Joints needed.
        needed: usize,
    },
    /// Neither the pelvis nor the hips and spine to place it were seen.
    #[error("pelvis not observed and not recoverable from the hips and spine")]
    NoPelvis,
    /// Too many bones of implausible length.
    #[error("{bad} bones have implausible lengths (first: {first})")]
    ImplausibleBones {
        /// How many.
        bad: usize,
        /// The first offending joint.
        first: &'static str,
    },
    /// The detection jumped further than a person can move.
    #[error("track {track} jumped {distance_m:.2} m in {dt_s:.3} s")]
    Teleport {
        /// Track id.
        track: u32,
        /// Jump.
        distance_m: f64,
        /// Time.
        dt_s: f64,
    },
}

impl DetectionError {
    /// Short label for counters.
    pub fn reason(&self) -> &'static str {
        match self {
            DetectionError::TooFewJoints { .. } => "too_few_joints",
            DetectionError::NoPelvis => "no_pelvis",
            DetectionError::ImplausibleBones { .. } => "implausible_bones",
            DetectionError::Teleport { .. } => "teleport",
        }
    }
}

/// A filtered observation of a track.
#[derive(Debug, Clone)]
pub struct Observation {
    /// Capture stamp.
    pub stamp_ns: u64,
    /// Smoothed joints.
    pub joints: [Vector3<f64>; NUM_JOINTS],
    /// Confidence (decayed for filled joints).
    pub confidence: [f64; NUM_JOINTS],
    /// Joints filled in this frame.
    pub filled: Vec<u8>,
}

/// A tracked person.
#[derive(Debug, Clone)]
pub struct Track {
    /// Stable id.
    pub id: u32,
    /// Consecutive hits (saturating).
    pub hits: u32,
    /// Published once confirmed.
    pub confirmed: bool,
    /// Output frames emitted for this track.
    pub age_frames: u32,
    detection_id: Option<u32>,
    filters: Vec<OneEuro3>,
    /// Last two observations (older first).
    pub history: Vec<Observation>,
    /// Per joint: last observed position relative to the pelvis in the heading frame, its
    /// stamp and confidence.
    memory: [Option<(Vector3<f64>, u64, f64)>; NUM_JOINTS],
}

impl Track {
    /// Latest observation.
    pub fn last(&self) -> Option<&Observation> {
        self.history.last()
    }
}

/// All tracks plus the partner choice.
#[derive(Debug, Clone, Default)]
pub struct Tracker {
    tracks: Vec<Track>,
    next_id: u32,
    partner: Option<u32>,
}

fn reference_bones() -> [f64; NUM_JOINTS] {
    Body::with_height(1.75).bone_lengths()
}

impl Tracker {
    /// No tracks.
    pub fn new() -> Self {
        Self::default()
    }

    /// Current tracks.
    pub fn tracks(&self) -> &[Track] {
        &self.tracks
    }

    /// Current partner track id.
    pub fn partner(&self) -> Option<u32> {
        self.partner
    }

    /// Check a detection's plausibility: joints with implausible bones are marked missing;
    /// too many of them, or too few joints, rejects it.
    pub fn check(cfg: &BridgeConfig, d: &mut Detection) -> Result<(), DetectionError> {
        let refs = reference_bones();
        let mut bad = 0;
        let mut first = "";
        for k in 1..NUM_JOINTS {
            let parent = PARENTS[k] as usize;
            if d.confidence[k] < cfg.min_confidence || d.confidence[parent] < cfg.min_confidence {
                continue;
            }
            let len = (d.joints[k] - d.joints[parent]).norm();
            let (lo, hi) = (
                cfg.bone_ratio.0 * refs[k],
                cfg.bone_ratio.1 * refs[k] + 0.03,
            );
            if !(lo - 0.03..=hi).contains(&len) {
                bad += 1;
                if first.is_empty() {
                    first = skeleton::JOINT_NAMES[k];
                }
                d.confidence[k] = 0.0;
            }
        }
        if bad > cfg.max_bad_bones {
            return Err(DetectionError::ImplausibleBones { bad, first });
        }
        let observed = d
            .confidence
            .iter()
            .filter(|c| **c >= cfg.min_confidence)
            .count();
        if observed < cfg.min_observed_joints {
            return Err(DetectionError::TooFewJoints {
                observed,
                needed: cfg.min_observed_joints,
            });
        }
        if d.confidence[j::PELVIS] < cfg.min_confidence {
            // The pelvis lies 45 % of the way from the hip midpoint to spine1 (reference body).
            let c = d.confidence[j::L_HIP]
                .min(d.confidence[j::R_HIP])
                .min(d.confidence[j::SPINE1]);
            if c < cfg.min_confidence {
                return Err(DetectionError::NoPelvis);
            }
            let mid = (d.joints[j::L_HIP] + d.joints[j::R_HIP]) * 0.5;
            d.joints[j::PELVIS] = mid + (d.joints[j::SPINE1] - mid) * 0.45;
            d.confidence[j::PELVIS] = c;
        }
        Ok(())
    }

    /// Update with the detections of one image at `stamp_ns`. Returns per-detection errors
    /// (the others were used).
    pub fn update(
        &mut self,
        cfg: &BridgeConfig,
        stamp_ns: u64,
        detections: Vec<Detection>,
    ) -> Vec<(usize, DetectionError)> {
        let mut errors = vec![];
        let mut usable = vec![];
        let mut index = vec![];
        for (i, mut d) in detections.into_iter().enumerate() {
            match Self::check(cfg, &mut d) {
                Ok(()) => {
                    usable.push(d);
                    index.push(i);
                }
                Err(e) => errors.push((i, e)),
            }
        }
        // Greedy association by pelvis distance to each track's predicted pelvis.
        let mut pairs = vec![];
        for (di, d) in usable.iter().enumerate() {
            for (ti, t) in self.tracks.iter().enumerate() {
                let Some(last) = t.last() else { continue };
                let dt = stamp_ns.saturating_sub(last.stamp_ns) as f64 / 1e9;
                let dist = (d.joints[0] - predict_root(t, stamp_ns)).norm();
                let gate = cfg.gate_m + cfg.max_speed_mps * dt;
                if dist <= gate {
                    pairs.push((dist, di, ti));
                } else if d.detection_id.is_some()
                    && d.detection_id == t.detection_id
                    && t.confirmed
                {
                    // The estimator says it is the same person, but nobody moves that fast.
                    errors.push((
                        index[di],
                        DetectionError::Teleport {
                            track: t.id,
                            distance_m: dist,
                            dt_s: dt,
                        },
                    ));
                    pairs.push((f64::INFINITY, di, usize::MAX));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut det_used = vec![false; usable.len()];
        let mut track_used = vec![false; self.tracks.len()];
        for (dist, di, ti) in pairs {
            if det_used[di] {
                continue;
            }
            if !dist.is_finite() {
                det_used[di] = true; // teleport: drop the detection
                continue;
            }
            if track_used[ti] {
                continue;
            }
            det_used[di] = true;
            track_used[ti] = true;
            let t = &mut self.tracks[ti];
            absorb(cfg, t, &usable[di], stamp_ns);
        }
        for (di, d) in usable.iter().enumerate() {
            if !det_used[di] {
                let mut t = Track {
                    id: self.next_id,
                    hits: 0,
                    confirmed: false,
                    age_frames: 0,
                    detection_id: d.detection_id,
                    filters: vec![OneEuro3::new(cfg.one_euro); NUM_JOINTS],
                    history: vec![],
                    memory: [None; NUM_JOINTS],
                };
                self.next_id = self.next_id.wrapping_add(1);
                absorb(cfg, &mut t, d, stamp_ns);
                self.tracks.push(t);
            }
        }
        // Unmatched tracks lose their streak; old ones are dropped.
        for (ti, t) in self.tracks.iter_mut().enumerate() {
            if ti < track_used.len() && !track_used[ti] {
                t.hits = 0;
            }
        }
        let timeout = (cfg.track_timeout_s * 1e9) as u64;
        self.tracks.retain(|t| {
            t.last()
                .is_some_and(|o| stamp_ns.saturating_sub(o.stamp_ns) <= timeout)
                && (t.confirmed || t.hits > 0)
        });
        errors
    }

    /// Count one more output frame for each of `ids`.
    pub fn bump_ages(&mut self, ids: impl Iterator<Item = u32>) {
        for id in ids {
            if let Some(t) = self.tracks.iter_mut().find(|t| t.id == id) {
                t.age_frames = t.age_frames.saturating_add(1);
            }
        }
    }

    /// Choose the partner among `candidates` = (track id, pelvis, heading) with hysteresis.
    pub fn choose_partner(
        &mut self,
        cfg: &BridgeConfig,
        candidates: &[(u32, Vector3<f64>, UnitQuaternion<f64>)],
    ) -> Option<u32> {
        let p = &cfg.partner;
        let score = |root: &Vector3<f64>, heading: &UnitQuaternion<f64>| {
            let dist = root.xy().norm();
            let facing = heading * Vector3::x();
            let to_robot = -root.xy() / dist.max(1e-6);
            let cos = facing.x * to_robot.x + facing.y * to_robot.y;
            (dist <= p.max_distance_m && cos >= p.min_facing_cos).then_some(dist)
        };
        let scored: Vec<(u32, f64)> = candidates
            .iter()
            .filter_map(|(id, r, h)| score(r, h).map(|d| (*id, d)))
            .collect();
        let best = scored.iter().min_by(|a, b| a.1.total_cmp(&b.1)).copied();
        let current = self
            .partner
            .and_then(|id| scored.iter().find(|(i, _)| *i == id).copied());
        self.partner = match (current, best) {
            (Some(cur), Some(b)) if b.1 + p.switch_margin_m < cur.1 => Some(b.0),
            (Some(cur), _) => Some(cur.0),
            (None, b) => b.map(|b| b.0),
        };
        self.partner
    }
}

fn predict_root(t: &Track, stamp_ns: u64) -> Vector3<f64> {
    match t.history.as_slice() {
        [.., a, b] => {
            let dt_ab = (b.stamp_ns.saturating_sub(a.stamp_ns)) as f64 / 1e9;
            let dt = (stamp_ns.saturating_sub(b.stamp_ns)) as f64 / 1e9;
            if dt_ab > 1e-6 {
                b.joints[0] + (b.joints[0] - a.joints[0]) * (dt / dt_ab).min(3.0)
            } else {
                b.joints[0]
            }
        }
        [b] => b.joints[0],
        [] => Vector3::zeros(),
    }
}

/// Merge a detection into a track: fill missing joints, smooth, remember.
fn absorb(cfg: &BridgeConfig, t: &mut Track, d: &Detection, stamp_ns: u64) {
    let heading = skeleton::heading(&d.joints);
    let root = d.joints[j::PELVIS];
    let rest = Body::with_height(1.75);
    let mut joints = d.joints;
    let mut conf = d.confidence;
    let mut filled = vec![];
    let max_fill_ns = (cfg.max_fill_s * 1e9) as u64;
    for k in 0..NUM_JOINTS {
        if conf[k] >= cfg.min_confidence {
            continue;
        }
        filled.push(k as u8);
        match t.memory[k] {
            Some((rel, seen, c)) => {
                let age = stamp_ns.saturating_sub(seen);
                joints[k] = root + heading * rel;
                conf[k] = if age <= max_fill_ns {
                    c * (1.0 - age as f64 / max_fill_ns.max(1) as f64)
                } else {
                    0.0
                };
            }
            None => {
                // Never seen: place it at its rest offset from the parent (e.g. COCO feet).
                let parent = PARENTS[k].max(0) as usize;
                joints[k] = if k == 0 {
                    root
                } else {
                    joints[parent] + heading * rest.offsets[k]
                };
                conf[k] = 0.0;
            }
        }
    }
    for ((mem, p), c) in t.memory.iter_mut().zip(&joints).zip(&d.confidence) {
        if *c >= cfg.min_confidence {
            *mem = Some((heading.inverse() * (p - root), stamp_ns, *c));
        }
    }
    let dt = t
        .last()
        .map(|o| stamp_ns.saturating_sub(o.stamp_ns) as f64 / 1e9)
        .unwrap_or(0.0);
    if dt > cfg.max_interp_gap_s {
        for f in &mut t.filters {
            f.reset();
        }
    }
    for (f, p) in t.filters.iter_mut().zip(joints.iter_mut()) {
        *p = Vector3::from(f.filter((*p).into(), dt));
    }
    t.hits = t.hits.saturating_add(1);
    if t.hits >= cfg.confirm_frames {
        t.confirmed = true;
    }
    if d.detection_id.is_some() {
        t.detection_id = d.detection_id;
    }
    t.history.push(Observation {
        stamp_ns,
        joints,
        confidence: conf,
        filled,
    });
    if t.history.len() > 2 {
        t.history.remove(0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use echo_motion::skeleton::{forward, Pose};

    fn person_at(x: f64, y: f64, yaw: f64) -> Detection {
        let body = Body::with_height(1.75);
        let p = forward(&body, &Pose::rest(Vector3::new(x, y, 0.95), yaw));
        Detection {
            detection_id: None,
            joints: p,
            confidence: [0.9; NUM_JOINTS],
        }
    }

    const MS: u64 = 1_000_000;
    const FACING_ROBOT: f64 = std::f64::consts::PI;

    #[test]
    fn keeps_ids_and_confirms_after_three_hits() {
        let cfg = BridgeConfig::default();
        let mut tr = Tracker::new();
        for i in 0..5u64 {
            let x = 2.0 - 0.05 * i as f64;
            tr.update(
                &cfg,
                i * 66 * MS,
                vec![person_at(x, 0.0, FACING_ROBOT), person_at(2.0, 2.0, 0.0)],
            );
        }
        assert_eq!(tr.tracks().len(), 2);
        assert!(tr.tracks().iter().all(|t| t.confirmed));
        let ids: Vec<u32> = tr.tracks().iter().map(|t| t.id).collect();
        assert_eq!(ids, vec![0, 1]);
    }

    #[test]
    fn implausible_bones_are_rejected() {
        let cfg = BridgeConfig::default();
        let mut d = person_at(2.0, 0.0, FACING_ROBOT);
        for k in [18, 19, 4, 5, 10, 11, 15] {
            d.joints[k] += Vector3::new(0.0, 0.0, 1.5);
        }
        let errs = Tracker::new().update(&cfg, 0, vec![d]);
        assert_eq!(errs[0].1.reason(), "implausible_bones");
        // One bad joint is only masked.
        let mut d = person_at(2.0, 0.0, FACING_ROBOT);
        d.joints[21] += Vector3::new(0.0, 0.0, 1.0);
        let mut tr = Tracker::new();
        assert!(tr.update(&cfg, 0, vec![d]).is_empty());
        assert_eq!(tr.tracks()[0].last().unwrap().filled, vec![21]);
    }

    #[test]
    fn teleports_of_a_known_person_are_rejected() {
        let cfg = BridgeConfig::default();
        let mut tr = Tracker::new();
        for i in 0..4u64 {
            let mut d = person_at(2.0, 0.0, FACING_ROBOT);
            d.detection_id = Some(7);
            tr.update(&cfg, i * 66 * MS, vec![d]);
        }
        let mut far = person_at(2.0, 3.0, FACING_ROBOT);
        far.detection_id = Some(7);
        let errs = tr.update(&cfg, 4 * 66 * MS, vec![far]);
        assert_eq!(errs.len(), 1);
        assert_eq!(errs[0].1.reason(), "teleport");
        assert_eq!(tr.tracks().len(), 1, "no new track from a teleport");
    }

    #[test]
    fn short_gaps_are_filled_from_history() {
        let cfg = BridgeConfig::default();
        let mut tr = Tracker::new();
        tr.update(&cfg, 0, vec![person_at(2.0, 0.0, FACING_ROBOT)]);
        let mut d = person_at(2.0, 0.0, FACING_ROBOT);
        d.confidence[j::R_WRIST] = 0.0;
        d.joints[j::R_WRIST] = Vector3::zeros();
        tr.update(&cfg, 100 * MS, vec![d]);
        let o = tr.tracks()[0].last().unwrap();
        let truth = person_at(2.0, 0.0, FACING_ROBOT).joints[j::R_WRIST];
        assert!((o.joints[j::R_WRIST] - truth).norm() < 0.01);
        assert!(o.confidence[j::R_WRIST] > 0.0 && o.confidence[j::R_WRIST] < 0.9);
    }

    #[test]
    fn partner_is_the_closest_facing_person_with_hysteresis() {
        let cfg = BridgeConfig::default();
        let mut tr = Tracker::new();
        let face_robot = UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::PI);
        let away = UnitQuaternion::identity();
        let a = (1, Vector3::new(1.5, 0.0, 0.9), face_robot);
        let b = (2, Vector3::new(1.3, 0.5, 0.9), face_robot);
        let c = (3, Vector3::new(0.8, 0.0, 0.9), away);
        assert_eq!(tr.choose_partner(&cfg, &[a, c]), Some(1), "c faces away");
        // b is closer, but not by the switch margin.
        assert_eq!(tr.choose_partner(&cfg, &[a, b, c]), Some(1));
        let b_close = (2, Vector3::new(0.9, 0.2, 0.9), face_robot);
        assert_eq!(tr.choose_partner(&cfg, &[a, b_close]), Some(2));
    }
}
