//! Per-source monotonic sequence checking, with per-source state that neither a flood of forged
//! sources, nor one forged sequence number, nor a restarted sender can wedge.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use crate::{Header, ValidationError};

/// Outcome of a sequence check.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SeqCheck {
    /// Messages skipped between the last accepted one and this one (lost on the way).
    pub gap: u64,
    /// The source was known but its state started over from this message: it had expired, or
    /// the source restarted (see [`SeqTracker`]).
    pub restarted: bool,
}

/// What is remembered of one source.
#[derive(Debug, Clone, Copy)]
struct Entry {
    /// Last accepted sequence number.
    last: u64,
    /// When the last message was accepted (receiver's monotonic clock).
    accepted_at: Instant,
    /// Messages accepted from this source (saturating).
    accepted: u64,
}

/// Tracks the last accepted sequence number per sender instance (`header.source`) and rejects
/// repeated or reordered messages (`out_of_order`). Sequence numbers start at 0 for each
/// publisher (`echo_bus::Publisher::put`) and rise by one per message sent.
///
/// Rules, per source (times on the receiver's monotonic clock, "silent" = no message
/// *accepted* from it, so a stream of refused messages does not keep an entry alive):
/// * a source not known (never heard, forgotten or evicted) is accepted with any number;
/// * a number after the last accepted one is accepted (`gap` = numbers skipped), unless it
///   jumps more than [`MAX_JUMP`](Self::MAX_JUMP) ahead (`seq_jump`): no sender publishes that
///   many messages before its entry expires, so it is a forged or corrupt number, and it
///   changes nothing;
/// * **restart**: a number not after the last one is accepted, and the source's state starts
///   over from it, when it is at most [`RESTART_MAX_SEQ`](Self::RESTART_MAX_SEQ) and the
///   source has been silent for at least [`RESTART_SILENCE`](Self::RESTART_SILENCE): a
///   restarted publisher numbers from 0 again (its first messages may be lost);
/// * any other number not after the last one is refused (`out_of_order`): a duplicate, a
///   reordered message, or a replay;
/// * **expiry**: a source silent for [`EXPIRY`](Self::EXPIRY) is forgotten; its next message is
///   accepted whatever its number (a restart whose first messages came too fast or too many
///   for the restart rule waits at most this long);
/// * **memory**: at most [`MAX_SOURCES`](Self::MAX_SOURCES) sources are remembered. When a new
///   one arrives at a full table, expired entries go first, then the least recently accepted
///   source among those heard from only once (a flood of forged sources, one message each,
///   evicts its own entries, not a live source's), then the least recently accepted of all.
///   The table is never cleared as a whole.
///
/// These checks catch duplicates, reordering and stale replays on the network; they do not
/// authenticate anyone (anyone who can publish can name a fresh source): access is decided by
/// the transport (mutual TLS and the router's access control).
#[derive(Debug, Clone)]
pub struct SeqTracker {
    sources: HashMap<String, Entry>,
    max_sources: usize,
}

impl Default for SeqTracker {
    fn default() -> Self {
        Self::new()
    }
}

impl SeqTracker {
    /// Most distinct sources remembered (bounded memory under a flood of forged sources).
    pub const MAX_SOURCES: usize = 256;
    /// A source silent (nothing accepted) this long is forgotten.
    pub const EXPIRY: Duration = Duration::from_secs(5);
    /// Silence after which a low sequence number is taken as the source's restart.
    pub const RESTART_SILENCE: Duration = Duration::from_millis(500);
    /// Highest sequence number a restarted source may arrive with (its first messages may be
    /// lost).
    pub const RESTART_MAX_SEQ: u64 = 16;
    /// Largest forward jump of a known source's sequence number (no sender publishes 2^20
    /// messages within [`EXPIRY`](Self::EXPIRY)).
    pub const MAX_JUMP: u64 = 1 << 20;

    /// A tracker that has seen nothing.
    pub fn new() -> Self {
        Self::with_max_sources(Self::MAX_SOURCES)
    }

    /// A tracker that remembers at most `max_sources` sources (at least 1).
    pub fn with_max_sources(max_sources: usize) -> Self {
        SeqTracker {
            sources: HashMap::new(),
            max_sources: max_sources.max(1),
        }
    }

    /// Sources remembered now.
    pub fn len(&self) -> usize {
        self.sources.len()
    }

    /// Whether no source is remembered.
    pub fn is_empty(&self) -> bool {
        self.sources.is_empty()
    }

    /// Accept `header` if its sequence number is in order for its source (rules above), now.
    pub fn check(&mut self, header: &Header) -> Result<SeqCheck, ValidationError> {
        self.check_at(header, Instant::now())
    }

