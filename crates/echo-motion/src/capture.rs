//! Real two-person motion captures: two BVH files, one per person, sharing one capture volume
//! and one clock (CMU 18_01.bvh + 19_01.bvh, for instance), cleaned and loaded as one
//! [`Clip`]: both people's 22 SMPL-order joints, z up, metres, at [`FPS`].
//!
//! Real files have quirks synthetic data never shows. Each has one rule; everything done is
//! counted in the [`CleanReport`] and said in its `notes`, and what cannot be used is an error
//! naming the file (or both files, `a + b`) and the problem. The rules, in the order applied:
//!
//! 1. **Frame rate.** Both files must have the same frame time (rates differing by more than
//!    one part in 10⁶ are an error: one capture has one clock). A frame time written with
//!    limited precision is read as the nearest whole rate when within 0.05 % of it (CMU's
//!    `.0083333` is 120 Hz). Positions are resampled linearly to 30 Hz ([`bvh::to_smpl`]).
//! 2. **Calibration pose.** Leading frames in which every rotation channel is a whole number of
//!    degrees, followed by a frame in which one is not, are a calibration pose (CMU: frame 0, a
//!    T-pose-like frame with angles such as −21 and 16). Failing that, frame 0 is a calibration
//!    pose when the largest joint rotation change from frame 0 to 1 exceeds both
//!    [`CALIBRATION_JUMP_FACTOR`] × the median frame-to-frame change and the spike threshold,
//!    while the change from frame 1 to 2 is under a quarter of it (frame 1 continues the motion;
//!    a spike in frame 1 would jump back). Detected per file; both files then lose the larger of
//!    the two counts from their start, so they still start at the same instant. The jump is never
//!    seen as movement.
//! 3. **Lengths.** After that, both files start at their frame 0 (one clock). Lengths that differ
//!    by at most `max_length_mismatch_s` (0.5 s) are trimmed at the end to the shorter; more is
//!    an error naming both lengths.
//! 4. **Up axis.** BVH is normally Y-up and converted to Echo's z-up. The up axis is measured,
//!    not assumed: the median head-minus-mid-ankle direction over the first 0.5 s must lie along
//!    file +Y or +Z; a +Z-up file is turned (−90° about its X axis) before the usual conversion;
//!    any other direction is an error.
//! 5. **Units.** The standing height in file units, H = 90th percentile over the take of head
//!    minus lower ankle along the up axis (a take may start crouched or mid-squat), gives
//!    height = scale × H + [`HEAD_TOP_M`]. With
//!    `scale: Some(s)`, `s` is used as given (a height outside [`HEIGHT_RANGE_M`] only gives a
//!    note). With `None` and a map whose source has a known unit ([`bvh::default_scale`]: CMU
//!    0.0564), that unit is used and a height outside the range is an error. Otherwise the unit
//!    is the one of [`UNITS`] (metres, feet, CMU units, inches, centimetres, millimetres) that
//!    puts both people in 1.3–2.2 m; at most one can (neighbouring units differ by more than the
//!    range's ratio 1.79). None, or different units for the two files, is an error asking for the
//!    scale.
//! 6. **Spikes.** Only channels that move a mapped joint are examined (unused fingers are
//!    ignored), at interior frames (the first and last frames have one neighbour and are kept as
//!    they are). A value is a single-frame spike when it departs from the median of its 5-frame
//!    neighbourhood by more than the threshold (`spike_threshold_deg`, 25°, for angles;
//!    `spike_threshold_m`, 0.05 m, for positions) while both immediate neighbours lie within
//!    half that departure of the median. Angle differences are taken modulo 360° (179° → −179°
//!    is 2°). For a rotation channel the joint's rotation must also differ from its rotation in
//!    both neighbouring frames by more than half the threshold, so a frame that writes the same
//!    rotation with other Euler angles (near gimbal lock, or a ±180° re-expression) is not a
//!    spike. Spikes are replaced by the mean of the two neighbours (on the circle for angles) and
//!    counted per channel. A channel with spikes in more than `max_spike_fraction` (5 %) of its
//!    frames is an error: that is noise, not a glitch, and interpolating would invent motion.
//!    Below 30 Hz both thresholds grow with (30 / rate)², as a real movement's departure from its
//!    neighbours does.
//! 7. **Floor.** The lowest foot (ankle or toe joint, both people, all frames) is reported per
//!    file. Echo's floor is z = 0, where the synthetic foot joint rests. A pair whose lowest foot
//!    lies within [`FLOOR_TOLERANCE_M`] is kept as measured; otherwise both people are moved
//!    by the same vertical shift (one capture volume) to put it at 0, reported as
//!    `floor_shift_m` and in a note.
//! 8. **Proportions.** Each subject keeps their own bone lengths (no retargeting); each height
//!    (head minus lower ankle + 0.16 m, median over the first 0.5 s) is reported and becomes the
//!    clip's body height.
//! 9. **Unusable input.** No frames, a joint the map names missing from the file, a non-finite
//!    value, a frame-time or length mismatch as above, or fewer than [`MIN_FRAMES`] frames at
//!    30 Hz after cleaning (one 2.07 s forecasting window) is an error.

use std::path::Path;

use echo_msgs::Interaction;
use nalgebra::{Matrix3, Vector3};

use crate::bvh::{self, Bvh, BvhError, Channel, JointMap};
use crate::skeleton::{j, JOINT_NAMES, NUM_JOINTS};
use crate::synth::{Clip, FPS};

/// Fewest output frames: one forecasting window, 8 observed + 23 predicted frames at 15 Hz
/// (2.07 s), is 62 frames at 30 Hz.
pub const MIN_FRAMES: usize = 62;

/// Plausible standing heights of an adult subject, metres.
pub const HEIGHT_RANGE_M: (f64, f64) = (1.3, 2.2);

/// Head joint to the top of the head plus ankle joint to the sole, metres (the InterGen loader's
/// allowance).
pub const HEAD_TOP_M: f64 = 0.16;

/// File units tried when the scale is detected, with their size in metres.
pub const UNITS: [(&str, f64); 6] = [
    ("metres", 1.0),
    ("feet", 0.3048),
    ("CMU units", bvh::CMU_SCALE),
    ("inches", 0.0254),
    ("centimetres", 0.01),
    ("millimetres", 0.001),
];

/// The lowest foot height kept without a shift, metres.
pub const FLOOR_TOLERANCE_M: (f64, f64) = (-0.05, 0.10);

/// A frame-0 jump this many times the median frame-to-frame change marks a calibration pose.
pub const CALIBRATION_JUMP_FACTOR: f64 = 10.0;

/// Seconds at the start over which standing height and up axis are measured.
const STANDING_S: f64 = 0.5;

/// Relative distance to a whole rate under which a frame time is read as that rate.
const RATE_SNAP: f64 = 5e-4;

/// How a pair is cleaned.
#[derive(Debug, Clone)]
pub struct PairOptions {
    /// Joint-name map onto the 22 SMPL joints (default [`bvh::cmu_map`]).
    pub map: JointMap,
    /// File units → metres; `None`: the map's known unit, else detected from standing height.
    pub scale: Option<f64>,
    /// Longest length difference trimmed, seconds (default 0.5).
    pub max_length_mismatch_s: f64,
    /// Spike threshold for angles, degrees (default 25).
    pub spike_threshold_deg: f64,
    /// Spike threshold for positions, metres (default 0.05).
    pub spike_threshold_m: f64,
    /// Largest share of a channel's frames that may be spikes (default 0.05).
    pub max_spike_fraction: f64,
}

impl Default for PairOptions {
    fn default() -> Self {
        PairOptions {
            map: bvh::cmu_map(),
            scale: None,
            max_length_mismatch_s: 0.5,
            spike_threshold_deg: 25.0,
            spike_threshold_m: 0.05,
            max_spike_fraction: 0.05,
        }
    }
}

