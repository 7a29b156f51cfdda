//! NTP-style clock-offset estimation with a hard uncertainty bound.
//!
//! A ping carries four timestamps: `t0` client send and `t3` client receive on the client's
//! clock, `t1` server receive and `t2` server send on the server's. With `θ` the true offset
//! (server − client) and `d→`, `d←` the one-way delays,
//!
//! ```text
//! offset = ((t1 − t0) + (t2 − t3)) / 2 = θ + (d→ − d←) / 2
//! rtt    =  (t3 − t0) − (t2 − t1)      = d→ + d←
//! ```
//!
//! so, because both delays are non-negative, `|offset − θ| ≤ rtt / 2` for every sample, whatever
//! the asymmetry. The estimator keeps the last [`WINDOW`] samples and answers with the one of
//! least round trip (min-RTT filtering: queueing only ever adds delay, so outliers are long,
//! never short). The bound grows by `max_drift_ppm` × the age of that sample, so clocks that run
//! at slightly different rates stay inside it. Fixed-size storage: no allocation.

/// How many recent samples the estimator keeps.
pub const WINDOW: usize = 64;

/// One ping/pong exchange.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockSample {
    /// Client send, client clock, ns.
    pub t0_ns: u64,
    /// Server receive, server clock, ns.
    pub t1_ns: u64,
    /// Server send, server clock, ns.
    pub t2_ns: u64,
    /// Client receive, client clock, ns.
    pub t3_ns: u64,
}

impl ClockSample {
    /// Offset estimate (server − client) of this sample alone, ns.
    pub fn offset_ns(&self) -> i64 {
        let a = i128::from(self.t1_ns) - i128::from(self.t0_ns);
        let b = i128::from(self.t2_ns) - i128::from(self.t3_ns);
        ((a + b) / 2).clamp(i128::from(i64::MIN), i128::from(i64::MAX)) as i64
    }

    /// Round trip minus the server's hold time, ns; `None` if the timestamps are inconsistent
    /// (the client received before it sent, or the hold exceeds the whole round trip).
    ///
    /// The hold `t2 − t1` may be negative, and then adds to the round trip: the haptics
    /// server stamps a command's arrival `t1` when its receiver hands it to the servo, and
    /// the acknowledging cursor with `t2` = the start of the tick that applied it, so a
    /// command handed over between a tick's stamp and its drain of the ring is acknowledged
    /// by that tick with `t2 < t1`. The formula is exact either way.
    pub fn rtt_ns(&self) -> Option<u64> {
        let total = self.t3_ns.checked_sub(self.t0_ns)?;
        let hold = i128::from(self.t2_ns) - i128::from(self.t1_ns);
        u64::try_from(i128::from(total) - hold).ok()
    }
}

/// The estimator's answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockEstimate {
    /// Server clock minus client clock, ns.
    pub offset_ns: i64,
    /// Round trip of the sample used, ns.
    pub rtt_ns: u64,
    /// The true offset lies within `offset_ns ± uncertainty_ns`.
    pub uncertainty_ns: u64,
    /// Samples in the window.
    pub samples: usize,
}

impl ClockEstimate {
    /// A client-clock time expressed on the server's clock.
    pub fn client_to_server(&self, client_ns: u64) -> i128 {
        i128::from(client_ns) + i128::from(self.offset_ns)
    }

    /// A server-clock time expressed on the client's clock.
    pub fn server_to_client(&self, server_ns: u64) -> i128 {
        i128::from(server_ns) - i128::from(self.offset_ns)
    }
}

/// Why a sample was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ClockError {
    /// `t3 < t0`, `t2 < t1`, or the server held the ping longer than the round trip.
    #[error("inconsistent ping timestamps")]
    Inconsistent,
}

/// Min-RTT clock-offset estimator; see the module doc.
#[derive(Debug, Clone)]
pub struct ClockEstimator {
    samples: [Option<(ClockSample, u64)>; WINDOW],
    next: usize,
    max_drift_ppm: f64,
    newest_t3_ns: u64,
    refused: u64,
}

impl ClockEstimator {
    /// An empty estimator; `max_drift_ppm` is the largest rate difference of the two clocks
    /// (100 ppm covers ordinary crystal oscillators).
    pub fn new(max_drift_ppm: f64) -> Self {
        Self {
            samples: [None; WINDOW],
            next: 0,
            max_drift_ppm: max_drift_ppm.max(0.0),
            newest_t3_ns: 0,
            refused: 0,
        }
    }

    /// Add one exchange.
    pub fn add(&mut self, sample: ClockSample) -> Result<(), ClockError> {
        let Some(rtt) = sample.rtt_ns() else {
            self.refused += 1;
            return Err(ClockError::Inconsistent);
        };
        self.samples[self.next] = Some((sample, rtt));
        self.next = (self.next + 1) % WINDOW;
        self.newest_t3_ns = self.newest_t3_ns.max(sample.t3_ns);
        Ok(())
    }

