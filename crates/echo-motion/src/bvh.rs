//! BVH motion capture files: a reader for any skeleton (joint-name maps onto the 22 SMPL joints,
//! the CMU 31-joint skeleton built in, any frame rate resampled, Y-up converted to z-up) and a
//! writer for Echo's skeleton.
//!
//! Axes: BVH files are Y-up. Echo's world is REP-103 z-up (x forward, y left). The conversion
//! is the rotation taking Echo (x, y, z) to BVH (X, Y, Z) = (y, z, x): X left, Y up, Z forward.

use std::collections::HashMap;
use std::path::Path;

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use crate::skeleton::{inverse, JOINT_NAMES, NUM_JOINTS, PARENTS};

/// Errors naming the file, the line and the problem.
#[derive(Debug, thiserror::Error)]
#[error("{file}:{line}: {what}")]
pub struct BvhError {
    /// File (or "<string>").
    pub file: String,
    /// Line number (0 when not tied to a line).
    pub line: usize,
    /// What is wrong.
    pub what: String,
}

/// Channel of a joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channel {
    /// Translation.
    Pos(usize),
    /// Rotation about an axis (degrees in the file).
    Rot(usize),
}

/// One joint of a BVH hierarchy.
#[derive(Debug, Clone)]
pub struct BvhJoint {
    /// Name.
    pub name: String,
    /// Parent index.
    pub parent: Option<usize>,
    /// Offset from the parent, file units, Y-up.
    pub offset: Vector3<f64>,
    /// Channels in file order.
    pub channels: Vec<Channel>,
}

/// A parsed BVH file.
#[derive(Debug, Clone)]
pub struct Bvh {
    /// Joints (End Sites omitted).
    pub joints: Vec<BvhJoint>,
    /// Seconds per frame.
    pub frame_time: f64,
    /// Channel values per frame.
    pub frames: Vec<Vec<f64>>,
}

fn axis(c: char) -> Option<usize> {
    match c {
        'X' => Some(0),
        'Y' => Some(1),
        'Z' => Some(2),
        _ => None,
    }
}

