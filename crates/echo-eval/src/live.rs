//! Live forecast quality on a running system: each forecast's partner prediction at 1.0 s is
//! kept until the partner's skeleton at that time arrives, then scored against it — and against
//! holding the pose the forecast started from (zero velocity), the same way.

use std::collections::{BTreeMap, VecDeque};

use echo_msgs::{Forecast, HumanSkeletons};

/// Scored horizon, future frames after the newest observation (frame 15 at 15 Hz: 1.0 s).
pub const SCORE_STEP: usize = 14;
/// A forecast is scored with the skeleton frame within this of its horizon, ns (half a frame).
const MATCH_NS: u64 = 33_000_000;

/// A forecast waiting for the partner's frame at its scored horizon.
struct Pending {
    due_ns: u64,
    partner: u32,
    predicted: Vec<[f64; 3]>,
    held: Option<Vec<[f64; 3]>>,
}

/// Mean joint error at 1.0 s of live forecasts and of holding the pose.
#[derive(Default)]
pub struct ForecastScore {
    pending: VecDeque<Pending>,
    last_partner: BTreeMap<u64, (u32, Vec<[f64; 3]>)>,
    model_mm: Vec<f64>,
    hold_mm: Vec<f64>,
    /// The model's inference time per forecast, ms.
    pub inference_ms: Vec<f64>,
}

/// Mean distance between corresponding joints, mm.
pub fn mean_mm(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let n = a.len().min(b.len()).max(1) as f64;
    a.iter()
        .zip(b)
        .map(|(p, q)| {
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        })
        .sum::<f64>()
        / n
        * 1e3
}

/// The joints of track `id` in `h`.
pub fn joints_of(h: &HumanSkeletons, id: u32) -> Option<&[[f64; 3]]> {
    h.tracks
        .iter()
        .find(|t| t.track_id == id)
        .map(|t| t.pose.joints.as_slice())
}

impl ForecastScore {
    /// A forecast arrived.
    pub fn on_forecast(&mut self, f: &Forecast) {
        if self.inference_ms.len() < 100_000 {
            self.inference_ms.push(f.inference_ms);
        }
        let Some(predicted) = f.human.get(SCORE_STEP) else {
            return;
        };
        let stamp = f.header.stamp_ns;
        let held = self
            .last_partner
            .get(&stamp)
            .filter(|(id, _)| *id == f.partner_id)
            .map(|(_, j)| j.clone());
        let due_ns = stamp + ((SCORE_STEP + 1) as f64 / f.rate_hz.max(1e-3) * 1e9) as u64;
        if self.pending.len() < 1000 {
            self.pending.push_back(Pending {
                due_ns,
                partner: f.partner_id,
                predicted: predicted.clone(),
                held,
            });
        }
    }

    /// A skeleton frame arrived: remember the partner's pose, score the forecasts due now.
    pub fn on_humans(&mut self, h: &HumanSkeletons) {
        let stamp = h.header.stamp_ns;
        if let Some(pid) = h.partner_id {
            if let Some(j) = joints_of(h, pid) {
                self.last_partner.insert(stamp, (pid, j.to_vec()));
                while self.last_partner.len() > 64 {
                    self.last_partner.pop_first();
                }
            }
        }
        while let Some(p) = self.pending.front() {
            if p.due_ns > stamp + MATCH_NS {
                break;
            }
            let Some(p) = self.pending.pop_front() else {
                break;
            };
            if p.due_ns + MATCH_NS < stamp {
                continue;
            }
            if let Some(actual) = joints_of(h, p.partner) {
                self.model_mm.push(mean_mm(&p.predicted, actual));
                if let Some(held) = &p.held {
                    self.hold_mm.push(mean_mm(held, actual));
                }
            }
        }
    }

    /// (model error, holding error, forecasts scored), once both have samples.
    pub fn means(&self) -> Option<(f64, f64, usize)> {
        if self.model_mm.is_empty() || self.hold_mm.is_empty() {
            return None;
        }
        let m = self.model_mm.iter().sum::<f64>() / self.model_mm.len() as f64;
        let h = self.hold_mm.iter().sum::<f64>() / self.hold_mm.len() as f64;
        Some((m, h, self.model_mm.len()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use echo_msgs::{Header, HumanTrack};

    fn humans(stamp_ns: u64, x: f64) -> HumanSkeletons {
        let mut header = Header::new("r", "bridge", "base_footprint");
        header.stamp_ns = stamp_ns;
        HumanSkeletons {
            header,
            rate_hz: 15.0,
            tracks: vec![HumanTrack::from_joints(3, vec![[x, 0.0, 1.0]; 22])],
            partner_id: Some(3),
        }
    }

    #[test]
    fn a_forecast_is_scored_against_the_frame_at_its_horizon_and_against_holding() {
        let frame_ns = 66_666_667u64;
        let t0 = 1_000_000_000_000;
        let mut s = ForecastScore::default();
        // The partner walks +x at 1.5 m/s (0.1 m a frame).
        s.on_humans(&humans(t0, 0.0));
        let mut header = Header::new("r", "forecaster", "base_footprint");
        header.stamp_ns = t0;
        let f = Forecast {
            header,
            model: "m".into(),
            rate_hz: 15.0,
            partner_id: 3,
            // Predicts 1.4 m ahead at frame 15 (exact), nothing else matters.
            human: (1..=23)
                .map(|k| vec![[0.1 * k as f64, 0.0, 1.0]; 22])
                .collect(),
            robot: None,
            inference_ms: 2.5,
        };
        s.on_forecast(&f);
        for k in 1..=16u64 {
            s.on_humans(&humans(t0 + k * frame_ns, 0.1 * k as f64));
        }
        let (model, hold, n) = s.means().expect("scored");
        assert_eq!(n, 1);
        assert!(model < 1.0, "{model}");
        assert!((hold - 1500.0).abs() < 1.0, "{hold}");
        assert_eq!(s.inference_ms, vec![2.5]);
    }
}