    /// The current estimate, or `None` before the first sample.
    pub fn estimate(&self) -> Option<ClockEstimate> {
        let mut count = 0;
        let mut best: Option<(ClockSample, u64)> = None;
        for (sample, rtt) in self.samples.iter().flatten() {
            count += 1;
            if best.is_none_or(|(_, b)| *rtt < b) {
                best = Some((*sample, *rtt));
            }
        }
        let (sample, rtt) = best?;
        let age = self.newest_t3_ns.saturating_sub(sample.t3_ns);
        let drift = (age as f64 * self.max_drift_ppm * 1e-6).ceil() as u64;
        Some(ClockEstimate {
            offset_ns: sample.offset_ns(),
            rtt_ns: rtt,
            // +1 covers the integer halving in `offset_ns`.
            uncertainty_ns: (rtt / 2).saturating_add(1).saturating_add(drift),
            samples: count,
        })
    }

    /// Samples refused as inconsistent.
    pub fn refused(&self) -> u64 {
        self.refused
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn symmetric_delay_gives_exact_offset() {
        let mut e = ClockEstimator::new(0.0);
        // Server is 5 ms ahead; 100 µs each way; 10 µs hold.
        e.add(ClockSample {
            t0_ns: 1_000_000,
            t1_ns: 1_000_000 + 5_000_000 + 100_000,
            t2_ns: 1_000_000 + 5_000_000 + 110_000,
            t3_ns: 1_000_000 + 210_000,
        })
        .unwrap();
        let est = e.estimate().unwrap();
        assert_eq!(est.offset_ns, 5_000_000);
        assert_eq!(est.rtt_ns, 200_000);
    }

    #[test]
    fn absurd_timestamps_saturate_instead_of_overflowing() {
        let mut e = ClockEstimator::new(1e6);
        // A huge round trip, then a sample from the far future that ages it by ~u64::MAX.
        e.add(ClockSample {
            t0_ns: 0,
            t1_ns: 0,
            t2_ns: 0,
            t3_ns: u64::MAX - 1,
        })
        .unwrap();
        e.add(ClockSample {
            t0_ns: u64::MAX,
            t1_ns: 0,
            t2_ns: 0,
            t3_ns: u64::MAX,
        })
        .unwrap();
        let est = e.estimate().unwrap();
        assert_eq!(est.rtt_ns, 0);
        assert_eq!(est.uncertainty_ns, 1);
        let mut e = ClockEstimator::new(1e6);
        e.add(ClockSample {
            t0_ns: 0,
            t1_ns: 0,
            t2_ns: 0,
            t3_ns: u64::MAX,
        })
        .unwrap();
        e.add(ClockSample {
            t0_ns: 0,
            t1_ns: 0,
            t2_ns: 0,
            t3_ns: u64::MAX,
        })
        .unwrap();
        assert_eq!(e.estimate().unwrap().uncertainty_ns, u64::MAX / 2 + 1);
        let mut e = ClockEstimator::new(1e6);
        e.add(ClockSample {
            t0_ns: 0,
            t1_ns: 0,
            t2_ns: 0,
            t3_ns: u64::MAX / 2,
        })
        .unwrap();
        e.add(ClockSample {
            t0_ns: u64::MAX - 10,
            t1_ns: 0,
            t2_ns: 0,
            t3_ns: u64::MAX,
        })
        .unwrap();
        e.add(ClockSample {
            t0_ns: 0,
            t1_ns: 0,
            t2_ns: 0,
            t3_ns: 0,
        })
        .unwrap();
        // Best sample (rtt 0) is aged u64::MAX at 1e6 ppm: the bound saturates.
        assert_eq!(e.estimate().unwrap().uncertainty_ns, u64::MAX);
    }

    #[test]
    fn inconsistent_samples_are_refused() {
        let mut e = ClockEstimator::new(0.0);
        let bad = ClockSample {
            t0_ns: 10,
            t1_ns: 0,
            t2_ns: 100,
            t3_ns: 20,
        };
        assert_eq!(e.add(bad), Err(ClockError::Inconsistent));
        assert_eq!(e.refused(), 1);
        assert!(e.estimate().is_none());
    }

    #[test]
    fn a_negative_hold_adds_to_the_round_trip() {
        // Acknowledged by a tick stamped 10 ns before the command's arrival was stamped.
        let s = ClockSample {
            t0_ns: 0,
            t1_ns: 50,
            t2_ns: 40,
            t3_ns: 100,
        };
        assert_eq!(s.rtt_ns(), Some(110));
        // The one-way delays from any offset add up to it, as for a positive hold.
        let offset = 7;
        let down = s.t3_ns as i64 - s.t2_ns as i64 + offset;
        let up = s.t1_ns as i64 - offset - s.t0_ns as i64;
        assert_eq!(down + up, 110);
        let mut e = ClockEstimator::new(0.0);
        assert!(e.add(s).is_ok());
    }
}
