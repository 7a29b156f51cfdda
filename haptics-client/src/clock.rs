//! A monotonic clock: nanoseconds since an epoch fixed at construction.
//!
//! In the server one [`MonoClock`] is shared (by copy) between the servo thread and the network
//! side, so a command's arrival stamp and the servo tick's `now` are on the same time base; in
//! the workstation the hot path's clock stamps force commands and clock pings alike.

use std::time::Instant;

/// Monotonic nanoseconds since `epoch`. `Copy`: every thread holds its own.
#[derive(Debug, Clone, Copy)]
pub struct MonoClock {
    epoch: Instant,
}

impl MonoClock {
    /// A clock whose zero is now.
    pub fn new() -> Self {
        Self {
            epoch: Instant::now(),
        }
    }

    /// Nanoseconds since the epoch (saturating; 584 years of range).
    pub fn now_ns(&self) -> u64 {
        self.ns_at(Instant::now())
    }

    /// Nanoseconds since the epoch at `t`.
    pub fn ns_at(&self, t: Instant) -> u64 {
        u64::try_from(t.saturating_duration_since(self.epoch).as_nanos()).unwrap_or(u64::MAX)
    }

    /// The instant `ns` after the epoch.
    pub fn instant_at(&self, ns: u64) -> Instant {
        self.epoch + std::time::Duration::from_nanos(ns)
    }
}

impl Default for MonoClock {
    fn default() -> Self {
        Self::new()
    }
}
