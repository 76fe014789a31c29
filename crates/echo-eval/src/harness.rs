//! The evaluation harness: run a predictor over windows, aggregate per interaction type and
//! overall, print a paper-style markdown table, write JSON.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::metrics::{ajpe, fde, jpe, mpjpe, Confusion};
use crate::window::{horizon_frame, Predictor, Window, HORIZONS_S};

/// Errors at the reported horizons, millimetres.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Scores {
    /// Windows evaluated.
    pub windows: usize,
    /// JPE at each horizon of [`HORIZONS_S`].
    pub jpe: Vec<f64>,
    /// JPE at each horizon of person A (who starts a reaction-type interaction) and of person
    /// B (who answers); empty for single-person windows.
    #[serde(default)]
    pub jpe_by_agent: Vec<Vec<f64>>,
    /// AJPE at each horizon.
    pub ajpe: Vec<f64>,
    /// FDE at each horizon.
    pub fde: Vec<f64>,
    /// MPJPE over the whole predicted horizon.
    pub mpjpe: f64,
    /// F1 of contact between the two predicted agents vs the true pair (None: no contact at all).
    pub f1_contact: Option<f64>,
    /// F1 of proximity (5 cm).
    pub f1_proximity: Option<f64>,
}

#[derive(Default)]
struct Acc {
    n: usize,
    jpe: Vec<f64>,
    /// Per agent: sums and windows counted (two-agent windows only).
    by_agent: [Vec<f64>; 2],
    n_pairs: usize,
    ajpe: Vec<f64>,
    fde: Vec<f64>,
    mpjpe: f64,
    contact: Confusion,
    proximity: Confusion,
}

impl Acc {
    fn add(&mut self, pred: &[crate::metrics::Frame], w: &Window) {
        if self.jpe.is_empty() {
            self.jpe = vec![0.0; HORIZONS_S.len()];
            self.ajpe = vec![0.0; HORIZONS_S.len()];
            self.fde = vec![0.0; HORIZONS_S.len()];
        }
        for (i, h) in HORIZONS_S.iter().enumerate() {
            let k = horizon_frame(*h) - 1;
            self.jpe[i] += jpe(&pred[k], &w.future[k]);
            self.ajpe[i] += ajpe(&pred[k], &w.future[k]);
            self.fde[i] += fde(&pred[k], &w.future[k]);
        }
        if pred.first().is_some_and(|p| p.len() == 2)
            && w.future.first().is_some_and(|t| t.len() == 2)
        {
            for (a, sums) in self.by_agent.iter_mut().enumerate() {
                if sums.is_empty() {
                    *sums = vec![0.0; HORIZONS_S.len()];
                }
                for (i, h) in HORIZONS_S.iter().enumerate() {
                    let k = horizon_frame(*h) - 1;
                    sums[i] += jpe(&pred[k][a..=a], &w.future[k][a..=a]);
                }
            }
            self.n_pairs += 1;
        }
        self.mpjpe += mpjpe(pred, &w.future);
        for (p, t) in pred.iter().zip(&w.future) {
            if p.len() == 2 && t.len() == 2 {
                let (pc, pp) = echo_motion::sensors::contact_and_proximity(&p[0], &p[1]);
                let (tc, tp) = echo_motion::sensors::contact_and_proximity(&t[0], &t[1]);
                self.contact.add(pc, tc);
                self.proximity.add(pp, tp);
            }
        }
        self.n += 1;
    }

    fn scores(&self) -> Scores {
        let n = self.n.max(1) as f64;
        Scores {
            windows: self.n,
            jpe: self.jpe.iter().map(|x| x / n).collect(),
            jpe_by_agent: if self.n_pairs == 0 {
                vec![]
            } else {
                let m = self.n_pairs as f64;
                self.by_agent
                    .iter()
                    .map(|v| v.iter().map(|x| x / m).collect())
                    .collect()
            },
            ajpe: self.ajpe.iter().map(|x| x / n).collect(),
            fde: self.fde.iter().map(|x| x / n).collect(),
            mpjpe: self.mpjpe / n,
            f1_contact: self.contact.f1(),
            f1_proximity: self.proximity.f1(),
        }
    }
}