    /// [`check`](Self::check) at receiver time `now`.
    pub fn check_at(&mut self, header: &Header, now: Instant) -> Result<SeqCheck, ValidationError> {
        let seq = header.seq;
        let Some(e) = self.sources.get_mut(&header.source) else {
            self.insert(&header.source, seq, now);
            return Ok(SeqCheck {
                gap: 0,
                restarted: false,
            });
        };
        let silent = now.saturating_duration_since(e.accepted_at);
        let start_over = |e: &mut Entry| {
            e.last = seq;
            e.accepted_at = now;
            e.accepted = e.accepted.saturating_add(1);
            SeqCheck {
                gap: 0,
                restarted: true,
            }
        };
        if silent >= Self::EXPIRY {
            return Ok(start_over(e));
        }
        if seq > e.last {
            let gap = seq - e.last - 1;
            if gap >= Self::MAX_JUMP {
                return Err(ValidationError::SeqJump {
                    source_id: header.source.clone(),
                    last: e.last,
                    got: seq,
                });
            }
            e.last = seq;
            e.accepted_at = now;
            e.accepted = e.accepted.saturating_add(1);
            return Ok(SeqCheck {
                gap,
                restarted: false,
            });
        }
        if seq <= Self::RESTART_MAX_SEQ && silent >= Self::RESTART_SILENCE {
            return Ok(start_over(e));
        }
        Err(ValidationError::OutOfOrder {
            source_id: header.source.clone(),
            last: e.last,
            got: seq,
        })
    }

