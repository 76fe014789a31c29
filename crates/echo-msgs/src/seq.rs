//! Per-source monotonic sequence checking.

use std::collections::HashMap;

use crate::{Header, ValidationError};

/// Outcome of a sequence check.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SeqCheck {
    /// Messages skipped between the last accepted one and this one (lost on the way).
    pub gap: u64,
}

/// Tracks the last accepted sequence number per sender instance (`header.source`) and
/// rejects repeated or reordered messages. A new source starts fresh, so a restarted
/// sender is accepted at once.
#[derive(Debug, Default, Clone)]
pub struct SeqTracker {
    last: HashMap<String, u64>,
}

/// Most distinct sources remembered; older entries are forgotten first (bounded memory
/// under a flood of forged sources).
const MAX_SOURCES: usize = 256;

impl SeqTracker {
    /// A tracker that has seen nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// Accept `header` if its sequence number is after the last one from the same source.
    pub fn check(&mut self, header: &Header) -> Result<SeqCheck, ValidationError> {
        match self.last.get_mut(&header.source) {
            Some(last) if header.seq <= *last => Err(ValidationError::OutOfOrder {
                source_id: header.source.clone(),
                last: *last,
                got: header.seq,
            }),
            Some(last) => {
                let gap = header.seq - *last - 1;
                *last = header.seq;
                Ok(SeqCheck { gap })
            }
            None => {
                if self.last.len() >= MAX_SOURCES {
                    self.last.clear();
                }
                self.last.insert(header.source.clone(), header.seq);
                Ok(SeqCheck { gap: 0 })
            }
        }
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
}