/// One predictor's results.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// Predictor name.
    pub predictor: String,
    /// Horizons, seconds.
    pub horizons_s: Vec<f64>,
    /// Over every window.
    pub overall: Scores,
    /// Per interaction type (snake_case names).
    pub per_kind: BTreeMap<String, Scores>,
    /// Windows per second of evaluation (prediction and metrics).
    pub windows_per_s: f64,
}

/// Evaluate `predictor` on `windows` in batches of `batch`.
pub fn evaluate(predictor: &mut dyn Predictor, windows: &[Window], batch: usize) -> Report {
    let started = std::time::Instant::now();
    let mut all = Acc::default();
    let mut per: BTreeMap<String, Acc> = BTreeMap::new();
    for chunk in windows.chunks(batch.max(1)) {
        let refs: Vec<&Window> = chunk.iter().collect();
        let preds = predictor.predict(&refs);
        for (p, w) in preds.iter().zip(chunk) {
            all.add(p, w);
            let kind = serde_json::to_value(w.kind)
                .ok()
                .and_then(|v| v.as_str().map(str::to_string))
                .unwrap_or_default();
            per.entry(kind).or_default().add(p, w);
        }
    }
    Report {
        predictor: predictor.name(),
        horizons_s: HORIZONS_S.to_vec(),
        overall: all.scores(),
        per_kind: per.into_iter().map(|(k, a)| (k, a.scores())).collect(),
        windows_per_s: windows.len() as f64 / started.elapsed().as_secs_f64().max(1e-9),
    }
}

/// Millimetres to one decimal, as table cells.
fn cells(v: &[f64]) -> String {
    v.iter()
        .map(|x| format!("{x:.1}"))
        .collect::<Vec<_>>()
        .join(" | ")
}

fn row(name: &str, s: &Scores) -> String {
    format!(
        "| {name} | {} | {} | {} |",
        cells(&s.jpe),
        cells(&s.ajpe),
        cells(&s.fde)
    )
}

/// Paper-style table: one row per report, JPE / AJPE / FDE at 0.2, 0.5, 1.0, 1.5 s (mm).
pub fn markdown_table(reports: &[Report]) -> String {
    let mut out = String::from(
        "| method | JPE 0.2 | JPE 0.5 | JPE 1.0 | JPE 1.5 | AJPE 0.2 | AJPE 0.5 | AJPE 1.0 | AJPE 1.5 | FDE 0.2 | FDE 0.5 | FDE 1.0 | FDE 1.5 |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in reports {
        out.push_str(&row(&r.predictor, &r.overall));
        out.push('\n');
    }
    out
}

/// Per-type table for `kinds` (JPE only, to keep it readable).
pub fn markdown_per_kind(reports: &[Report], kinds: &[&str]) -> String {
    let mut out = String::from("| type | method | JPE 0.2 | JPE 0.5 | JPE 1.0 | JPE 1.5 | windows |\n|---|---|---|---|---|---|---|\n");
    for k in kinds {
        for r in reports {
            if let Some(s) = r.per_kind.get(*k) {
                let v = cells(&s.jpe);
                out.push_str(&format!(
                    "| {k} | {} | {v} | {} |\n",
                    r.predictor, s.windows
                ));
            }
        }
    }
    out
}

