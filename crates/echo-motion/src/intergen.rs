//! The InterGen / InterHuman processed layout — loader and exporter.
//!
//! ```text
//! <root>/motions_processed/person1/<id>.npy   float32 (T, 492), 30 fps, z-up, metres
//! <root>/motions_processed/person2/<id>.npy
//! <root>/annots/<id>.txt                      descriptions, one per line
//! <root>/split/{train,val,test}.txt           ids, one per line (optional ignore_list.txt)
//! ```
//! Columns 0–65: the 22 joint positions; 186–311: local rotations of joints 1..21 as 6D (the
//! first two columns of each rotation matrix, row-wise: R00 R01 R10 R11 R20 R21); the hand
//! columns (66–185, 312–491) are zero in exports and ignored on load. The loader trusts the
//! positions (rotations are re-derived by inverse kinematics when needed), so the 6D column
//! convention of a given release does not matter to it.

use std::path::{Path, PathBuf};

use echo_msgs::Interaction;
use nalgebra::Vector3;
use npyz::WriterBuilder;

use crate::dataset::DatasetError;
use crate::rotation::to_6d;
use crate::skeleton::{inverse, NUM_JOINTS};
use crate::synth::Clip;

/// Columns per frame.
pub const COLUMNS: usize = 492;
/// First rotation column.
pub const ROT_COL: usize = 186;

fn invalid(path: &Path, what: impl Into<String>) -> DatasetError {
    DatasetError::Invalid {
        path: path.to_path_buf(),
        what: what.into(),
    }
}

