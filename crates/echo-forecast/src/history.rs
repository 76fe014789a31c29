//! Both agents' joints at the model rate, newest last, with gap handling.
//!
//! Stamps are the sender's wall clock (`header.stamp_ns`); two guards keep one bad stamp from
//! wedging a history (see [`History::push_at`]): a frame stamped further ahead of this host's
//! clock than `max_ahead` never enters it (`from_future`), and when every frame has been
//! refused as reordered for `resync_after` since the last accepted one, the history restarts
//! from the next frame ([`Push::Resynced`]).

use std::collections::VecDeque;
use std::time::{Duration, Instant};

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
    /// Stamped further ahead of this host's clock than allowed.
    #[error("frame stamped {ahead_ms:.1} ms ahead of this host's clock (limit {limit_ms:.1} ms)")]
    FromFuture {
        /// How far ahead, ms.
        ahead_ms: f64,
        /// Accepted maximum, ms.
        limit_ms: f64,
    },
}

impl HistoryError {
    /// Short reason for counters.
    pub fn reason(&self) -> &'static str {
        match self {
            HistoryError::Reordered { .. } => "reordered",
            HistoryError::FromFuture { .. } => "from_future",
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
    /// Frames had been refused as reordered for at least the resync bound since the last one
    /// accepted (the sender's clock stepped back, or a frame stamped ahead of the stream got
    /// in): the history restarted from this frame, which was not newer than the last one held.
    Resynced {
        /// Time since the last accepted frame, ms.
        stalled_ms: u64,
    },
}

/// Default of how far ahead of this host's clock a frame may be stamped, ms.
pub const DEFAULT_MAX_AHEAD_MS: f64 = 1000.0;

/// Default of how long frames may be refused as reordered before the history restarts, ms.
pub const DEFAULT_RESYNC_AFTER_MS: f64 = 500.0;

/// Ring buffer of [`Pair`]s on the model-rate grid.
#[derive(Debug, Clone)]
pub struct History {
    period_ns: u64,
    capacity: usize,
    max_fill: usize,
    frames: VecDeque<Frame>,
    last_ns: Option<u64>,
    max_ahead_ns: u64,
    resync_after: Duration,
    /// When the newest frame was accepted (receiver's monotonic clock).
    accepted_at: Option<Instant>,
}

impl History {
    /// `rate_hz`: model rate; `capacity`: frames kept (≥ the model's observed frames);
    /// `max_fill`: longest gap, in frames, filled by interpolation. The guards take their
    /// defaults ([`DEFAULT_MAX_AHEAD_MS`], [`DEFAULT_RESYNC_AFTER_MS`]).
    pub fn new(rate_hz: f64, capacity: usize, max_fill: usize) -> History {
        History {
            period_ns: (1e9 / rate_hz.max(1e-3)) as u64,
            capacity: capacity.max(1),
            max_fill,
            frames: VecDeque::with_capacity(capacity.max(1)),
            last_ns: None,
            max_ahead_ns: 0,
            resync_after: Duration::ZERO,
            accepted_at: None,
        }
        .with_guards(DEFAULT_MAX_AHEAD_MS, DEFAULT_RESYNC_AFTER_MS)
    }

    /// Refuse frames stamped more than `max_ahead_ms` ahead of this host's clock; restart after
    /// `resync_after_ms` of frames refused as reordered (negative or NaN: 0).
    pub fn with_guards(mut self, max_ahead_ms: f64, resync_after_ms: f64) -> History {
        let ms = |v: f64| if v.is_nan() { 0.0 } else { v.max(0.0) };
        self.max_ahead_ns = (ms(max_ahead_ms) * 1e6) as u64;
        self.resync_after =
            Duration::try_from_secs_f64(ms(resync_after_ms) / 1e3).unwrap_or(Duration::MAX);
        self
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
        self.accepted_at = None;
    }