impl Bvh {
    /// Parse BVH text; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Bvh, BvhError> {
        let err = |line: usize, what: String| BvhError {
            file: file.to_string(),
            line,
            what,
        };
        let mut tokens: Vec<(usize, &str)> = vec![];
        for (i, l) in text.lines().enumerate() {
            for t in l.split_whitespace() {
                tokens.push((i + 1, t));
            }
        }
        let mut k = 0;
        let mut next = |what: &str| -> Result<(usize, &str), BvhError> {
            let t = tokens
                .get(k)
                .copied()
                .ok_or_else(|| err(0, format!("unexpected end of file, expected {what}")))?;
            k += 1;
            Ok(t)
        };
        let (l, t) = next("HIERARCHY")?;
        if t != "HIERARCHY" {
            return Err(err(l, format!("expected HIERARCHY, found '{t}'")));
        }
        let mut joints: Vec<BvhJoint> = vec![];
        let mut stack: Vec<Option<usize>> = vec![];
        let mut pending: Option<(String, Option<usize>, bool)> = None;
        loop {
            let (l, t) = next("a joint")?;
            match t {
                "ROOT" | "JOINT" => {
                    let (_, name) = next("a joint name")?;
                    let parent = stack.last().copied().flatten();
                    if t == "ROOT" && !joints.is_empty() {
                        return Err(err(
                            l,
                            "a second ROOT (only one skeleton per file is supported)".into(),
                        ));
                    }
                    pending = Some((name.to_string(), parent, false));
                }
                "End" => {
                    let (_, _site) = next("Site")?;
                    pending = Some((String::new(), None, true));
                }
                "{" => {
                    let (name, parent, end) = pending
                        .take()
                        .ok_or_else(|| err(l, "'{' without a joint".into()))?;
                    if end {
                        stack.push(None);
                    } else {
                        joints.push(BvhJoint {
                            name,
                            parent,
                            offset: Vector3::zeros(),
                            channels: vec![],
                        });
                        stack.push(Some(joints.len() - 1));
                    }
                }
                "OFFSET" => {
                    let mut o = [0.0; 3];
                    for v in &mut o {
                        let (l, t) = next("an offset value")?;
                        *v = t
                            .parse()
                            .map_err(|_| err(l, format!("bad OFFSET value '{t}'")))?;
                    }
                    if let Some(Some(j)) = stack.last() {
                        joints[*j].offset = Vector3::from(o);
                    }
                }
                "CHANNELS" => {
                    let (l, n) = next("a channel count")?;
                    let n: usize = n
                        .parse()
                        .map_err(|_| err(l, format!("bad channel count '{n}'")))?;
                    if n > 6 {
                        return Err(err(l, format!("{n} channels (at most 6)")));
                    }
                    let j = stack
                        .last()
                        .copied()
                        .flatten()
                        .ok_or_else(|| err(l, "CHANNELS outside a joint".into()))?;
                    for _ in 0..n {
                        let (l, c) = next("a channel name")?;
                        let a = c
                            .chars()
                            .next()
                            .and_then(axis)
                            .ok_or_else(|| err(l, format!("unknown channel '{c}'")))?;
                        let ch = if c.ends_with("position") {
                            Channel::Pos(a)
                        } else if c.ends_with("rotation") {
                            Channel::Rot(a)
                        } else {
                            return Err(err(l, format!("unknown channel '{c}'")));
                        };
                        joints[j].channels.push(ch);
                    }
                }
                "}" => {
                    stack.pop().ok_or_else(|| err(l, "unbalanced '}'".into()))?;
                }
                "MOTION" => break,
                other => return Err(err(l, format!("unexpected '{other}' in HIERARCHY"))),
            }
        }
        if joints.is_empty() {
            return Err(err(0, "no joints".into()));
        }
        let (l, t) = next("Frames:")?;
        if t != "Frames:" {
            return Err(err(l, format!("expected 'Frames:', found '{t}'")));
        }
        let (l, n) = next("a frame count")?;
        let n: usize = n
            .parse()
            .map_err(|_| err(l, format!("bad frame count '{n}'")))?;
        let (l1, a) = next("Frame Time:")?;
        let (_, b) = next("Frame Time:")?;
        if a != "Frame" || b != "Time:" {
            return Err(err(l1, "expected 'Frame Time:'".into()));
        }
        let (l, ft) = next("a frame time")?;
        let frame_time: f64 = ft
            .parse()
            .map_err(|_| err(l, format!("bad frame time '{ft}'")))?;
        if !(frame_time.is_finite() && frame_time > 0.0) {
            return Err(err(
                l,
                format!("frame time must be positive, not {frame_time}"),
            ));
        }
        let per: usize = joints.iter().map(|j| j.channels.len()).sum();
        let mut frames = Vec::with_capacity(n);
        for f in 0..n {
            let mut row = Vec::with_capacity(per);
            for _ in 0..per {
                let (l, t) = next("a channel value").map_err(|e| BvhError {
                    what: format!("frame {f}: {}", e.what),
                    ..e
                })?;
                let v: f64 = t
                    .parse()
                    .map_err(|_| err(l, format!("bad value '{t}' in frame {f}")))?;
                if !v.is_finite() {
                    return Err(err(l, format!("non-finite value in frame {f}")));
                }
                row.push(v);
            }
            frames.push(row);
        }
        Ok(Bvh {
            joints,
            frame_time,
            frames,
        })
    }

    /// Read a file.
    pub fn read(path: &Path) -> Result<Bvh, BvhError> {
        let text = std::fs::read_to_string(path).map_err(|e| BvhError {
            file: path.display().to_string(),
            line: 0,
            what: e.to_string(),
        })?;
        Self::parse(&text, &path.display().to_string())
    }

    /// Index of each joint's first channel in a frame row.
    pub fn channel_starts(&self) -> Vec<usize> {
        self.joints
            .iter()
            .scan(0, |k, j| {
                let s = *k;
                *k += j.channels.len();
                Some(s)
            })
            .collect()
    }

    /// Local rotation and translation of joint `j` given that joint's channel values (in
    /// channel order): rotations compose in channel order; a joint without position channels
    /// keeps its offset.
    pub fn local(&self, j: usize, values: &[f64]) -> (Rotation3<f64>, Vector3<f64>) {
        let joint = &self.joints[j];
        let mut t = joint.offset;
        let mut r = Rotation3::identity();
        for (c, v) in joint.channels.iter().zip(values) {
            match c {
                Channel::Pos(a) => t[*a] = *v,
                Channel::Rot(a) => {
                    let ax = [Vector3::x_axis(), Vector3::y_axis(), Vector3::z_axis()][*a];
                    r *= Rotation3::from_axis_angle(&ax, v.to_radians());
                }
            }
        }
        (r, t)
    }

    /// BVH text of this file (End Sites, which are not kept, are written as zero offsets).
    pub fn to_text(&self) -> String {
        let name = |c: &Channel| match c {
            Channel::Pos(a) => format!("{}position", ["X", "Y", "Z"][*a]),
            Channel::Rot(a) => format!("{}rotation", ["X", "Y", "Z"][*a]),
        };
        fn joint(
            s: &mut String,
            b: &Bvh,
            j: usize,
            depth: usize,
            name: &dyn Fn(&Channel) -> String,
        ) {
            let pad = "  ".repeat(depth);
            let jt = &b.joints[j];
            let kw = if jt.parent.is_none() { "ROOT" } else { "JOINT" };
            let o = jt.offset;
            s.push_str(&format!(
                "{pad}{kw} {}\n{pad}{{\n{pad}  OFFSET {} {} {}\n",
                jt.name, o.x, o.y, o.z
            ));
            if !jt.channels.is_empty() {
                let names: Vec<String> = jt.channels.iter().map(name).collect();
                s.push_str(&format!(
                    "{pad}  CHANNELS {} {}\n",
                    names.len(),
                    names.join(" ")
                ));
            }
            let kids: Vec<usize> = (0..b.joints.len())
                .filter(|c| b.joints[*c].parent == Some(j))
                .collect();
            if kids.is_empty() {
                s.push_str(&format!(
                    "{pad}  End Site\n{pad}  {{\n{pad}    OFFSET 0 0 0\n{pad}  }}\n"
                ));
            }
            for c in kids {
                joint(s, b, c, depth + 1, name);
            }
            s.push_str(&format!("{pad}}}\n"));
        }
        let mut s = String::from("HIERARCHY\n");
        joint(&mut s, self, 0, 0, &name);
        s.push_str(&format!(
            "MOTION\nFrames: {}\nFrame Time: {}\n",
            self.frames.len(),
            self.frame_time
        ));
        for row in &self.frames {
            let vals: Vec<String> = row.iter().map(|v| v.to_string()).collect();
            s.push_str(&vals.join(" "));
            s.push('\n');
        }
        s
    }

    /// World positions of every joint at frame `f` (file units, Y-up).
    pub fn positions(&self, f: usize) -> Vec<Vector3<f64>> {
        let row = &self.frames[f];
        let mut k = 0;
        let mut global: Vec<(Rotation3<f64>, Vector3<f64>)> = Vec::with_capacity(self.joints.len());
        for (i, j) in self.joints.iter().enumerate() {
            let (r, t) = self.local(i, &row[k..k + j.channels.len()]);
            k += j.channels.len();
            let g = match j.parent {
                Some(p) => (global[p].0 * r, global[p].1 + global[p].0 * t),
                None => (r, t),
            };
            global.push(g);
        }
        global.into_iter().map(|(_, p)| p).collect()
    }
}

