//! Sequence tracking: loss, reordering and duplicates, with a 64-packet replay window.
//!
//! Sequence numbers are `u32` and wrap; comparisons use serial-number arithmetic (RFC 1982),
//! so a session may run for more than the 49 days a 1 kHz stream takes to wrap. The newest
//! sequence and a 64-bit bitmap of the ones just below it are all the state: no allocation.

use serde::{Deserialize, Serialize};

/// How far behind the newest sequence a packet is still told apart from a replay.
pub const WINDOW: u32 = 64;

/// What one arriving sequence number was.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arrival {
    /// The first packet, or the next one expected.
    InOrder,
    /// Ahead of the next expected one: `missing` packets were skipped (lost so far).
    Gap {
        /// Sequence numbers skipped over.
        missing: u32,
    },
    /// Behind the newest but inside the window and not seen before: reordered (fills a gap).
    Late,
    /// Already received.
    Duplicate,
    /// Older than the window: cannot be checked, treated as a replay.
    Stale,
}

impl Arrival {
    /// Whether the packet is new (may be used).
    pub fn is_new(self) -> bool {
        matches!(self, Arrival::InOrder | Arrival::Gap { .. } | Arrival::Late)
    }
}

/// Counters of a packet stream.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SequenceStats {
    /// Distinct packets received.
    pub received: u64,
    /// Packets skipped and not (yet) arrived late.
    pub lost: u64,
    /// Packets that arrived after a later one.
    pub reordered: u64,
    /// Packets received twice.
    pub duplicates: u64,
    /// Packets too old to check.
    pub stale: u64,
}

/// Tracks one direction's sequence numbers; see the module doc.
#[derive(Debug, Clone, Default)]
pub struct SequenceTracker {
    newest: Option<u32>,
    /// Bit `i` set: sequence `newest - i` was received (bit 0 is `newest` itself).
    seen: u64,
    stats: SequenceStats,
}

impl SequenceTracker {
    /// An empty tracker.
    pub fn new() -> Self {
        Self::default()
    }

    /// Classify `sequence` without recording it.
    pub fn classify(&self, sequence: u32) -> Arrival {
        let Some(newest) = self.newest else {
            return Arrival::InOrder;
        };
        let ahead = sequence.wrapping_sub(newest);
        if ahead != 0 && ahead < 1 << 31 {
            return if ahead == 1 {
                Arrival::InOrder
            } else {
                Arrival::Gap { missing: ahead - 1 }
            };
        }
        let behind = newest.wrapping_sub(sequence);
        if behind >= WINDOW {
            Arrival::Stale
        } else if self.seen & (1u64 << behind) != 0 {
            Arrival::Duplicate
        } else {
            Arrival::Late
        }
    }

    /// Classify `sequence` and record it in the window and the counters.
    pub fn record(&mut self, sequence: u32) -> Arrival {
        let arrival = self.classify(sequence);
        let s = &mut self.stats;
        match arrival {
            Arrival::InOrder | Arrival::Gap { .. } => {
                let advance = match self.newest {
                    Some(newest) => sequence.wrapping_sub(newest),
                    None => 0,
                };
                if let Arrival::Gap { missing } = arrival {
                    s.lost += u64::from(missing);
                }
                self.seen = if advance >= 64 {
                    0
                } else {
                    self.seen << advance
                };
                self.seen |= 1;
                self.newest = Some(sequence);
                s.received += 1;
            }
            Arrival::Late => {
                let behind = self.newest.map_or(0, |n| n.wrapping_sub(sequence));
                self.seen |= 1u64 << behind;
                s.received += 1;
                s.reordered += 1;
                s.lost = s.lost.saturating_sub(1);
            }
            Arrival::Duplicate => s.duplicates += 1,
            Arrival::Stale => s.stale += 1,
        }
        arrival
    }

    /// The counters so far.
    pub fn stats(&self) -> SequenceStats {
        self.stats
    }

    /// The newest sequence received.
    pub fn newest(&self) -> Option<u32> {
        self.newest
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn in_order_stream_has_no_loss() {
        let mut t = SequenceTracker::new();
        for s in 0..1000 {
            assert_eq!(t.record(s), Arrival::InOrder);
        }
        assert_eq!(
            t.stats(),
            SequenceStats {
                received: 1000,
                ..Default::default()
            }
        );
    }

    #[test]
    fn gap_then_late_fill_counts_reorder_not_loss() {
        let mut t = SequenceTracker::new();
        t.record(1);
        assert_eq!(t.record(4), Arrival::Gap { missing: 2 });
        assert_eq!(t.stats().lost, 2);
        assert_eq!(t.record(2), Arrival::Late);
        assert_eq!(t.record(2), Arrival::Duplicate);
        let s = t.stats();
        assert_eq!(
            (s.received, s.lost, s.reordered, s.duplicates),
            (3, 1, 1, 1)
        );
    }

    #[test]
    fn window_edge_and_stale() {
        let mut t = SequenceTracker::new();
        t.record(100);
        assert_eq!(t.classify(100 - 63), Arrival::Late);
        assert_eq!(t.classify(100 - 64), Arrival::Stale);
        assert_eq!(t.record(100 - 64), Arrival::Stale);
        assert_eq!(t.stats().stale, 1);
    }

    #[test]
    fn wraps_around_u32() {
        let mut t = SequenceTracker::new();
        t.record(u32::MAX - 1);
        assert_eq!(t.record(u32::MAX), Arrival::InOrder);
        assert_eq!(t.record(0), Arrival::InOrder);
        assert_eq!(t.record(u32::MAX), Arrival::Duplicate);
        assert_eq!(t.record(2), Arrival::Gap { missing: 1 });
        assert_eq!(t.record(1), Arrival::Late);
    }

    #[test]
    fn big_jump_clears_window() {
        let mut t = SequenceTracker::new();
        t.record(0);
        assert_eq!(t.record(1000), Arrival::Gap { missing: 999 });
        assert_eq!(t.classify(999), Arrival::Late);
        assert_eq!(t.classify(1000), Arrival::Duplicate);
    }
}