fn io(path: &Path, source: std::io::Error) -> DatasetError {
    DatasetError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// One frame of one person as the 492 InterGen columns.
pub fn frame_columns(p: &[Vector3<f64>; NUM_JOINTS]) -> Vec<f32> {
    let mut row = vec![0f32; COLUMNS];
    for (k, x) in p.iter().enumerate() {
        row[3 * k] = x.x as f32;
        row[3 * k + 1] = x.y as f32;
        row[3 * k + 2] = x.z as f32;
    }
    let (_, pose) = inverse(p);
    for k in 1..NUM_JOINTS {
        let r = to_6d(&pose.local[k].to_rotation_matrix());
        for (c, v) in r.iter().enumerate() {
            row[ROT_COL + 6 * (k - 1) + c] = *v as f32;
        }
    }
    row
}

/// Export clips (`ids[i]` for `clips[i]`) with the given split lists.
pub fn export(
    root: &Path,
    clips: &[Clip],
    splits: &[(&str, Vec<usize>)],
) -> Result<(), DatasetError> {
    for sub in [
        "motions_processed/person1",
        "motions_processed/person2",
        "annots",
        "split",
    ] {
        let d = root.join(sub);
        std::fs::create_dir_all(&d).map_err(|e| io(&d, e))?;
    }
    for (i, c) in clips.iter().enumerate() {
        let id = i.to_string();
        for p in 0..2 {
            let path = root.join(format!("motions_processed/person{}/{id}.npy", p + 1));
            let file = std::fs::File::create(&path).map_err(|e| io(&path, e))?;
            let mut w = npyz::WriteOptions::new()
                .default_dtype()
                .shape(&[c.frames.len() as u64, COLUMNS as u64])
                .writer(std::io::BufWriter::new(file))
                .begin_nd()
                .map_err(|e| io(&path, e))?;
            for f in 0..c.frames.len() {
                w.extend(frame_columns(&c.joints(f, p)))
                    .map_err(|e| io(&path, e))?;
            }
            w.finish().map_err(|e| io(&path, e))?;
        }
        let ap = root.join(format!("annots/{id}.txt"));
        std::fs::write(&ap, c.texts.join("\n")).map_err(|e| io(&ap, e))?;
    }
    for (name, ids) in splits {
        let sp = root.join(format!("split/{name}.txt"));
        let text: Vec<String> = ids.iter().map(|i| i.to_string()).collect();
        std::fs::write(&sp, text.join("\n")).map_err(|e| io(&sp, e))?;
    }
    Ok(())
}

/// Read one person's motion: (T, 492) float32 → joint positions per frame.
pub fn read_motion(path: &Path) -> Result<Vec<[Vector3<f64>; NUM_JOINTS]>, DatasetError> {
    let bytes = std::fs::read(path).map_err(|e| io(path, e))?;
    let npy = npyz::NpyFile::new(&bytes[..])
        .map_err(|e| invalid(path, format!("not a .npy file: {e}")))?;
    let shape = npy.shape().to_vec();
    if shape.len() != 2 || shape[1] as usize != COLUMNS || shape[0] == 0 {
        return Err(invalid(
            path,
            format!("expected shape (T, {COLUMNS}), found {shape:?}"),
        ));
    }
    let data: Vec<f32> = npy
        .into_vec()
        .map_err(|e| invalid(path, format!("expected float32 data: {e}")))?;
    let t = shape[0] as usize;
    if data.len() != t * COLUMNS {
        return Err(invalid(path, "truncated data"));
    }
    let mut out = Vec::with_capacity(t);
    for f in 0..t {
        let row = &data[f * COLUMNS..(f + 1) * COLUMNS];
        if row[..3 * NUM_JOINTS].iter().any(|x| !x.is_finite()) {
            return Err(invalid(
                path,
                format!("frame {f} has a non-finite position"),
            ));
        }
        out.push(std::array::from_fn(|k| {
            Vector3::new(
                row[3 * k] as f64,
                row[3 * k + 1] as f64,
                row[3 * k + 2] as f64,
            )
        }));
    }
    Ok(out)
}

/// The interaction type a description names (keyword match), `Idle` when none.
pub fn kind_from_text(texts: &[String]) -> Interaction {
    let t = texts.join(" ").to_lowercase();
    let rules: [(&str, Interaction); 12] = [
        ("handshake", Interaction::Handshake),
        ("shake", Interaction::Handshake),
        ("high five", Interaction::HighFive),
        ("hug", Interaction::Hug),
        ("embrace", Interaction::Hug),
        ("bow", Interaction::Bow),
        ("wave", Interaction::Wave),
        ("point", Interaction::PointAndLook),
        ("tap", Interaction::ShoulderTap),
        ("clap", Interaction::Clap),
        ("hand", Interaction::Handover),
        ("pass", Interaction::WalkPast),
    ];
    rules
        .iter()
        .find(|(k, _)| t.contains(k))
        .map_or(Interaction::Idle, |(_, i)| *i)
}

/// Load the clips listed in `split/<split>.txt` (minus `ignore_list.txt`).
pub fn load(root: &Path, split: &str) -> Result<Vec<(String, Clip)>, DatasetError> {
    let sp = root.join(format!("split/{split}.txt"));
    let list = std::fs::read_to_string(&sp).map_err(|e| io(&sp, e))?;
    let ignore: Vec<String> = std::fs::read_to_string(root.join("split/ignore_list.txt"))
        .map(|s| s.lines().map(|l| l.trim().to_string()).collect())
        .unwrap_or_default();
    let mut out = vec![];
    for id in list
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !ignore.iter().any(|x| x == l))
    {
        let p1 = read_motion(&root.join(format!("motions_processed/person1/{id}.npy")))?;
        let p2 = read_motion(&root.join(format!("motions_processed/person2/{id}.npy")))?;
        if p1.len() != p2.len() {
            return Err(invalid(
                &root.join(format!("motions_processed/person2/{id}.npy")),
                format!("{} frames, person1 has {}", p2.len(), p1.len()),
            ));
        }
        let ap: PathBuf = root.join(format!("annots/{id}.txt"));
        // A few annotation files are not UTF-8: decode lossily rather than fail.
        let texts: Vec<String> = std::fs::read(&ap)
            .map(|b| {
                String::from_utf8_lossy(&b)
                    .lines()
                    .map(|l| l.trim().to_string())
                    .filter(|l| !l.is_empty())
                    .collect()
            })
            .unwrap_or_default();
        let kind = kind_from_text(&texts);
        let height =
            |p: &[Vector3<f64>; NUM_JOINTS]| (p[15].z - p[7].z.min(p[8].z)).max(0.5) + 0.16;
        let heights = [height(&p1[0]), height(&p2[0])];
        out.push((
            id.to_string(),
            Clip::recorded(kind, texts, heights, &p1, &p2),
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{generate, Split};

    #[test]
    fn export_then_load_in_the_intergen_layout() {
        let scratch = tempfile::tempdir().unwrap();
        let root = scratch.path().to_path_buf();
        let clips: Vec<Clip> = (0..4).map(|i| generate(&Split::Test.clip(i))).collect();
        export(
            &root,
            &clips,
            &[("train", vec![0, 1]), ("test", vec![2, 3])],
        )
        .unwrap();
        std::fs::write(root.join("split/ignore_list.txt"), "3\n").unwrap();
        let got = load(&root, "test").unwrap();
        assert_eq!(got.len(), 1, "3 is ignored");
        let (id, c) = &got[0];
        assert_eq!(id, "2");
        assert_eq!(c.frames, clips[2].frames);
        assert_eq!(c.texts, clips[2].texts);
        assert_eq!(
            c.params.kind, clips[2].params.kind,
            "kind recovered from the descriptions"
        );
        // The 6D rotations in the file reproduce the positions through forward kinematics.
        let bytes = std::fs::read(root.join("motions_processed/person1/2.npy")).unwrap();
        let data: Vec<f32> = npyz::NpyFile::new(&bytes[..]).unwrap().into_vec().unwrap();
        let row = &data[10 * COLUMNS..11 * COLUMNS];
        let truth = clips[2].joints(10, 0);
        let (body, mut pose) = inverse(&truth);
        for k in 1..NUM_JOINTS {
            let v: [f64; 6] = std::array::from_fn(|c| row[ROT_COL + 6 * (k - 1) + c] as f64);
            pose.local[k] =
                nalgebra::UnitQuaternion::from_rotation_matrix(&crate::rotation::from_6d(&v));
        }
        let x = crate::skeleton::forward(&body, &pose);
        let err = (0..NUM_JOINTS)
            .map(|k| (x[k] - truth[k]).norm())
            .fold(0.0, f64::max);
        assert!(err < 1e-3, "{err} m");
    }

    #[test]
    fn bad_files_name_the_file_and_the_problem() {
        let scratch = tempfile::tempdir().unwrap();
        let root = scratch.path().to_path_buf();
        std::fs::create_dir_all(root.join("motions_processed/person1")).unwrap();
        std::fs::create_dir_all(root.join("split")).unwrap();
        std::fs::write(root.join("split/test.txt"), "7\n").unwrap();
        std::fs::write(root.join("motions_processed/person1/7.npy"), b"garbage").unwrap();
        let e = load(&root, "test").unwrap_err().to_string();
        assert!(
            e.contains("person1/7.npy") && e.contains("not a .npy"),
            "{e}"
        );
        // Wrong shape.
        let file = std::fs::File::create(root.join("motions_processed/person1/7.npy")).unwrap();
        let mut w = npyz::WriteOptions::new()
            .default_dtype()
            .shape(&[2, 10])
            .writer(file)
            .begin_nd()
            .unwrap();
        w.extend(vec![0f32; 20]).unwrap();
        w.finish().unwrap();
        let e = load(&root, "test").unwrap_err().to_string();
        assert!(e.contains("expected shape (T, 492)"), "{e}");
        let e = load(&root, "val").unwrap_err().to_string();
        assert!(e.contains("split/val.txt"), "{e}");
    }
}