/// Per-type table of the answering person B alone for `kinds` (JPE): in the reaction types B
/// answers A, so B's future is where the partner's motion matters.
pub fn markdown_responder(reports: &[Report], kinds: &[&str]) -> String {
    let mut out = String::from("| type | method | B: JPE 0.2 | JPE 0.5 | JPE 1.0 | JPE 1.5 | A: JPE 1.0 | JPE 1.5 |\n|---|---|---|---|---|---|---|---|\n");
    for k in kinds {
        for r in reports {
            if let Some([a, b]) = r.per_kind.get(*k).map(|s| s.jpe_by_agent.as_slice()) {
                out.push_str(&format!(
                    "| {k} | {} | {} | {} |\n",
                    r.predictor,
                    cells(b),
                    cells(&a[2..])
                ));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::window::{windows, ConstantVelocity, ZeroVelocity};
    use echo_motion::synth::{generate, ClipParams, ParamRanges};
    use echo_msgs::Interaction;

    fn some_windows() -> Vec<Window> {
        [Interaction::Wave, Interaction::WalkPast, Interaction::Idle]
            .iter()
            .enumerate()
            .flat_map(|(i, k)| {
                windows(
                    &generate(&ClipParams::sample(
                        *k,
                        &ParamRanges::train(),
                        100 + i as u64,
                    )),
                    8,
                )
            })
            .collect()
    }

    #[test]
    fn a_perfect_predictor_scores_zero_and_baselines_do_not() {
        struct Oracle;
        impl Predictor for Oracle {
            fn name(&self) -> String {
                "oracle".into()
            }
            fn predict(&mut self, batch: &[&Window]) -> Vec<Vec<crate::metrics::Frame>> {
                batch.iter().map(|w| w.future.clone()).collect()
            }
        }
        let w = some_windows();
        assert!(!w.is_empty());
        let r = evaluate(&mut Oracle, &w, 16);
        assert!(r.overall.jpe.iter().all(|x| *x == 0.0));
        let zv = evaluate(&mut ZeroVelocity, &w, 16);
        assert!(
            zv.overall.jpe[3] > zv.overall.jpe[0],
            "error grows with the horizon"
        );
        assert!(
            zv.per_kind["walk_past"].fde[3] > 500.0,
            "walkers move > 0.5 m in 1.5 s"
        );
        assert!(zv.per_kind["idle"].jpe[3] < zv.per_kind["walk_past"].jpe[3]);
        let cv = evaluate(&mut ConstantVelocity, &w, 16);
        // Walking is steady: constant velocity beats zero velocity there at short range.
        assert!(cv.per_kind["walk_past"].fde[0] < zv.per_kind["walk_past"].fde[0]);
        let table = markdown_table(&[zv, cv]);
        assert!(table.contains("| zero-velocity |") && table.lines().count() == 4);
    }

    #[test]
    fn errors_are_split_by_person() {
        // Exact for person A, holds person B's last pose: only B's column has an error.
        struct OracleForA;
        impl Predictor for OracleForA {
            fn name(&self) -> String {
                "oracle for A".into()
            }
            fn predict(&mut self, batch: &[&Window]) -> Vec<Vec<crate::metrics::Frame>> {
                let mut zv = ZeroVelocity.predict(batch);
                for (p, w) in zv.iter_mut().zip(batch) {
                    for (f, t) in p.iter_mut().zip(&w.future) {
                        f[0] = t[0];
                    }
                }
                zv
            }
        }
        let w = some_windows();
        let r = evaluate(&mut OracleForA, &w, 16);
        let wave = &r.per_kind["wave"];
        let [a, b] = [&wave.jpe_by_agent[0], &wave.jpe_by_agent[1]];
        assert!(a.iter().all(|x| *x == 0.0), "{a:?}");
        assert!(b[3] > 0.0);
        // The two people have equally many joints: the mean of both is the overall JPE.
        for i in 0..HORIZONS_S.len() {
            assert!((0.5 * (a[i] + b[i]) - wave.jpe[i]).abs() < 1e-9);
        }
        let t = markdown_responder(&[r], &["wave", "bow"]);
        assert_eq!(t.lines().count(), 3, "{t}");
    }
}