/// Spikes repaired in one channel.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SpikeChannel {
    /// BVH joint name.
    pub joint: String,
    /// Channel name (`Zrotation`, `Xposition`, …).
    pub channel: String,
    /// Spikes replaced.
    pub count: usize,
}

/// What was done to one file.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FileReport {
    /// File name.
    pub file: String,
    /// Frames in the file.
    pub frames_in: usize,
    /// Frame time as written, seconds.
    pub frame_time_s: f64,
    /// Frame rate used, Hz (the frame time read as a whole rate where it is one).
    pub source_fps: f64,
    /// Calibration frames detected in this file.
    pub calibration_frames: usize,
    /// Which calibration rule fired ("whole-number angles" or "jump"), if any.
    pub calibration_rule: Option<String>,
    /// Frames dropped from the start (the larger count of the pair).
    pub frames_dropped_start: usize,
    /// Spikes repaired, all channels.
    pub spikes: usize,
    /// Spikes per channel (channels with none left out).
    pub spike_channels: Vec<SpikeChannel>,
    /// File units → metres used.
    pub scale: f64,
    /// Where the scale came from.
    pub scale_source: String,
    /// Up axis found in the file ("+Y" or "+Z").
    pub up_axis: String,
    /// Frames trimmed from the end to match the other file.
    pub frames_trimmed_end: usize,
    /// Standing height, metres.
    pub height_m: f64,
    /// Lowest ankle or toe joint over all frames, metres, before any floor shift.
    pub lowest_foot_m: f64,
}

/// What cleaning did to a pair.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CleanReport {
    /// Person A's file, then person B's.
    pub files: [FileReport; 2],
    /// Output frames.
    pub output_frames: usize,
    /// Output rate, Hz.
    pub output_fps: f64,
    /// Vertical shift applied to both people, metres (0 when the floor was kept).
    pub floor_shift_m: f64,
    /// What was found and done, in words.
    pub notes: Vec<String>,
}

/// Load a two-person capture from two BVH files (person A, person B).
pub fn load_bvh_pair(
    a: &Path,
    b: &Path,
    opts: &PairOptions,
    texts: Vec<String>,
    kind: Interaction,
) -> Result<(Clip, CleanReport), BvhError> {
    let ba = Bvh::read(a)?;
    let bb = Bvh::read(b)?;
    clean_pair(
        [(a.display().to_string(), ba), (b.display().to_string(), bb)],
        opts,
        texts,
        kind,
    )
}

/// [`load_bvh_pair`] from text: `a` and `b` are (name used in errors, BVH text).
pub fn load_bvh_pair_str(
    a: (&str, &str),
    b: (&str, &str),
    opts: &PairOptions,
    texts: Vec<String>,
    kind: Interaction,
) -> Result<(Clip, CleanReport), BvhError> {
    let ba = Bvh::parse(a.1, a.0)?;
    let bb = Bvh::parse(b.1, b.0)?;
    clean_pair(
        [(a.0.to_string(), ba), (b.0.to_string(), bb)],
        opts,
        texts,
        kind,
    )
}

