//! Metrics (plain Euclidean distances, not squared; millimetres; taken AT a future frame, not
//! averaged over the horizon — as TBIFormer / MI-Motion compute them):
//!
//! * JPE: mean over joints and agents of ‖ŷ − y‖ in the world frame;
//! * AJPE: the same after subtracting each agent's root (pelvis) from its joints;
//! * FDE: ‖ŷ_root − y_root‖, mean over agents;
//! * MPJPE: JPE averaged over every predicted frame;
//! * F1 of contact (margin 0) and proximity (margin 0.05 m) per frame;
//! * head rotation error: distance between normalised quaternions, min(‖q₁ − q₂‖, ‖q₁ + q₂‖).

use nalgebra::{UnitQuaternion, Vector3};

/// One frame of agents, each 22 joints.
pub type Frame = Vec<[Vector3<f64>; 22]>;

/// JPE (mm) of one frame.
pub fn jpe(pred: &[[Vector3<f64>; 22]], truth: &[[Vector3<f64>; 22]]) -> f64 {
    let mut s = 0.0;
    let mut n = 0;
    for (p, t) in pred.iter().zip(truth) {
        for (a, b) in p.iter().zip(t) {
            s += (a - b).norm();
            n += 1;
        }
    }
    1000.0 * s / n.max(1) as f64
}

/// AJPE (mm) of one frame: root-relative.
pub fn ajpe(pred: &Frame, truth: &Frame) -> f64 {
    let mut s = 0.0;
    let mut n = 0;
    for (p, t) in pred.iter().zip(truth) {
        for (a, b) in p.iter().zip(t) {
            s += ((a - p[0]) - (b - t[0])).norm();
            n += 1;
        }
    }
    1000.0 * s / n.max(1) as f64
}

/// FDE (mm) of one frame: the root.
pub fn fde(pred: &Frame, truth: &Frame) -> f64 {
    let s: f64 = pred
        .iter()
        .zip(truth)
        .map(|(p, t)| (p[0] - t[0]).norm())
        .sum();
    1000.0 * s / pred.len().max(1) as f64
}

/// MPJPE (mm) over a sequence of frames.
pub fn mpjpe(pred: &[Frame], truth: &[Frame]) -> f64 {
    let v: Vec<f64> = pred.iter().zip(truth).map(|(p, t)| jpe(p, t)).collect();
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// Confusion counts of a binary per-frame label.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Confusion {
    /// Predicted and true.
    pub tp: u64,
    /// Predicted, not true.
    pub fp: u64,
    /// Not predicted, true.
    pub fn_: u64,
    /// Neither.
    pub tn: u64,
}

impl Confusion {
    /// Add one frame.
    pub fn add(&mut self, pred: bool, truth: bool) {
        match (pred, truth) {
            (true, true) => self.tp += 1,
            (true, false) => self.fp += 1,
            (false, true) => self.fn_ += 1,
            (false, false) => self.tn += 1,
        }
    }

    /// F1 = 2·TP / (2·TP + FP + FN); `None` when there is no positive at all.
    pub fn f1(&self) -> Option<f64> {
        let d = 2 * self.tp + self.fp + self.fn_;
        (d > 0).then(|| 2.0 * self.tp as f64 / d as f64)
    }
}

/// Head rotation error between two orientations.
pub fn head_rotation_error(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> f64 {
    let (qa, qb) = (a.coords, b.coords);
    (qa - qb).norm().min((qa + qb).norm())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(offset: Vector3<f64>, root_shift: Vector3<f64>) -> Frame {
        let mut f = [Vector3::zeros(); 22];
        for (k, p) in f.iter_mut().enumerate() {
            *p = Vector3::new(k as f64 * 0.1, 0.0, 1.0) + offset;
        }
        f[0] += root_shift;
        vec![f, f]
    }

    #[test]
    fn hand_computed_errors() {
        let t = frame(Vector3::zeros(), Vector3::zeros());
        // Every joint 3 cm off along x: JPE 30 mm, AJPE 0 (rigid shift), FDE 30 mm.
        let p = frame(Vector3::new(0.03, 0.0, 0.0), Vector3::zeros());
        assert!((jpe(&p, &t) - 30.0).abs() < 1e-9);
        assert!(ajpe(&p, &t).abs() < 1e-9);
        assert!((fde(&p, &t) - 30.0).abs() < 1e-9);
        // Only the root 22 mm off.
        let p = frame(Vector3::zeros(), Vector3::new(0.0, 0.022, 0.0));
        assert!((fde(&p, &t) - 22.0).abs() < 1e-9);
        assert!(
            (jpe(&p, &t) - 1.0).abs() < 1e-9,
            "22 mm on one of 22 joints"
        );
        // Root moved, others not: root-relative, the 21 others are 22 mm off.
        assert!((ajpe(&p, &t) - 21.0).abs() < 1e-9);
        assert!((mpjpe(&[p.clone(), t.clone()], &[t.clone(), t]) - 0.5).abs() < 1e-9);
    }

    #[test]
    fn f1_and_head_error() {
        let mut c = Confusion::default();
        for (p, t) in [
            (true, true),
            (true, false),
            (false, true),
            (false, false),
            (true, true),
        ] {
            c.add(p, t);
        }
        // TP 2, FP 1, FN 1 → F1 = 4/6.
        assert!((c.f1().unwrap() - 4.0 / 6.0).abs() < 1e-12);
        assert_eq!(Confusion::default().f1(), None);
        let q = UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3);
        let minus = UnitQuaternion::new_unchecked(-q.into_inner());
        assert!(
            head_rotation_error(&q, &minus) < 1e-12,
            "q and −q are the same rotation"
        );
        let r = UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3);
        let e = head_rotation_error(&UnitQuaternion::identity(), &r);
        // ‖(0,0,sin .15, cos .15) − (0,0,0,1)‖ = 2·sin(0.075)
        assert!((e - 2.0 * (0.075f64).sin()).abs() < 1e-12);
    }
}