    fn insert(&mut self, source: &str, seq: u64, now: Instant) {
        if self.sources.len() >= self.max_sources {
            self.sources
                .retain(|_, e| now.saturating_duration_since(e.accepted_at) < Self::EXPIRY);
        }
        if self.sources.len() >= self.max_sources {
            let victim = self
                .sources
                .iter()
                .min_by_key(|(_, e)| (e.accepted > 1, e.accepted_at))
                .map(|(k, _)| k.clone());
            if let Some(k) = victim {
                self.sources.remove(&k);
            }
        }
        self.sources.insert(
            source.to_string(),
            Entry {
                last: seq,
                accepted_at: now,
                accepted: 1,
            },
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn h(source: &str, seq: u64) -> Header {
        let mut h = Header::new("tiago", source, "");
        h.seq = seq;
        h
    }

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn accepts_increasing_and_reports_gaps() {
        let mut t = SeqTracker::new();
        assert_eq!(t.check(&h("a", 3)).unwrap().gap, 0);
        assert_eq!(t.check(&h("a", 4)).unwrap().gap, 0);
        assert_eq!(t.check(&h("a", 7)).unwrap().gap, 2);
    }

    #[test]
    fn rejects_repeat_and_reorder() {
        let mut t = SeqTracker::new();
        t.check(&h("a", 5)).unwrap();
        assert!(matches!(
            t.check(&h("a", 5)),
            Err(ValidationError::OutOfOrder {
                last: 5,
                got: 5,
                ..
            })
        ));
        assert!(t.check(&h("a", 2)).is_err());
        // another source is independent
        assert!(t.check(&h("b", 0)).is_ok());
    }

    #[test]
    fn a_flood_of_forged_sources_keeps_the_live_source() {
        let mut t = SeqTracker::new();
        let mut live = 10;
        t.check(&h("live", live)).unwrap();
        t.check(&h("live", live + 1)).unwrap();
        live += 1;
        // Forged sources, one message each, far more than are remembered; the live source keeps
        // talking now and then (more than a whole table of forgeries between two messages).
        for k in 0..5_000u64 {
            t.check(&h(&format!("forged-{k}"), 0)).unwrap();
            if k % 1_000 == 999 {
                // One message lost on the way: the gap shows the state was kept.
                live += 2;
                assert_eq!(t.check(&h("live", live)).unwrap().gap, 1, "after {k}");
            }
        }
        for k in 0..600u64 {
            t.check(&h(&format!("late-{k}"), 0)).unwrap();
        }
        // Its state survived: a replay of an old number is still refused, the next one is not.
        assert!(matches!(
            t.check(&h("live", live - 1)),
            Err(ValidationError::OutOfOrder { .. })
        ));
        assert_eq!(t.check(&h("live", live + 1)).unwrap().gap, 0);
    }

    #[test]
    fn memory_is_bounded_and_the_least_recently_heard_goes_first() {
        let t0 = Instant::now();
        let mut t = SeqTracker::with_max_sources(3);
        // Three live sources, each heard twice, at different times.
        for (k, s) in ["a", "b", "c"].iter().enumerate() {
            let at = t0 + (10 * k as u32) * MS;
            t.check_at(&h(s, 1), at).unwrap();
            t.check_at(&h(s, 2), at + MS).unwrap();
        }
        t.check_at(&h("a", 3), t0 + 40 * MS).unwrap();
        // A new one evicts the least recently heard ("b"), not everyone.
        t.check_at(&h("d", 0), t0 + 50 * MS).unwrap();
        assert_eq!(t.len(), 3);
        assert!(t.check_at(&h("a", 3), t0 + 51 * MS).is_err(), "a kept");
        assert!(t.check_at(&h("c", 2), t0 + 51 * MS).is_err(), "c kept");
        // "b" was forgotten: whatever it sends next is new to the tracker. It takes the place
        // of "d", heard from only once, although "c" was heard from less recently.
        assert_eq!(
            t.check_at(&h("b", 1), t0 + 52 * MS).unwrap(),
            SeqCheck {
                gap: 0,
                restarted: false
            }
        );
        assert_eq!(t.len(), 3);
        assert!(t.check_at(&h("c", 2), t0 + 53 * MS).is_err(), "c kept");
        assert!(t.check_at(&h("a", 3), t0 + 53 * MS).is_err(), "a kept");
    }

    #[test]
    fn a_silent_source_expires_and_is_then_accepted_from_any_number() {
        let t0 = Instant::now();
        let mut t = SeqTracker::new();
        t.check_at(&h("a", 500), t0).unwrap();
        // Silent (only refused messages) for less than the expiry: still refused.
        let before = t0 + SeqTracker::EXPIRY - MS;
        assert!(t.check_at(&h("a", 100), before).is_err());
        // From the expiry on, the entry is forgotten: any number starts it over.
        let after = t0 + SeqTracker::EXPIRY;
        assert_eq!(
            t.check_at(&h("a", 100), after).unwrap(),
            SeqCheck {
                gap: 0,
                restarted: true
            }
        );
        assert_eq!(t.check_at(&h("a", 101), after + MS).unwrap().gap, 0);
        // Expired entries are also what a full table drops first.
        let mut t = SeqTracker::with_max_sources(2);
        t.check_at(&h("old", 1), t0).unwrap();
        t.check_at(&h("old", 2), t0).unwrap();
        t.check_at(&h("new", 1), after).unwrap();
        t.check_at(&h("x", 0), after).unwrap();
        assert!(
            t.check_at(&h("new", 1), after).is_err(),
            "the live one stays"
        );
    }

    #[test]
    fn a_restarted_source_is_accepted_after_a_short_silence() {
        let t0 = Instant::now();
        let mut t = SeqTracker::new();
        t.check_at(&h("a", 500), t0).unwrap();
        // Back to 0 too soon after the last message: a replay, refused.
        assert!(t.check_at(&h("a", 0), t0 + 100 * MS).is_err());
        // After the silence, a number ≤ RESTART_MAX_SEQ is a restart (its first messages lost).
        let at = t0 + SeqTracker::RESTART_SILENCE;
        assert_eq!(
            t.check_at(&h("a", 2), at).unwrap(),
            SeqCheck {
                gap: 0,
                restarted: true
            }
        );
        assert_eq!(t.check_at(&h("a", 3), at + MS).unwrap().gap, 0);
        assert!(
            t.check_at(&h("a", 2), at + 2 * MS).is_err(),
            "replay refused"
        );
        // A higher number after the same silence is no restart.
        let mut t = SeqTracker::new();
        t.check_at(&h("a", 500), t0).unwrap();
        assert!(t
            .check_at(&h("a", SeqTracker::RESTART_MAX_SEQ + 1), at)
            .is_err());
    }

    #[test]
    fn replays_of_old_numbers_are_still_refused() {
        let t0 = Instant::now();
        let mut t = SeqTracker::new();
        for k in 0..=100u64 {
            t.check_at(&h("a", k), t0 + (k as u32) * MS).unwrap();
        }
        let last = t0 + 100 * MS;
        // Right away, any old number.
        for old in [0, 3, 50, 100] {
            assert!(
                matches!(
                    t.check_at(&h("a", old), last + MS),
                    Err(ValidationError::OutOfOrder { last: 100, .. })
                ),
                "{old}"
            );
        }
        // After a silence, still every number above the restart range.
        let later = last + 2 * SeqTracker::RESTART_SILENCE;
        for old in [17, 50, 100] {
            assert!(t.check_at(&h("a", old), later).is_err(), "{old}");
        }
        assert_eq!(t.check_at(&h("a", 101), later).unwrap().gap, 0);
    }

    #[test]
    fn an_impossible_jump_is_refused_and_changes_nothing() {
        let mut t = SeqTracker::new();
        t.check(&h("a", 10)).unwrap();
        let e = t.check(&h("a", u64::MAX)).unwrap_err();
        assert_eq!(e.reason(), "seq_jump");
        assert_eq!(t.check(&h("a", 11)).unwrap().gap, 0);
        assert_eq!(
            t.check(&h("a", 11 + SeqTracker::MAX_JUMP)).unwrap().gap,
            SeqTracker::MAX_JUMP - 1
        );
        // A new source may start anywhere.
        assert!(t.check(&h("b", u64::MAX)).is_ok());
    }
}