/// Echo (z-up) → BVH (Y-up) axes.
fn to_yup() -> Matrix3<f64> {
    Matrix3::new(0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0)
}

/// Joint-name map onto the 22 SMPL joints: SMPL name → BVH joint name.
pub type JointMap = HashMap<&'static str, String>;

/// The CMU 31-joint skeleton's names for the 22 joints.
pub fn cmu_map() -> JointMap {
    [
        ("pelvis", "Hips"),
        ("left_hip", "LeftUpLeg"),
        ("right_hip", "RightUpLeg"),
        ("spine1", "LowerBack"),
        ("left_knee", "LeftLeg"),
        ("right_knee", "RightLeg"),
        ("spine2", "Spine"),
        ("left_ankle", "LeftFoot"),
        ("right_ankle", "RightFoot"),
        ("spine3", "Spine1"),
        ("left_foot", "LeftToeBase"),
        ("right_foot", "RightToeBase"),
        ("neck", "Neck"),
        ("left_collar", "LeftShoulder"),
        ("right_collar", "RightShoulder"),
        ("head", "Head"),
        ("left_shoulder", "LeftArm"),
        ("right_shoulder", "RightArm"),
        ("left_elbow", "LeftForeArm"),
        ("right_elbow", "RightForeArm"),
        ("left_wrist", "LeftHand"),
        ("right_wrist", "RightHand"),
    ]
    .into_iter()
    .map(|(a, b)| (a, b.to_string()))
    .collect()
}

