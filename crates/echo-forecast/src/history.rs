//! Both agents' joints at the model rate, newest last, with gap handling.

use std::collections::VecDeque;

use echo_motion::skeleton::NUM_JOINTS;
use nalgebra::Vector3;

/// Both agents' joints at one instant: `[A, B]`.
pub type Pair = [[Vector3<f64>; NUM_JOINTS]; 2];

/// Joint values of the robot kept with each frame (for models whose second agent is the robot).
pub const ROBOT_STATE: usize = 17;

/// One instant: both agents' joints and the robot's joint values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Joints of A and B.
    pub pair: Pair,
    /// The robot's joint values.
    pub robot: [f64; ROBOT_STATE],
}

/// Why a frame was not taken.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HistoryError {
    /// Older than (or as old as) the newest frame held.
    #[error("frame at {stamp_ns} ns is not newer than the last one ({last_ns} ns)")]
    Reordered {
        /// Its stamp.
        stamp_ns: u64,
        /// The newest stamp held.
        last_ns: u64,
    },
}

impl HistoryError {
    /// Short reason for counters.
    pub fn reason(&self) -> &'static str {
        match self {
            HistoryError::Reordered { .. } => "reordered",
        }
    }
}

/// What a push did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Push {
    /// Appended as the next frame.
    Appended,
    /// Frames were missing: `filled` of them were interpolated, then it was appended.
    Filled {
        /// Frames filled in.
        filled: usize,
    },
    /// The gap was too long to fill: the history restarted from this frame.
    Restarted {
        /// Frames missing.
        missing: usize,
    },
}

/// Ring buffer of [`Pair`]s on the model-rate grid.
#[derive(Debug, Clone)]
pub struct History {
    period_ns: u64,
    capacity: usize,
    max_fill: usize,
    frames: VecDeque<Frame>,
    last_ns: Option<u64>,
}

impl History {
    /// `rate_hz`: model rate; `capacity`: frames kept (≥ the model's observed frames);
    /// `max_fill`: longest gap, in frames, filled by interpolation.
    pub fn new(rate_hz: f64, capacity: usize, max_fill: usize) -> History {
        History {
            period_ns: (1e9 / rate_hz.max(1e-3)) as u64,
            capacity: capacity.max(1),
            max_fill,
            frames: VecDeque::with_capacity(capacity.max(1)),
            last_ns: None,
        }
    }

    /// Frames held.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether empty.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Stamp of the newest frame.
    pub fn last_stamp_ns(&self) -> Option<u64> {
        self.last_ns
    }

    /// Forget everything (partner changed, input went stale).
    pub fn clear(&mut self) {
        self.frames.clear();
        self.last_ns = None;
    }

    /// The newest `n` frames, oldest first, if that many are held.
    pub fn last(&self, n: usize) -> Option<Vec<Frame>> {
        (self.frames.len() >= n).then(|| {
            self.frames
                .iter()
                .skip(self.frames.len() - n)
                .copied()
                .collect()
        })
    }

    fn append(&mut self, p: Frame) {
        if self.frames.len() == self.capacity {
            self.frames.pop_front();
        }
        self.frames.push_back(p);
    }

    /// Add the frame observed at `stamp_ns`. Frames arrive on the model-rate grid; a frame that
    /// lands `k > 1` periods after the last one means `k − 1` frames were lost: up to
    /// `max_fill` are interpolated, more restart the history.
    pub fn push(&mut self, stamp_ns: u64, pair: Frame) -> Result<Push, HistoryError> {
        let Some(last_ns) = self.last_ns else {
            self.append(pair);
            self.last_ns = Some(stamp_ns);
            return Ok(Push::Appended);
        };
        if stamp_ns <= last_ns {
            return Err(HistoryError::Reordered { stamp_ns, last_ns });
        }
        let steps = ((stamp_ns - last_ns) as f64 / self.period_ns as f64)
            .round()
            .max(1.0) as usize;
        let missing = steps - 1;
        let out = if missing == 0 {
            Push::Appended
        } else if missing <= self.max_fill {
            let prev = *self.frames.back().expect("a stamp implies a frame");
            for k in 1..=missing {
                let t = k as f64 / steps as f64;
                let mut mid = prev;
                for (a, agent) in mid.pair.iter_mut().enumerate() {
                    for (j, x) in agent.iter_mut().enumerate() {
                        *x = prev.pair[a][j].lerp(&pair.pair[a][j], t);
                    }
                }
                for (k, v) in mid.robot.iter_mut().enumerate() {
                    *v = prev.robot[k] + t * (pair.robot[k] - prev.robot[k]);
                }
                self.append(mid);
            }
            Push::Filled { filled: missing }
        } else {
            self.frames.clear();
            Push::Restarted { missing }
        };
        self.append(pair);
        self.last_ns = Some(stamp_ns);
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair(x: f64) -> Frame {
        Frame {
            pair: [
                [Vector3::new(x, 0.0, 1.0); NUM_JOINTS],
                [Vector3::new(-x, 0.0, 1.0); NUM_JOINTS],
            ],
            robot: [x; ROBOT_STATE],
        }
    }

    const P: u64 = 66_666_667;

    #[test]
    fn fills_short_gaps_restarts_after_long_ones_rejects_reordering() {
        let mut h = History::new(15.0, 8, 3);
        assert_eq!(h.push(0, pair(0.0)), Ok(Push::Appended));
        assert_eq!(h.push(P, pair(1.0)), Ok(Push::Appended));
        // Two frames lost: interpolated on the grid.
        assert_eq!(h.push(4 * P, pair(4.0)), Ok(Push::Filled { filled: 2 }));
        let f = h.last(5).unwrap();
        let xs: Vec<f64> = f.iter().map(|p| p.pair[0][0].x).collect();
        for (a, b) in xs.iter().zip([0.0, 1.0, 2.0, 3.0, 4.0]) {
            assert!((a - b).abs() < 1e-9, "{xs:?}");
        }
        assert!((f[2].pair[1][0].x + 2.0).abs() < 1e-9, "agent B too");
        assert!((f[3].robot[5] - 3.0).abs() < 1e-9, "and the robot's joints");
        // Reordered and duplicate frames are refused and change nothing.
        assert!(matches!(
            h.push(3 * P, pair(9.0)),
            Err(HistoryError::Reordered { .. })
        ));
        assert!(h.push(4 * P, pair(9.0)).is_err());
        assert_eq!(h.len(), 5);
        // Capacity bounds memory.
        for k in 5..20 {
            h.push(k * P, pair(k as f64)).unwrap();
        }
        assert_eq!(h.len(), 8);
        // Long gap: restart from the new frame.
        assert_eq!(
            h.push(40 * P, pair(40.0)),
            Ok(Push::Restarted { missing: 20 })
        );
        assert_eq!(h.len(), 1);
        assert!(h.last(2).is_none());
    }

    #[test]
    fn jitter_within_half_a_period_is_not_a_gap() {
        let mut h = History::new(15.0, 8, 3);
        h.push(0, pair(0.0)).unwrap();
        assert_eq!(h.push(P + P / 3, pair(1.0)), Ok(Push::Appended));
    }
}