fn fail(file: &str, what: String) -> BvhError {
    BvhError {
        file: file.to_string(),
        line: 0,
        what,
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// An angle difference in degrees taken into (−180, 180].
fn wrap_deg(d: f64) -> f64 {
    let w = (d + 180.0).rem_euclid(360.0) - 180.0;
    if w == -180.0 {
        180.0
    } else {
        w
    }
}

/// The frame time read as a whole rate when within [`RATE_SNAP`] of one.
fn source_rate(frame_time: f64) -> f64 {
    let rate = 1.0 / frame_time;
    let whole = rate.round();
    if whole >= 1.0 && (rate - whole).abs() <= RATE_SNAP * rate {
        whole
    } else {
        rate
    }
}

/// One file while it is being cleaned.
struct Work {
    name: String,
    bvh: Bvh,
    /// Indices of the 22 mapped joints.
    idx: Vec<usize>,
    /// Joints that move a mapped joint (mapped joints and their ancestors).
    moving: Vec<usize>,
    starts: Vec<usize>,
    report: FileReport,
}

impl Work {
    fn new(name: String, bvh: Bvh, map: &JointMap) -> Result<Work, BvhError> {
        if bvh.frames.is_empty() {
            return Err(fail(&name, "no frames (Frames: 0)".into()));
        }
        let idx = bvh::joint_indices(&bvh, map, &name)?;
        let mut moving = vec![false; bvh.joints.len()];
        for &k in &idx {
            let mut at = Some(k);
            while let Some(q) = at {
                moving[q] = true;
                at = bvh.joints[q].parent;
            }
        }
        let moving = (0..bvh.joints.len()).filter(|q| moving[*q]).collect();
        let starts = bvh.channel_starts();
        let report = FileReport {
            file: name.clone(),
            frames_in: bvh.frames.len(),
            frame_time_s: bvh.frame_time,
            source_fps: source_rate(bvh.frame_time),
            calibration_frames: 0,
            calibration_rule: None,
            frames_dropped_start: 0,
            spikes: 0,
            spike_channels: vec![],
            scale: 0.0,
            scale_source: String::new(),
            up_axis: String::new(),
            frames_trimmed_end: 0,
            height_m: 0.0,
            lowest_foot_m: 0.0,
        };
        Ok(Work {
            name,
            bvh,
            idx,
            moving,
            starts,
            report,
        })
    }

    /// Channel values of joint `q` in `row`.
    fn values<'a>(&self, q: usize, row: &'a [f64]) -> &'a [f64] {
        &row[self.starts[q]..self.starts[q] + self.bvh.joints[q].channels.len()]
    }

    /// Largest rotation change of a moving joint between frames `f` and `f + 1`, degrees.
    fn rotation_change(&self, f: usize) -> f64 {
        let (a, b) = (&self.bvh.frames[f], &self.bvh.frames[f + 1]);
        self.moving
            .iter()
            .map(|&q| {
                let ra = self.bvh.local(q, self.values(q, a)).0;
                let rb = self.bvh.local(q, self.values(q, b)).0;
                ra.angle_to(&rb).to_degrees()
            })
            .fold(0.0, f64::max)
    }

    /// Calibration frames at the start (rule 2) and the rule that found them.
    fn calibration(&self, jump_floor_deg: f64) -> (usize, Option<&'static str>) {
        let frames = &self.bvh.frames;
        let rot: Vec<usize> = self
            .bvh
            .joints
            .iter()
            .enumerate()
            .flat_map(|(q, jt)| {
                jt.channels
                    .iter()
                    .enumerate()
                    .filter(|(_, c)| matches!(c, Channel::Rot(_)))
                    .map(move |(i, _)| (q, i))
            })
            .map(|(q, i)| self.starts[q] + i)
            .collect();
        if rot.is_empty() {
            return (0, None);
        }
        let whole = |row: &Vec<f64>| rot.iter().all(|&k| row[k] == row[k].round());
        let lead = frames.iter().take_while(|r| whole(r)).count();
        if lead > 0 && lead < frames.len() {
            return (lead, Some("whole-number angles"));
        }
        if frames.len() >= 4 {
            let jumps: Vec<f64> = (0..frames.len() - 1)
                .map(|f| self.rotation_change(f))
                .collect();
            let typical = median(jumps[1..].to_vec());
            if jumps[0] > (CALIBRATION_JUMP_FACTOR * typical).max(jump_floor_deg)
                && jumps[1] < jumps[0] / 4.0
            {
                return (1, Some("jump"));
            }
        }
        (0, None)
    }

    /// Positions of the head and both ankles over the first [`STANDING_S`], file units.
    fn standing(&self) -> Vec<[Vector3<f64>; 3]> {
        let n =
            ((STANDING_S * self.report.source_fps).ceil() as usize).clamp(1, self.bvh.frames.len());
        (0..n)
            .map(|f| {
                let p = self.bvh.positions(f);
                [
                    p[self.idx[j::HEAD]],
                    p[self.idx[j::L_ANKLE]],
                    p[self.idx[j::R_ANKLE]],
                ]
            })
            .collect()
    }

    /// Up axis (1 = +Y, 2 = +Z) and standing height H in file units (rule 4, rule 5).
    fn up_and_height(&self) -> Result<(usize, f64), BvhError> {
        let s = self.standing();
        let up: Vector3<f64> = Vector3::from_fn(|a, _| {
            median(
                s.iter()
                    .map(|[h, l, r]| h[a] - 0.5 * (l[a] + r[a]))
                    .collect(),
            )
        });
        let a = up.iamax();
        let name =
            |a: usize, v: f64| format!("{}{}", if v < 0.0 { "-" } else { "+" }, ["X", "Y", "Z"][a]);
        if !(a == 1 || a == 2) || up[a] <= 0.0 {
            return Err(fail(
                &self.name,
                format!(
                    "the head is above the ankles along {} (head − ankles = [{:.3}, {:.3}, {:.3}] file units over the first {STANDING_S} s): only +Y-up and +Z-up files are read",
                    name(a, up[a]),
                    up.x,
                    up.y,
                    up.z
                ),
            ));
        }
        // Standing height: the 90th percentile over the whole take (every 4th frame), so that a
        // take starting crouched, sitting or mid-squat is measured where the person stands.
        let mut hs: Vec<f64> = (0..self.bvh.frames.len())
            .step_by(4)
            .map(|f| {
                let p = self.bvh.positions(f);
                let (h, l, r) = (
                    p[self.idx[j::HEAD]],
                    p[self.idx[j::L_ANKLE]],
                    p[self.idx[j::R_ANKLE]],
                );
                h[a] - l[a].min(r[a])
            })
            .filter(|x| x.is_finite())
            .collect();
        hs.sort_by(|x, y| x.total_cmp(y));
        let h = hs
            .get(((hs.len().max(1) - 1) as f64 * 0.9).round() as usize)
            .copied()
            .unwrap_or_else(|| median(s.iter().map(|[h, l, r]| h[a] - l[a].min(r[a])).collect()));
        Ok((a, h))
    }

    /// Repair single-frame spikes (rule 6); errors when a channel is mostly noise.
    fn repair_spikes(
        &mut self,
        thr_deg: f64,
        thr_units: f64,
        max_fraction: f64,
    ) -> Result<(), BvhError> {
        let n = self.bvh.frames.len();
        if n < 3 {
            return Ok(());
        }
        let mut fixes: Vec<(usize, usize, f64)> = vec![];
        let mut per_channel: Vec<SpikeChannel> = vec![];
        for &q in &self.moving {
            for (i, c) in self.bvh.joints[q].channels.iter().enumerate() {
                let k = self.starts[q] + i;
                let rot = matches!(c, Channel::Rot(_));
                let thr = if rot { thr_deg } else { thr_units };
                let v: Vec<f64> = self.bvh.frames.iter().map(|r| r[k]).collect();
                // Difference b − a (modulo 360° for angles).
                let diff = |a: f64, b: f64| if rot { wrap_deg(b - a) } else { b - a };
                let mut count = 0;
                for t in 1..n - 1 {
                    let lo = t.saturating_sub(2);
                    let hi = (t + 2).min(n - 1);
                    let med = median((lo..=hi).map(|s| diff(v[t], v[s])).collect());
                    let dev = -med;
                    if dev.abs() <= thr {
                        continue;
                    }
                    let near = |s: usize| (diff(v[t], v[s]) - med).abs() < 0.5 * dev.abs();
                    if !(near(t - 1) && near(t + 1)) {
                        continue;
                    }
                    if rot {
                        let r = |f: usize| {
                            let row = &self.bvh.frames[f];
                            self.bvh.local(q, self.values(q, row)).0
                        };
                        let here = r(t);
                        let moved = here
                            .angle_to(&r(t - 1))
                            .to_degrees()
                            .min(here.angle_to(&r(t + 1)).to_degrees());
                        if moved <= 0.5 * thr {
                            continue;
                        }
                    }
                    count += 1;
                    fixes.push((t, k, v[t - 1] + 0.5 * diff(v[t - 1], v[t + 1])));
                }
                if count > 0 {
                    let channel = match c {
                        Channel::Pos(a) => format!("{}position", ["X", "Y", "Z"][*a]),
                        Channel::Rot(a) => format!("{}rotation", ["X", "Y", "Z"][*a]),
                    };
                    let joint = self.bvh.joints[q].name.clone();
                    if count as f64 > max_fraction * n as f64 {
                        return Err(fail(
                            &self.name,
                            format!(
                                "{joint} {channel} has spikes in {count} of {n} frames ({:.1} %, more than {:.1} %): the channel is noise, not a glitch to interpolate",
                                100.0 * count as f64 / n as f64,
                                100.0 * max_fraction
                            ),
                        ));
                    }
                    per_channel.push(SpikeChannel {
                        joint,
                        channel,
                        count,
                    });
                }
            }
        }
        for (t, k, x) in fixes {
            self.bvh.frames[t][k] = x;
        }
        self.report.spikes = per_channel.iter().map(|c| c.count).sum();
        self.report.spike_channels = per_channel;
        Ok(())
    }
}