    /// `Ok` unless `stamp_ns` lies further ahead of `now_ns` (this host's wall clock) than
    /// allowed. Nothing changes either way.
    pub fn check_ahead(&self, stamp_ns: u64, now_ns: u64) -> Result<(), HistoryError> {
        if stamp_ns <= now_ns.saturating_add(self.max_ahead_ns) {
            return Ok(());
        }
        Err(HistoryError::FromFuture {
            ahead_ms: (stamp_ns - now_ns) as f64 / 1e6,
            limit_ms: self.max_ahead_ns as f64 / 1e6,
        })
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

    /// [`push_at`](Self::push_at) now (this host's wall clock and monotonic clock).
    pub fn push(&mut self, stamp_ns: u64, pair: Frame) -> Result<Push, HistoryError> {
        self.push_at(stamp_ns, pair, echo_msgs::now_ns(), Instant::now())
    }

    /// Add the frame observed at `stamp_ns`, received at `now_ns` on this host's wall clock
    /// and `now` on its monotonic clock. Frames arrive on the model-rate grid; a frame that
    /// lands `k > 1` periods after the last one means `k − 1` frames were lost: up to
    /// `max_fill` are interpolated, more restart the history.
    ///
    /// A frame stamped more than `max_ahead` after `now_ns` is refused (`from_future`) and
    /// changes nothing. A frame not newer than the last one is refused (`reordered`), unless no
    /// frame has been accepted for `resync_after`: then the history restarts from it
    /// ([`Push::Resynced`]), so no stamp, however far ahead of the stream, blocks it for
    /// longer than that.
    pub fn push_at(
        &mut self,
        stamp_ns: u64,
        pair: Frame,
        now_ns: u64,
        now: Instant,
    ) -> Result<Push, HistoryError> {
        self.check_ahead(stamp_ns, now_ns)?;
        let Some(last_ns) = self.last_ns else {
            self.append(pair);
            self.last_ns = Some(stamp_ns);
            self.accepted_at = Some(now);
            return Ok(Push::Appended);
        };
        if stamp_ns <= last_ns {
            let stalled = self
                .accepted_at
                .map_or(Duration::MAX, |t| now.saturating_duration_since(t));
            if stalled < self.resync_after {
                return Err(HistoryError::Reordered { stamp_ns, last_ns });
            }
            self.frames.clear();
            self.append(pair);
            self.last_ns = Some(stamp_ns);
            self.accepted_at = Some(now);
            return Ok(Push::Resynced {
                stalled_ms: stalled.as_millis().min(u64::MAX as u128) as u64,
            });
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
        self.accepted_at = Some(now);
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

    #[test]
    fn frames_stamped_ahead_of_this_hosts_clock_never_enter() {
        let mut h = History::new(15.0, 8, 3).with_guards(500.0, 500.0);
        let now_ns = 1_000 * P;
        let t0 = Instant::now();
        for k in 0..3 {
            h.push_at(990 * P + k * P, pair(k as f64), now_ns, t0)
                .unwrap();
        }
        for stamp in [u64::MAX, now_ns + 600_000_000] {
            assert!(matches!(
                h.push_at(stamp, pair(9.0), now_ns, t0),
                Err(HistoryError::FromFuture { .. })
            ));
        }
        assert_eq!((h.len(), h.last_stamp_ns()), (3, Some(992 * P)));
        assert_eq!(
            h.push_at(993 * P, pair(3.0), now_ns, t0),
            Ok(Push::Appended)
        );
        // Within the skew allowed: taken (here a long gap, so a restart).
        assert_eq!(
            h.push_at(now_ns + 400_000_000, pair(4.0), now_ns, t0),
            Ok(Push::Restarted { missing: 12 })
        );
    }

    #[test]
    fn frames_refused_as_reordered_for_too_long_restart_the_history() {
        let ms = |n: u64| Duration::from_millis(n);
        let mut h = History::new(15.0, 8, 3).with_guards(500.0, 500.0);
        let now_ns = u64::MAX / 2;
        let t0 = Instant::now();
        for k in 0..5 {
            h.push_at(k * P, pair(k as f64), now_ns, t0 + ms(67 * k))
                .unwrap();
        }
        // One frame stamped a minute ahead of the stream gets in (a long gap: a restart) …
        let t = t0 + ms(67 * 5);
        assert!(matches!(
            h.push_at(900 * P, pair(9.0), now_ns, t),
            Ok(Push::Restarted { .. })
        ));
        // … and the real stream is refused as reordered, but only for `resync_after`.
        for k in 5..12 {
            let at = t + ms(67 * (k - 4));
            assert!(at - t < ms(500));
            assert!(matches!(
                h.push_at(k * P, pair(k as f64), now_ns, at),
                Err(HistoryError::Reordered { .. })
            ));
        }
        assert_eq!(
            h.push_at(12 * P, pair(12.0), now_ns, t + ms(500)),
            Ok(Push::Resynced { stalled_ms: 500 })
        );
        assert_eq!((h.len(), h.last_stamp_ns()), (1, Some(12 * P)));
        assert_eq!(
            h.push_at(13 * P, pair(13.0), now_ns, t + ms(567)),
            Ok(Push::Appended)
        );
        // A reordered frame soon after an accepted one is still refused.
        assert!(matches!(
            h.push_at(12 * P, pair(12.0), now_ns, t + ms(600)),
            Err(HistoryError::Reordered { .. })
        ));
    }
}