/// Echo's own names (files written by [`write`]).
pub fn echo_map() -> JointMap {
    JOINT_NAMES.iter().map(|n| (*n, n.to_string())).collect()
}

/// CMU's unit convention: file units × 0.0564 ≈ metres ("inches × 0.45").
pub const CMU_SCALE: f64 = 0.0564;

/// The file-unit scale a joint map's source is known to use: [`CMU_SCALE`] for [`cmu_map`];
/// `None` for any other map (its files may be in any unit).
pub fn default_scale(map: &JointMap) -> Option<f64> {
    (*map == cmu_map()).then_some(CMU_SCALE)
}

/// Index into `bvh.joints` of each of the 22 SMPL joints through `map`; an error names the
/// missing joint and lists the file's joints.
pub fn joint_indices(bvh: &Bvh, map: &JointMap, file: &str) -> Result<Vec<usize>, BvhError> {
    JOINT_NAMES
        .iter()
        .map(|n| {
            let want = map.get(n).ok_or_else(|| BvhError {
                file: file.into(),
                line: 0,
                what: format!("joint map has no entry for '{n}'"),
            })?;
            bvh.joints
                .iter()
                .position(|j| &j.name == want)
                .ok_or_else(|| BvhError {
                    file: file.into(),
                    line: 0,
                    what: format!(
                        "joint '{want}' (for {n}) is not in the file; it has: {}",
                        bvh.joints
                            .iter()
                            .map(|j| j.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                })
        })
        .collect()
}

/// The 22 joints per frame (z-up, metres) at `fps`, from a BVH via `map`; `scale` converts file
/// units to metres (0.01 for centimetres; CMU: [`CMU_SCALE`]). Linear resampling in time.
pub fn to_smpl(
    bvh: &Bvh,
    map: &JointMap,
    scale: f64,
    fps: f64,
    file: &str,
) -> Result<Vec<[Vector3<f64>; NUM_JOINTS]>, BvhError> {
    let idx = joint_indices(bvh, map, file)?;
    if bvh.frames.is_empty() {
        return Err(BvhError {
            file: file.into(),
            line: 0,
            what: "no frames".into(),
        });
    }
    let back = to_yup().transpose();
    let src: Vec<Vec<Vector3<f64>>> = (0..bvh.frames.len()).map(|f| bvh.positions(f)).collect();
    let duration = (bvh.frames.len() - 1) as f64 * bvh.frame_time;
    // A small tolerance: frame times are written with finite precision.
    let n = (duration * fps + 1e-4).floor() as usize + 1;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let t = i as f64 / fps / bvh.frame_time;
        let a = (t.floor() as usize).min(src.len() - 1);
        let b = (a + 1).min(src.len() - 1);
        let w = t - a as f64;
        out.push(std::array::from_fn(|k| {
            back * (src[a][idx[k]].lerp(&src[b][idx[k]], w)) * scale
        }));
    }
    Ok(out)
}

/// ZXY Euler angles (degrees) of R = Rz(a)·Rx(b)·Ry(c).
fn euler_zxy(r: &Matrix3<f64>) -> [f64; 3] {
    let b = r[(2, 1)].clamp(-1.0, 1.0).asin();
    let (a, c) = if b.cos().abs() > 1e-9 {
        ((-r[(0, 1)]).atan2(r[(1, 1)]), (-r[(2, 0)]).atan2(r[(2, 2)]))
    } else {
        (r[(1, 0)].atan2(r[(0, 0)]), 0.0)
    };
    [a.to_degrees(), b.to_degrees(), c.to_degrees()]
}

/// BVH text for one person's joint positions (z-up, metres) at `fps`, in centimetres, Y-up,
/// with Echo's joint names; offsets from the first frame, rotations by inverse kinematics.
pub fn write(frames: &[[Vector3<f64>; NUM_JOINTS]], fps: f64) -> String {
    let m = to_yup();
    let (body, _) = inverse(&frames[0]);
    let mut s = String::from("HIERARCHY\n");
    fn joint(
        s: &mut String,
        k: usize,
        depth: usize,
        body: &crate::skeleton::Body,
        m: &Matrix3<f64>,
        order: &mut Vec<usize>,
    ) {
        order.push(k);
        let pad = "  ".repeat(depth);
        let o = m * body.offsets[k] * 100.0;
        if k == 0 {
            s.push_str(&format!("ROOT {}\n{{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n", JOINT_NAMES[0]));
        } else {
            s.push_str(&format!("{pad}JOINT {}\n{pad}{{\n{pad}  OFFSET {:.6} {:.6} {:.6}\n{pad}  CHANNELS 3 Zrotation Xrotation Yrotation\n", JOINT_NAMES[k], o.x, o.y, o.z));
        }
        let kids: Vec<usize> = (0..NUM_JOINTS)
            .filter(|c| PARENTS[*c] == k as i32)
            .collect();
        if kids.is_empty() {
            s.push_str(&format!(
                "{pad}  End Site\n{pad}  {{\n{pad}    OFFSET 0 0 0\n{pad}  }}\n"
            ));
        }
        for c in kids {
            joint(s, c, depth + 1, body, m, order);
        }
        s.push_str(&format!("{pad}}}\n"));
    }
    // Channel values follow the hierarchy's depth-first order.
    let mut order = vec![];
    joint(&mut s, 0, 0, &body, &m, &mut order);
    s.push_str(&format!(
        "MOTION\nFrames: {}\nFrame Time: {:.8}\n",
        frames.len(),
        1.0 / fps
    ));
    for f in frames {
        let (_, pose) = inverse(f);
        let g = pose.root_orientation * pose.local[0];
        let mut row: Vec<f64> = (m * pose.root_position * 100.0).iter().copied().collect();
        let rot = |q: &UnitQuaternion<f64>| {
            euler_zxy(&(m * q.to_rotation_matrix().matrix() * m.transpose()))
        };
        row.extend(rot(&g));
        for &k in &order[1..] {
            row.extend(rot(&pose.local[k]));
        }
        s.push_str(
            &row.iter()
                .map(|v| format!("{v:.6}"))
                .collect::<Vec<_>>()
                .join(" "),
        );
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{generate, Split, FPS};

    #[test]
    fn write_then_read_reproduces_positions_within_a_millimetre() {
        for i in 0..4 {
            let c = generate(&Split::Test.clip(i));
            let frames: Vec<_> = (0..c.frames.len()).map(|f| c.joints(f, 0)).collect();
            let text = write(&frames, FPS);
            let bvh = Bvh::parse(&text, "<generated>").unwrap();
            let back = to_smpl(&bvh, &echo_map(), 0.01, FPS, "<generated>").unwrap();
            assert_eq!(back.len(), frames.len());
            let err = frames
                .iter()
                .zip(&back)
                .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).norm()))
                .fold(0.0, f64::max);
            assert!(err < 1e-3, "clip {i}: {err} m");
        }
    }

    /// A BVH at 120 fps whose joints carry the CMU skeleton's names (only the 22 mapped ones:
    /// the map picks joints by name, so extra joints in a real CMU file are simply unused).
    fn cmu_fixture(frames: &[[Vector3<f64>; NUM_JOINTS]], fps: f64) -> String {
        let text = write(frames, fps);
        let map = cmu_map();
        let mut out = String::new();
        for line in text.lines() {
            let mut l = line.to_string();
            for (smpl, cmu) in &map {
                for kw in ["ROOT ", "JOINT "] {
                    if l.trim_start() == format!("{kw}{smpl}") {
                        l = l.replace(&format!("{kw}{smpl}"), &format!("{kw}{cmu}"));
                    }
                }
            }
            out.push_str(&l);
            out.push('\n');
        }
        out
    }

    #[test]
    fn cmu_names_units_and_frame_rate_are_mapped() {
        let c = generate(&Split::Test.clip(1));
        let frames: Vec<_> = (0..c.frames.len()).map(|f| c.joints(f, 0)).collect();
        let text = cmu_fixture(&frames, 120.0);
        let bvh = Bvh::parse(&text, "cmu.bvh").unwrap();
        // The file says 120 fps: resampled to 30 fps there are a quarter of the frames.
        let back = to_smpl(&bvh, &cmu_map(), 0.01, 30.0, "cmu.bvh").unwrap();
        assert_eq!(back.len(), (frames.len() - 1) / 4 + 1);
        let err = (0..back.len())
            .map(|i| (back[i][20] - frames[4 * i][20]).norm())
            .fold(0.0, f64::max);
        assert!(err < 1e-3, "{err}");
    }

    #[test]
    fn to_text_round_trips() {
        let c = generate(&Split::Test.clip(2));
        let frames: Vec<_> = (0..c.frames.len()).map(|f| c.joints(f, 1)).collect();
        let bvh = Bvh::parse(&write(&frames, FPS), "<generated>").unwrap();
        let again = Bvh::parse(&bvh.to_text(), "<again>").unwrap();
        assert_eq!(again.frames, bvh.frames);
        assert_eq!(again.frame_time, bvh.frame_time);
        assert_eq!(again.joints.len(), bvh.joints.len());
        for (a, b) in again.joints.iter().zip(&bvh.joints) {
            assert_eq!(
                (&a.name, a.parent, a.offset, &a.channels),
                (&b.name, b.parent, b.offset, &b.channels)
            );
        }
        assert_eq!(default_scale(&cmu_map()), Some(CMU_SCALE));
        assert_eq!(default_scale(&echo_map()), None);
    }

    #[test]
    fn bad_files_give_the_file_line_and_problem() {
        let e = Bvh::parse("HIERARCHY\nROOT a\n{\n OFFSET 0 0 x\n", "bad.bvh").unwrap_err();
        assert_eq!((e.file.as_str(), e.line), ("bad.bvh", 4));
        assert!(e.to_string().contains("bad OFFSET value 'x'"));
        let e = Bvh::parse("HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 1 Xposition\n}\nMOTION\nFrames: 2\nFrame Time: 0.1\n1\n", "short.bvh").unwrap_err();
        assert!(e.to_string().contains("frame 1"), "{e}");
        let ok = Bvh::parse("HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 1 Xposition\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\n1\n", "one.bvh").unwrap();
        let e = to_smpl(&ok, &cmu_map(), 0.01, 30.0, "one.bvh").unwrap_err();
        assert!(e.to_string().contains("not in the file"), "{e}");
        assert!(Bvh::parse("", "empty.bvh").is_err());
    }
}