/// Clean a pair of parsed files, `(name, file)` for person A then B, into one clip.
pub fn clean_pair(
    files: [(String, Bvh); 2],
    opts: &PairOptions,
    texts: Vec<String>,
    kind: Interaction,
) -> Result<(Clip, CleanReport), BvhError> {
    let [(na, ba), (nb, bb)] = files;
    let mut w = [Work::new(na, ba, &opts.map)?, Work::new(nb, bb, &opts.map)?];
    let pair = format!("{} + {}", w[0].name, w[1].name);
    let mut notes: Vec<String> = vec![];

    // Rule 1: one clock.
    let rate = w[0].report.source_fps;
    if (rate - w[1].report.source_fps).abs() > 1e-6 * rate {
        return Err(fail(
            &pair,
            format!(
                "frame times differ: {} has {} s ({:.3} Hz), {} has {} s ({:.3} Hz); the two files of one capture share one clock",
                w[0].name,
                w[0].report.frame_time_s,
                rate,
                w[1].name,
                w[1].report.frame_time_s,
                w[1].report.source_fps
            ),
        ));
    }
    for x in w.iter_mut() {
        x.bvh.frame_time = 1.0 / rate;
    }
    if (rate - FPS).abs() > 1e-9 {
        notes.push(format!("{rate} Hz resampled to {FPS} Hz"));
    }
    let slow = (FPS / rate).powi(2).max(1.0);
    let thr_deg = opts.spike_threshold_deg * slow;

    // Rule 2: calibration frames, the same number dropped from both files.
    let cal = [w[0].calibration(thr_deg), w[1].calibration(thr_deg)];
    let drop = cal[0].0.max(cal[1].0);
    for (x, (count, rule)) in w.iter_mut().zip(cal) {
        x.report.calibration_frames = count;
        x.report.calibration_rule = rule.map(str::to_string);
        if let Some(rule) = rule {
            notes.push(format!(
                "{}: {} calibration frame(s) at the start ({rule})",
                x.name, count
            ));
        }
    }
    if drop > 0 {
        for x in w.iter_mut() {
            if x.bvh.frames.len() <= drop {
                return Err(fail(
                    &x.name,
                    format!(
                        "no frames left after dropping {drop} calibration frame(s) of {}",
                        x.bvh.frames.len()
                    ),
                ));
            }
            x.bvh.frames.drain(..drop);
            x.report.frames_dropped_start = drop;
        }
        notes.push(format!(
            "dropped the first {drop} frame(s) of both files (one clock)"
        ));
    }

    // Rule 3: lengths.
    let lens = [w[0].bvh.frames.len(), w[1].bvh.frames.len()];
    let secs = |n: usize| n as f64 / rate;
    let keep = lens[0].min(lens[1]);
    let gap = secs(lens[0].max(lens[1]) - keep);
    if gap > opts.max_length_mismatch_s + 1e-9 {
        return Err(fail(
            &pair,
            format!(
                "lengths differ by {gap:.3} s: {} has {} frames ({:.3} s), {} has {} frames ({:.3} s); at most {} s is trimmed",
                w[0].name,
                lens[0],
                secs(lens[0]),
                w[1].name,
                lens[1],
                secs(lens[1]),
                opts.max_length_mismatch_s
            ),
        ));
    }
    for x in w.iter_mut() {
        let n = x.bvh.frames.len();
        if n > keep {
            x.bvh.frames.truncate(keep);
            x.report.frames_trimmed_end = n - keep;
            notes.push(format!(
                "{}: trimmed {} frame(s) ({:.3} s) at the end to the other file's length",
                x.name,
                n - keep,
                secs(n - keep)
            ));
        }
    }

    // Rules 4 and 5: up axis and units.
    let mut up = [1usize; 2];
    let mut h_units = [0.0; 2];
    for (p, x) in w.iter_mut().enumerate() {
        let (a, h) = x.up_and_height()?;
        up[p] = a;
        h_units[p] = h;
        x.report.up_axis = if a == 1 { "+Y" } else { "+Z" }.into();
        if a == 2 {
            notes.push(format!(
                "{}: Z-up file turned Y-up before conversion",
                x.name
            ));
        }
        if h <= 0.0 {
            return Err(fail(
                &x.name,
                format!("head is not above the ankles at the start ({h:.3} file units)"),
            ));
        }
    }
    let height = |s: f64, h: f64| s * h + HEAD_TOP_M;
    let in_range = |m: f64| (HEIGHT_RANGE_M.0..=HEIGHT_RANGE_M.1).contains(&m);
    let (scale, source) = match (opts.scale, bvh::default_scale(&opts.map)) {
        (Some(s), _) => {
            if !(s.is_finite() && s > 0.0) {
                return Err(fail(&pair, format!("scale must be positive, not {s}")));
            }
            for (x, h) in w.iter().zip(h_units) {
                if !in_range(height(s, h)) {
                    notes.push(format!(
                        "{}: standing height {:.2} m at the given scale {s} is outside {}–{} m",
                        x.name,
                        height(s, h),
                        HEIGHT_RANGE_M.0,
                        HEIGHT_RANGE_M.1
                    ));
                }
            }
            (s, "given".to_string())
        }
        (None, Some(s)) => {
            for (x, h) in w.iter().zip(h_units) {
                if !in_range(height(s, h)) {
                    return Err(fail(
                        &x.name,
                        format!(
                            "standing height {:.2} m at the joint map's unit ({s} m per file unit) is outside {}–{} m: the file is in another unit; give the scale (file units → metres, --scale)",
                            height(s, h),
                            HEIGHT_RANGE_M.0,
                            HEIGHT_RANGE_M.1
                        ),
                    ));
                }
            }
            (s, "the joint map's unit".to_string())
        }
        (None, None) => {
            let fits = |h: f64| UNITS.iter().find(|(_, s)| in_range(height(*s, h)));
            let found = [fits(h_units[0]), fits(h_units[1])];
            for (x, (f, h)) in w.iter().zip(found.iter().zip(h_units)) {
                if f.is_none() {
                    return Err(fail(
                        &x.name,
                        format!(
                            "standing height {h:.3} file units (head to ankle) fits no known unit ({}) for a {}–{} m person; give the scale (file units → metres, --scale)",
                            UNITS.map(|u| u.0).join(", "),
                            HEIGHT_RANGE_M.0,
                            HEIGHT_RANGE_M.1
                        ),
                    ));
                }
            }
            let (ua, ub) = (
                found[0].copied().unwrap_or(UNITS[0]),
                found[1].copied().unwrap_or(UNITS[0]),
            );
            if ua.0 != ub.0 {
                return Err(fail(
                    &pair,
                    format!(
                        "the files look like different units ({}: {}, {}: {}) but share one capture volume; give the scale (file units → metres, --scale)",
                        w[0].name, ua.0, w[1].name, ub.0
                    ),
                ));
            }
            (ua.1, format!("detected: {}", ua.0))
        }
    };
    notes.push(format!("scale {scale} m per file unit ({source})"));
    for x in w.iter_mut() {
        x.report.scale = scale;
        x.report.scale_source = source.clone();
    }

    // Rule 6: spikes.
    let thr_units = opts.spike_threshold_m * slow / scale;
    for x in w.iter_mut() {
        x.repair_spikes(thr_deg, thr_units, opts.max_spike_fraction)?;
        if x.report.spikes > 0 {
            notes.push(format!(
                "{}: {} spike(s) interpolated ({})",
                x.name,
                x.report.spikes,
                x.report
                    .spike_channels
                    .iter()
                    .map(|c| format!("{} {} ×{}", c.joint, c.channel, c.count))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
    }

    // Conversion: z up, metres, 30 Hz.
    let mut people: Vec<Vec<[Vector3<f64>; NUM_JOINTS]>> = vec![];
    for (x, a) in w.iter().zip(up) {
        let mut frames = bvh::to_smpl(&x.bvh, &opts.map, scale, FPS, &x.name)?;
        if a == 2 {
            // File Z up: −90° about file X, which is −90° about Echo's y: (x, y, z) → (−z, y, x).
            let turn = Matrix3::new(0.0, 0.0, -1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0);
            for f in frames.iter_mut() {
                for v in f.iter_mut() {
                    *v = turn * *v;
                }
            }
        }
        if let Some((f, k)) = frames.iter().enumerate().find_map(|(f, p)| {
            p.iter()
                .position(|v| !(v.x.is_finite() && v.y.is_finite() && v.z.is_finite()))
                .map(|k| (f, k))
        }) {
            return Err(fail(
                &x.name,
                format!(
                    "non-finite position of {} at output frame {f}",
                    JOINT_NAMES[k]
                ),
            ));
        }
        people.push(frames);
    }
    let n = people[0].len().min(people[1].len());
    for p in people.iter_mut() {
        p.truncate(n);
    }
    if n < MIN_FRAMES {
        return Err(fail(
            &pair,
            format!(
                "{n} frames at {FPS} Hz ({:.2} s) after cleaning: fewer than one forecasting window ({MIN_FRAMES} frames, {:.2} s)",
                n as f64 / FPS,
                MIN_FRAMES as f64 / FPS
            ),
        ));
    }

    // Rule 7: floor.
    let feet = [j::L_ANKLE, j::R_ANKLE, j::L_FOOT, j::R_FOOT];
    for (x, frames) in w.iter_mut().zip(&people) {
        x.report.lowest_foot_m = frames
            .iter()
            .flat_map(|p| feet.iter().map(|&k| p[k].z))
            .fold(f64::INFINITY, f64::min);
    }
    let lowest = w[0].report.lowest_foot_m.min(w[1].report.lowest_foot_m);
    let shift = if (FLOOR_TOLERANCE_M.0..=FLOOR_TOLERANCE_M.1).contains(&lowest) {
        notes.push(format!("lowest foot at {lowest:.3} m: floor kept"));
        0.0
    } else {
        notes.push(format!(
            "lowest foot at {lowest:.3} m, outside {}–{} m: both people moved {:+.3} m vertically to put it on the floor",
            FLOOR_TOLERANCE_M.0, FLOOR_TOLERANCE_M.1, -lowest
        ));
        -lowest
    };
    if shift != 0.0 {
        for p in people.iter_mut() {
            for f in p.iter_mut() {
                for v in f.iter_mut() {
                    v.z += shift;
                }
            }
        }
    }

    // Rule 8: each subject's own height.
    let stand = ((STANDING_S * FPS).ceil() as usize).clamp(1, n);
    for (x, frames) in w.iter_mut().zip(&people) {
        let h = median(
            frames[..stand]
                .iter()
                .map(|p| p[j::HEAD].z - p[j::L_ANKLE].z.min(p[j::R_ANKLE].z))
                .collect(),
        );
        x.report.height_m = h.max(0.5) + HEAD_TOP_M;
    }
    notes.push(format!(
        "heights {:.2} m ({}) and {:.2} m ({}); own proportions kept",
        w[0].report.height_m, w[0].name, w[1].report.height_m, w[1].name
    ));

    let clip = Clip::recorded(
        kind,
        texts,
        [w[0].report.height_m, w[1].report.height_m],
        &people[0][..n],
        &people[1][..n],
    );
    let [ra, rb] = w.map(|x| x.report);
    Ok((
        clip,
        CleanReport {
            files: [ra, rb],
            output_frames: n,
            output_fps: FPS,
            floor_shift_m: shift,
            notes,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{generate, Split};
    use nalgebra::Rotation3;

    /// Rotation-channel flags of a file's frame row.
    fn rot_flags(b: &Bvh) -> Vec<bool> {
        b.joints
            .iter()
            .flat_map(|jt| jt.channels.iter().map(|c| matches!(c, Channel::Rot(_))))
            .collect()
    }

    /// Index in a frame row of `joint`'s channel `ch`.
    fn chan(b: &Bvh, joint: &str, ch: Channel) -> usize {
        let q = b.joints.iter().position(|jt| jt.name == joint).unwrap();
        b.channel_starts()[q] + b.joints[q].channels.iter().position(|c| *c == ch).unwrap()
    }

    /// Frames of person `p` written by [`bvh::write`] at 30 Hz, then brought to `fps` (a whole
    /// multiple of 30) by interpolating every channel (on the circle for angles): the frames at
    /// multiples of 1/30 s are the clip's own.
    fn person_from(frames: &[[Vector3<f64>; NUM_JOINTS]], fps: f64) -> Bvh {
        let b = Bvh::parse(&bvh::write(frames, FPS), "fixture").unwrap();
        let k = (fps / FPS).round() as usize;
        let rot = rot_flags(&b);
        let mut out = vec![];
        for f in 0..b.frames.len() {
            for s in 0..k {
                if f + 1 == b.frames.len() && s > 0 {
                    break;
                }
                let w = s as f64 / k as f64;
                let row = (0..rot.len())
                    .map(|c| {
                        let a = b.frames[f][c];
                        if s == 0 {
                            return a;
                        }
                        let z = b.frames[f + 1][c];
                        let d = if rot[c] { wrap_deg(z - a) } else { z - a };
                        a + w * d
                    })
                    .collect();
                out.push(row);
            }
        }
        Bvh {
            frames: out,
            frame_time: 1.0 / fps,
            ..b
        }
    }

    fn truth_frames(clip: &Clip, p: usize) -> Vec<[Vector3<f64>; NUM_JOINTS]> {
        (0..clip.frames.len()).map(|f| clip.joints(f, p)).collect()
    }

    /// Test clip `i` and both people as BVH files at `fps`.
    fn fixture(i: u64, fps: f64) -> (Clip, [Bvh; 2]) {
        let c = generate(&Split::Test.clip(i));
        let files = [0, 1].map(|p| person_from(&truth_frames(&c, p), fps));
        (c, files)
    }

    fn load(a: &Bvh, b: &Bvh, opts: &PairOptions) -> Result<(Clip, CleanReport), BvhError> {
        load_bvh_pair_str(
            ("a.bvh", &a.to_text()),
            ("b.bvh", &b.to_text()),
            opts,
            vec!["Two people meet.".into()],
            Interaction::Handshake,
        )
    }

    /// Echo-named files, unit detected.
    fn echo() -> PairOptions {
        PairOptions {
            map: bvh::echo_map(),
            ..PairOptions::default()
        }
    }

    /// Largest joint distance between two clips over their common frames, metres.
    fn max_err(got: &Clip, truth: &Clip) -> f64 {
        let n = got.frames.len().min(truth.frames.len());
        (0..n)
            .flat_map(|f| {
                (0..2).flat_map(move |p| {
                    let (a, b) = (got.joints(f, p), truth.joints(f, p));
                    (0..NUM_JOINTS).map(move |k| (a[k] - b[k]).norm())
                })
            })
            .fold(0.0, f64::max)
    }

    /// A CMU-like calibration row: the first frame's root position, whole-number angles.
    fn calibration_row(b: &Bvh) -> Vec<f64> {
        let rot = rot_flags(b);
        let mut row: Vec<f64> = b.frames[0]
            .iter()
            .zip(&rot)
            .map(|(v, r)| if *r { 0.0 } else { *v })
            .collect();
        let some: Vec<usize> = (0..rot.len()).filter(|c| rot[*c]).collect();
        for (c, v) in some
            .iter()
            .skip(9)
            .step_by(7)
            .zip([-21.0, 21.0, -16.0, 11.0, -8.0, 8.0])
        {
            row[*c] = v;
        }
        row
    }

    #[test]
    fn a_clean_pair_at_120_hz_loads_within_a_millimetre() {
        let (truth, [a, b]) = fixture(0, 120.0);
        let (c, r) = load(&a, &b, &echo()).unwrap();
        assert_eq!(c.frames.len(), truth.frames.len());
        assert_eq!(r.output_frames, truth.frames.len());
        let err = max_err(&c, &truth);
        assert!(err < 1e-3, "{err} m");
        for f in &r.files {
            assert_eq!(f.source_fps, 120.0);
            assert_eq!((f.calibration_frames, f.frames_dropped_start), (0, 0));
            assert_eq!((f.spikes, f.frames_trimmed_end), (0, 0));
            assert_eq!(f.scale, 0.01);
            assert_eq!(f.scale_source, "detected: centimetres");
            assert_eq!(f.up_axis, "+Y");
        }
        assert_eq!(r.floor_shift_m, 0.0);
        assert_eq!(c.params.kind, Interaction::Handshake);
        assert_eq!(c.texts, vec!["Two people meet.".to_string()]);
        assert!(
            r.notes.iter().any(|n| n.contains("120 Hz resampled")),
            "{:?}",
            r.notes
        );
        // The report serialises.
        let json = serde_json::to_string(&r).unwrap();
        assert!(json.contains("\"calibration_frames\":0"), "{json}");
    }

    #[test]
    fn a_calibration_frame_is_dropped_from_both_files() {
        let (truth, [mut a, mut b]) = fixture(0, 120.0);
        for x in [&mut a, &mut b] {
            let row = calibration_row(x);
            x.frames.insert(0, row);
        }
        let (c, r) = load(&a, &b, &echo()).unwrap();
        for f in &r.files {
            assert_eq!(f.frames_in, (truth.frames.len() - 1) * 4 + 2);
            assert_eq!(f.calibration_frames, 1);
            assert_eq!(f.calibration_rule.as_deref(), Some("whole-number angles"));
            assert_eq!(f.frames_dropped_start, 1);
        }
        // Nothing of the calibration pose survives: the output is the motion itself.
        assert_eq!(c.frames.len(), truth.frames.len());
        let err = max_err(&c, &truth);
        assert!(err < 1e-3, "{err} m");

        // Only A has one: B loses its first frame too (one clock) and both stay aligned.
        let (truth, [mut a, b]) = fixture(0, 120.0);
        let row = calibration_row(&a);
        a.frames.insert(0, row);
        a.frames.pop();
        let (_, r) = load(&a, &b, &echo()).unwrap();
        assert_eq!(r.files[0].calibration_frames, 1);
        assert_eq!(r.files[1].calibration_frames, 0);
        assert_eq!(r.files[1].frames_dropped_start, 1);
        assert!(
            r.notes.iter().any(|n| n.contains("both files")),
            "{:?}",
            r.notes
        );
        assert_eq!(r.output_frames, truth.frames.len() - 1);
    }

    #[test]
    fn a_calibration_jump_without_whole_numbers_is_found() {
        let (truth, [mut a, mut b]) = fixture(0, 120.0);
        for x in [&mut a, &mut b] {
            let mut row = calibration_row(x);
            let rot = rot_flags(x);
            for (v, r) in row.iter_mut().zip(&rot) {
                if *r {
                    *v += 0.37;
                }
            }
            // The T-pose differs from the first real frame by a large turn of the whole body.
            let k = chan(x, "pelvis", Channel::Rot(1));
            row[k] = x.frames[0][k] + 150.0;
            x.frames.insert(0, row);
        }
        let (c, r) = load(&a, &b, &echo()).unwrap();
        for f in &r.files {
            assert_eq!(f.calibration_frames, 1);
            assert_eq!(f.calibration_rule.as_deref(), Some("jump"));
        }
        assert!(max_err(&c, &truth) < 1e-3);
    }

    #[test]
    fn single_channel_spikes_are_interpolated_and_counted() {
        let (truth, [mut a, b]) = fixture(0, 120.0);
        let elbow = chan(&a, "left_elbow", Channel::Rot(2));
        let root_y = chan(&a, "pelvis", Channel::Pos(1));
        a.frames[80][elbow] += 60.0;
        // Two spikes two frames apart in one channel: each is repaired from clean neighbours.
        a.frames[200][elbow] -= 45.0;
        a.frames[202][elbow] -= 45.0;
        a.frames[120][root_y] += 30.0; // centimetres
        let (c, r) = load(&a, &b, &echo()).unwrap();
        let f = &r.files[0];
        assert_eq!(f.spikes, 4, "{:?}", f.spike_channels);
        assert!(f.spike_channels.contains(&SpikeChannel {
            joint: "left_elbow".into(),
            channel: "Zrotation".into(),
            count: 3
        }));
        assert!(f.spike_channels.contains(&SpikeChannel {
            joint: "pelvis".into(),
            channel: "Yposition".into(),
            count: 1
        }));
        assert_eq!(r.files[1].spikes, 0);
        let err = max_err(&c, &truth);
        assert!(err < 2e-3, "{err} m");
        assert!(r.notes.iter().any(|n| n.contains("spike")), "{:?}", r.notes);
    }

    #[test]
    fn angles_wrapping_at_180_degrees_are_not_spikes() {
        let (truth, [mut a, mut b]) = fixture(0, 120.0);
        // The same angles written as v + 360 on every other frame (and v − 360 on others),
        // as real files do when a heading passes ±180°.
        for x in [&mut a, &mut b] {
            let rot = rot_flags(x);
            for (f, row) in x.frames.iter_mut().enumerate() {
                for (c, v) in row.iter_mut().enumerate() {
                    if rot[c] && c % 3 == f % 3 {
                        *v += if f % 2 == 0 { 360.0 } else { -360.0 };
                    }
                }
            }
        }
        let (c, r) = load(&a, &b, &echo()).unwrap();
        assert_eq!(r.files[0].spikes + r.files[1].spikes, 0, "{r:?}");
        assert!(max_err(&c, &truth) < 1e-3);
    }

    #[test]
    fn the_same_rotation_in_other_euler_angles_is_not_a_spike() {
        // Rz(a)·Rx(b)·Ry(c) = Rz(a + 180)·Rx(180 − b)·Ry(c + 180): one frame written the other
        // way jumps in all three channels but does not move the joint.
        let (truth, [mut a, b]) = fixture(0, 120.0);
        let ks = [
            chan(&a, "right_shoulder", Channel::Rot(2)),
            chan(&a, "right_shoulder", Channel::Rot(0)),
            chan(&a, "right_shoulder", Channel::Rot(1)),
        ];
        let row = &mut a.frames[150];
        let (z, x, y) = (row[ks[0]], row[ks[1]], row[ks[2]]);
        let before = Rotation3::from_axis_angle(&Vector3::z_axis(), z.to_radians())
            * Rotation3::from_axis_angle(&Vector3::x_axis(), x.to_radians())
            * Rotation3::from_axis_angle(&Vector3::y_axis(), y.to_radians());
        row[ks[0]] = z + 180.0;
        row[ks[1]] = 180.0 - x;
        row[ks[2]] = y + 180.0;
        let after = Rotation3::from_axis_angle(&Vector3::z_axis(), (z + 180.0).to_radians())
            * Rotation3::from_axis_angle(&Vector3::x_axis(), (180.0 - x).to_radians())
            * Rotation3::from_axis_angle(&Vector3::y_axis(), (y + 180.0).to_radians());
        assert!(before.angle_to(&after) < 1e-9);
        let (c, r) = load(&a, &b, &echo()).unwrap();
        assert_eq!(r.files[0].spikes, 0, "{:?}", r.files[0].spike_channels);
        assert!(max_err(&c, &truth) < 1e-3);
    }

    #[test]
    fn a_channel_that_is_mostly_spikes_is_an_error() {
        let (_, [mut a, b]) = fixture(0, 120.0);
        let k = chan(&a, "right_knee", Channel::Rot(0));
        let n = a.frames.len();
        for f in (5..n - 5).step_by(10) {
            a.frames[f][k] += 70.0;
        }
        let e = load(&a, &b, &echo()).unwrap_err();
        assert_eq!(e.file, "a.bvh");
        let s = e.to_string();
        assert!(
            s.contains("right_knee Xrotation") && s.contains("noise"),
            "{s}"
        );
    }

    #[test]
    fn any_frame_rate_is_resampled_to_30_hz_and_both_files_share_one() {
        for fps in [30.0, 60.0] {
            let (truth, [a, b]) = fixture(3, fps);
            let (c, r) = load(&a, &b, &echo()).unwrap();
            assert_eq!(r.files[0].source_fps, fps);
            assert_eq!(c.frames.len(), truth.frames.len(), "{fps} Hz");
            assert!(max_err(&c, &truth) < 1e-3, "{fps} Hz");
        }
        // CMU writes 120 Hz as ".0083333": read as 120 Hz.
        let (truth, [a, b]) = fixture(3, 120.0);
        let cmu = |x: &Bvh| {
            x.to_text()
                .replace("Frame Time: 0.008333333333333333", "Frame Time: .0083333")
        };
        let (ta, tb) = (cmu(&a), cmu(&b));
        assert!(ta.contains(".0083333\n"));
        let (c, r) = load_bvh_pair_str(
            ("a.bvh", &ta),
            ("b.bvh", &tb),
            &echo(),
            vec![],
            Interaction::Wave,
        )
        .unwrap();
        assert_eq!(r.files[0].frame_time_s, 0.0083333);
        assert_eq!(r.files[0].source_fps, 120.0);
        assert_eq!(c.frames.len(), truth.frames.len());
        assert!(max_err(&c, &truth) < 1e-3);
        // Different frame times: refused, naming both.
        let (_, [a, _]) = fixture(3, 120.0);
        let (_, [_, b]) = fixture(3, 60.0);
        let e = load(&a, &b, &echo()).unwrap_err().to_string();
        assert!(
            e.contains("frame times differ") && e.contains("a.bvh") && e.contains("b.bvh"),
            "{e}"
        );
    }

    #[test]
    fn z_up_files_are_turned_and_other_up_axes_refused() {
        let c = generate(&Split::Test.clip(1));
        // Echo's z mapped to x is written by `bvh::write` as file +Z up.
        let tilt = Rotation3::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2);
        let turned = |p: usize, r: &Rotation3<f64>| {
            person_from(
                &truth_frames(&c, p)
                    .iter()
                    .map(|f| f.map(|v| r * v))
                    .collect::<Vec<_>>(),
                120.0,
            )
        };
        let (a, b) = (turned(0, &tilt), turned(1, &tilt));
        let (got, r) = load(&a, &b, &echo()).unwrap();
        assert_eq!(r.files[0].up_axis, "+Z");
        assert!(r.notes.iter().any(|n| n.contains("Z-up")), "{:?}", r.notes);
        let err = max_err(&got, &c);
        assert!(err < 1e-3, "{err} m");
        // Upside down (file −Y up): refused.
        let flip = Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        let (a, b) = (turned(0, &flip), turned(1, &flip));
        let e = load(&a, &b, &echo()).unwrap_err().to_string();
        assert!(e.contains("a.bvh") && e.contains("along -Y"), "{e}");
    }

    /// Multiply every length in a file by `k` (offsets and position channels).
    fn rescale(b: &mut Bvh, k: f64) {
        for jt in b.joints.iter_mut() {
            jt.offset *= k;
        }
        let rot = rot_flags(b);
        for row in b.frames.iter_mut() {
            for (v, r) in row.iter_mut().zip(&rot) {
                if !*r {
                    *v *= k;
                }
            }
        }
    }

    #[test]
    fn units_come_from_the_option_the_map_or_the_standing_height() {
        let (truth, [a, b]) = fixture(2, 120.0);
        for (unit, size) in [("metres", 1.0), ("inches", 0.0254), ("millimetres", 0.001)] {
            let (mut a, mut b) = (a.clone(), b.clone());
            rescale(&mut a, 0.01 / size);
            rescale(&mut b, 0.01 / size);
            let (c, r) = load(&a, &b, &echo()).unwrap();
            assert_eq!(r.files[0].scale_source, format!("detected: {unit}"));
            assert_eq!(r.files[1].scale, size);
            let err = max_err(&c, &truth);
            assert!(err < 1e-3, "{unit}: {err} m");
        }
        // Given explicitly: used as given.
        let opts = PairOptions {
            scale: Some(0.01),
            ..echo()
        };
        let (c, r) = load(&a, &b, &opts).unwrap();
        assert_eq!(r.files[0].scale_source, "given");
        assert!(max_err(&c, &truth) < 1e-3);
        // Decimetres fit no known unit: an error asking for the scale.
        let (mut da, mut db) = (a.clone(), b.clone());
        rescale(&mut da, 0.1);
        rescale(&mut db, 0.1);
        let e = load(&da, &db, &echo()).unwrap_err();
        assert_eq!(e.file, "a.bvh");
        assert!(e.to_string().contains("--scale"), "{e}");
        // One file in inches, the other in centimetres: one capture volume has one unit.
        let mut ia = a.clone();
        rescale(&mut ia, 0.01 / 0.0254);
        let e = load(&ia, &b, &echo()).unwrap_err().to_string();
        assert!(e.contains("inches") && e.contains("centimetres"), "{e}");
    }

    /// Rename Echo's joints to the CMU skeleton's.
    fn cmu_names(b: &mut Bvh) {
        let map = bvh::cmu_map();
        for jt in b.joints.iter_mut() {
            if let Some(n) = map.get(jt.name.as_str()) {
                jt.name = n.clone();
            }
        }
    }

    #[test]
    fn the_cmu_map_uses_cmu_units_and_refuses_implausible_heights() {
        let (truth, [mut a, mut b]) = fixture(4, 120.0);
        for x in [&mut a, &mut b] {
            cmu_names(x);
            rescale(x, 0.01 / bvh::CMU_SCALE);
        }
        let (c, r) = load(&a, &b, &PairOptions::default()).unwrap();
        assert_eq!(r.files[0].scale, bvh::CMU_SCALE);
        assert_eq!(r.files[0].scale_source, "the joint map's unit");
        assert!(max_err(&c, &truth) < 1e-3);
        // The same names in centimetres: 0.0564 would make giants.
        let (_, [mut a, mut b]) = fixture(4, 120.0);
        cmu_names(&mut a);
        cmu_names(&mut b);
        let e = load(&a, &b, &PairOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("a.bvh") && e.contains("--scale"), "{e}");
    }

    #[test]
    fn the_floor_is_reported_and_a_distant_floor_moved_to_zero() {
        let (truth, [a, b]) = fixture(5, 120.0);
        let (_, r) = load(&a, &b, &echo()).unwrap();
        let low = r.files[0].lowest_foot_m.min(r.files[1].lowest_foot_m);
        assert!(low.abs() < 0.05, "{low}");
        assert_eq!(r.floor_shift_m, 0.0);
        // Both people 1 m up (a floor at another height): both moved down by the same amount.
        let (mut a, mut b) = (a, b);
        for x in [&mut a, &mut b] {
            let k = chan(x, "pelvis", Channel::Pos(1));
            for row in x.frames.iter_mut() {
                row[k] += 100.0;
            }
        }
        let (c, r) = load(&a, &b, &echo()).unwrap();
        assert!(
            (r.floor_shift_m + 1.0 + low).abs() < 1e-6,
            "{}",
            r.floor_shift_m
        );
        assert!(r.notes.iter().any(|n| n.contains("moved")), "{:?}", r.notes);
        // The pair moves as one: distances between the people are unchanged.
        let n = c.frames.len() - 1;
        let d = |x: &Clip, f: usize| (x.joints(f, 0)[0] - x.joints(f, 1)[0]).norm();
        assert!((d(&c, n) - d(&truth, n)).abs() < 1e-3);
        assert!(max_err(&c, &truth) < low.abs() + 2e-3);
    }

    #[test]
    fn subjects_keep_their_own_proportions_and_heights() {
        let (truth, [a, b]) = fixture(6, 120.0);
        let (c, r) = load(&a, &b, &echo()).unwrap();
        for p in 0..2 {
            // Height from head and ankles: within a few centimetres of the body it was made for.
            assert!(
                (r.files[p].height_m - truth.params.heights[p]).abs() < 0.06,
                "{r:?}"
            );
            assert_eq!(c.params.heights[p], r.files[p].height_m);
            // Bone lengths are the subject's own.
            let bones = |x: &Clip| {
                let q = x.joints(10, p);
                (1..NUM_JOINTS)
                    .map(|k| (q[k] - q[crate::skeleton::PARENTS[k] as usize]).norm())
                    .collect::<Vec<_>>()
            };
            for (g, t) in bones(&c).iter().zip(bones(&truth)) {
                assert!((g - t).abs() < 1e-3);
            }
        }
        let diff = (r.files[0].height_m - r.files[1].height_m)
            - (truth.params.heights[0] - truth.params.heights[1]);
        assert!(diff.abs() < 0.05, "{diff}");
    }

    #[test]
    fn lengths_within_half_a_second_are_trimmed_and_longer_refused() {
        let (truth, [a, b]) = fixture(0, 120.0);
        let mut short = b.clone();
        short.frames.truncate(b.frames.len() - 36); // 0.3 s
        let (c, r) = load(&a, &short, &echo()).unwrap();
        assert_eq!(r.files[0].frames_trimmed_end, 36);
        assert_eq!(r.files[1].frames_trimmed_end, 0);
        assert_eq!(c.frames.len(), truth.frames.len() - 9);
        assert!(max_err(&c, &truth) < 1e-3);
        let mut shorter = b.clone();
        shorter.frames.truncate(b.frames.len() - 120); // 1 s
        let e = load(&a, &shorter, &echo()).unwrap_err();
        assert_eq!(e.file, "a.bvh + b.bvh");
        let s = e.to_string();
        assert!(
            s.contains(&format!("{} frames", a.frames.len()))
                && s.contains(&format!("{} frames", shorter.frames.len())),
            "{s}"
        );
    }

    #[test]
    fn unusable_input_is_a_clear_error() {
        let (_, [a, b]) = fixture(0, 120.0);
        // No frames.
        let mut empty = a.clone();
        empty.frames.clear();
        let e = load(&empty, &b, &echo()).unwrap_err();
        assert_eq!(e.file, "a.bvh");
        assert!(e.to_string().contains("no frames"), "{e}");
        // A joint the map names is missing.
        let mut renamed = b.clone();
        renamed.joints[5].name = "knee".into();
        let e = load(&a, &renamed, &echo()).unwrap_err();
        assert_eq!(e.file, "b.bvh");
        assert!(e.to_string().contains("not in the file"), "{e}");
        // A non-finite value.
        let text = b.to_text();
        let at = text.find("MOTION").unwrap();
        let (head, tail) = text.split_at(at);
        let mut lines: Vec<String> = tail.lines().map(str::to_string).collect();
        let mut vals: Vec<&str> = lines[5].split(' ').collect();
        vals[4] = "nan";
        lines[5] = vals.join(" ");
        let bad = format!("{head}{}\n", lines.join("\n"));
        let e = load_bvh_pair_str(
            ("a.bvh", &a.to_text()),
            ("b.bvh", &bad),
            &echo(),
            vec![],
            Interaction::Idle,
        )
        .unwrap_err();
        assert_eq!(e.file, "b.bvh");
        assert!(e.to_string().contains("non-finite"), "{e}");
        // Shorter than one forecasting window after cleaning.
        let (mut sa, mut sb) = (a.clone(), b.clone());
        sa.frames.truncate(4 * 50 + 1);
        sb.frames.truncate(4 * 50 + 1);
        let e = load(&sa, &sb, &echo()).unwrap_err().to_string();
        assert!(
            e.contains("forecasting window") && e.contains("51 frames"),
            "{e}"
        );
        // Missing files are named.
        let e = load_bvh_pair(
            Path::new("/nonexistent/a.bvh"),
            Path::new("b.bvh"),
            &echo(),
            vec![],
            Interaction::Idle,
        )
        .unwrap_err();
        assert_eq!(e.file, "/nonexistent/a.bvh");
    }

    fn cmu_dir() -> Option<std::path::PathBuf> {
        let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/cmu");
        if d.join("18_01.bvh").exists() && d.join("19_01.bvh").exists() {
            Some(d)
        } else {
            eprintln!("skipped: {} (CMU 18_01/19_01) is not here", d.display());
            None
        }
    }

    #[test]
    fn the_real_cmu_handshake_pair_loads_with_plausible_facts() {
        let Some(d) = cmu_dir() else { return };
        let (c, r) = load_bvh_pair(
            &d.join("18_01.bvh"),
            &d.join("19_01.bvh"),
            &PairOptions::default(),
            vec!["Two people walk up to each other and shake hands.".into()],
            Interaction::Handshake,
        )
        .unwrap();
        eprintln!("{}", serde_json::to_string_pretty(&r).unwrap());
        for f in &r.files {
            assert_eq!(f.frames_in, 304);
            assert_eq!(f.source_fps, 120.0);
            assert_eq!(f.calibration_frames, 1);
            assert_eq!(f.calibration_rule.as_deref(), Some("whole-number angles"));
            assert_eq!(f.frames_dropped_start, 1);
            assert_eq!(f.frames_trimmed_end, 0);
            assert_eq!(f.scale, bvh::CMU_SCALE);
            assert_eq!(f.up_axis, "+Y");
            assert_eq!(f.spikes, 0);
            assert!((1.5..=2.0).contains(&f.height_m), "{}", f.height_m);
            assert!(f.lowest_foot_m.abs() < 0.1, "{}", f.lowest_foot_m);
        }
        // 303 frames at 120 Hz span 2.517 s: 76 frames at 30 Hz.
        assert_eq!(c.frames.len(), 76);
        assert_eq!(r.floor_shift_m, 0.0);
        let d = |f: usize| (c.joints(f, 0)[0] - c.joints(f, 1)[0]).norm();
        // They approach from 1.98 m to 0.74 m (about 1.1 s in), shake hands and step back apart.
        let n = c.frames.len();
        let (closest, at) =
            (0..n)
                .map(|f| (d(f), f))
                .fold((f64::INFINITY, 0), |m, x| if x.0 < m.0 { x } else { m });
        let (start, end) = (d(0), d(n - 1));
        let wrists = (0..n)
            .flat_map(|f| {
                let (a, b) = (c.joints(f, 0), c.joints(f, 1));
                [
                    (j::L_WRIST, j::L_WRIST),
                    (j::L_WRIST, j::R_WRIST),
                    (j::R_WRIST, j::L_WRIST),
                    (j::R_WRIST, j::R_WRIST),
                ]
                .map(|(x, y)| (a[x] - b[y]).norm())
            })
            .fold(f64::INFINITY, f64::min);
        eprintln!(
            "pelvis to pelvis: {start:.3} m at the start, {closest:.3} m at {:.2} s, {end:.3} m at the end; closest wrists {wrists:.3} m",
            at as f64 / FPS
        );
        assert!((start - 1.98).abs() < 0.1, "{start}");
        assert!((closest - 0.74).abs() < 0.1, "{closest}");
        assert!((0.8..1.6).contains(&(at as f64 / FPS)), "{at}");
        assert!((wrists - 0.375).abs() < 0.05, "{wrists}");
        assert!(end > 1.5, "{end}");
        // Never a calibration jump as movement: no pelvis moves more than 5 cm in one 30 Hz frame.
        for f in 1..c.frames.len() {
            for p in 0..2 {
                let step = (c.joints(f, p)[0] - c.joints(f - 1, p)[0]).norm();
                assert!(step < 0.05, "frame {f} person {p}: {step} m");
            }
        }
    }

    #[test]
    fn the_real_cmu_pair_with_its_quirks_exaggerated_still_loads() {
        let Some(d) = cmu_dir() else { return };
        let read = |n: &str| Bvh::read(&d.join(n)).unwrap();
        let (a, mut b) = (read("18_01.bvh"), read("19_01.bvh"));
        let (base, _) = clean_pair(
            [
                ("18_01.bvh".into(), a.clone()),
                ("19_01.bvh".into(), b.clone()),
            ],
            &PairOptions::default(),
            vec![],
            Interaction::Handshake,
        )
        .unwrap();
        // A sensor spike in B's right forearm, and B's take 0.25 s longer.
        let k = chan(&b, "RightForeArm", Channel::Rot(2));
        b.frames[100][k] += 90.0;
        let extra: Vec<Vec<f64>> = b.frames[b.frames.len() - 30..].to_vec();
        b.frames.extend(extra);
        let (c, r) = clean_pair(
            [("18_01.bvh".into(), a), ("19_01.bvh".into(), b)],
            &PairOptions::default(),
            vec![],
            Interaction::Handshake,
        )
        .unwrap();
        assert_eq!(r.files[1].spikes, 1, "{:?}", r.files[1].spike_channels);
        assert_eq!(r.files[1].frames_trimmed_end, 30);
        assert_eq!(c.frames.len(), base.frames.len());
        assert!(max_err(&c, &base) < 0.02, "{}", max_err(&c, &base));
    }
}
