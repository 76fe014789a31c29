//! The One-Euro filter (Casiez et al., CHI 2012): a first-order low-pass whose cutoff rises
//! with speed, so jitter at rest is smoothed and fast motion is followed with little lag.
//!
//! cutoff = min_cutoff + beta·|ẋ̂|, α = 1 / (1 + τ/Δt) with τ = 1 / (2π·cutoff).
//! For a ramp of speed v the steady-state lag is τ = 1 / (2π·(min_cutoff + beta·v)) seconds.

use serde::{Deserialize, Serialize};

/// Filter parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OneEuroParams {
    /// Cutoff at rest, Hz.
    pub min_cutoff_hz: f64,
    /// Cutoff increase per unit speed (Hz per m/s).
    pub beta: f64,
    /// Cutoff of the derivative estimate, Hz.
    pub d_cutoff_hz: f64,
}

impl Default for OneEuroParams {
    /// 1.5 Hz at rest, +4 Hz per m/s: ≤ 29 ms lag at 1 m/s, ≤ 45 ms at 0.5 m/s.
    fn default() -> Self {
        OneEuroParams {
            min_cutoff_hz: 1.5,
            beta: 4.0,
            d_cutoff_hz: 1.0,
        }
    }
}

impl OneEuroParams {
    /// Steady-state lag (seconds) for a ramp at `speed` (units/s).
    pub fn lag_bound_s(&self, speed: f64) -> f64 {
        1.0 / (2.0 * std::f64::consts::PI * (self.min_cutoff_hz + self.beta * speed.abs()))
    }
}

fn alpha(cutoff_hz: f64, dt: f64) -> f64 {
    let tau = 1.0 / (2.0 * std::f64::consts::PI * cutoff_hz);
    1.0 / (1.0 + tau / dt)
}

/// A One-Euro filter on a 3-vector (one joint), speed taken as the vector's norm.
#[derive(Debug, Clone)]
pub struct OneEuro3 {
    params: OneEuroParams,
    x: Option<[f64; 3]>,
    dx: [f64; 3],
}

impl OneEuro3 {
    /// A filter that has seen nothing.
    pub fn new(params: OneEuroParams) -> Self {
        OneEuro3 {
            params,
            x: None,
            dx: [0.0; 3],
        }
    }

    /// Filter a sample taken `dt` seconds after the previous one.
    pub fn filter(&mut self, x: [f64; 3], dt: f64) -> [f64; 3] {
        let Some(prev) = self.x else {
            self.x = Some(x);
            return x;
        };
        if dt <= 0.0 || !dt.is_finite() {
            return prev;
        }
        let ad = alpha(self.params.d_cutoff_hz, dt);
        for k in 0..3 {
            let raw = (x[k] - prev[k]) / dt;
            self.dx[k] += ad * (raw - self.dx[k]);
        }
        let speed = (self.dx[0].powi(2) + self.dx[1].powi(2) + self.dx[2].powi(2)).sqrt();
        let a = alpha(self.params.min_cutoff_hz + self.params.beta * speed, dt);
        let mut out = prev;
        for k in 0..3 {
            out[k] += a * (x[k] - prev[k]);
        }
        self.x = Some(out);
        out
    }

    /// Forget the state (next sample passes through).
    pub fn reset(&mut self) {
        self.x = None;
        self.dx = [0.0; 3];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smooths_jitter_at_rest() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let mut f = OneEuro3::new(OneEuroParams::default());
        let (mut raw, mut out) = (vec![], vec![]);
        for _ in 0..600 {
            let x = rng.random_range(-0.02..0.02);
            raw.push(x);
            out.push(f.filter([x, 0.0, 0.0], 1.0 / 30.0)[0]);
        }
        let sd = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
        assert!(
            sd(&out[30..]) < 0.5 * sd(&raw[30..]),
            "{} vs {}",
            sd(&out),
            sd(&raw)
        );
    }

    #[test]
    fn ramp_lag_stays_within_the_documented_bound() {
        let p = OneEuroParams::default();
        for speed in [0.5, 1.0, 2.0] {
            let mut f = OneEuro3::new(p);
            let dt = 1.0 / 30.0;
            let mut y = 0.0;
            for i in 0..300 {
                y = f.filter([speed * i as f64 * dt, 0.0, 0.0], dt)[0];
            }
            let lag_s = (speed * 299.0 * dt - y) / speed;
            // The discrete filter adds at most one sample period of lag to the continuous bound.
            assert!(
                lag_s <= p.lag_bound_s(speed) + dt,
                "speed {speed}: lag {lag_s}"
            );
            assert!(lag_s >= 0.0);
        }
    }
}
