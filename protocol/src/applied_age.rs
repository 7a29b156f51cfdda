//! The age of the command each servo tick applies, counted from the cursor stream alone.
//!
//! What the hand feels is decided per servo tick (DESIGN §6, tick-synchronous delivery): the
//! figure that matters is how many ticks old the cursor is that the applied command answers.
//! Every [`CursorSample`](crate::CursorSample) carries the servo tick it was read at and
//! acknowledges the command that tick applied ([`ForceAck`](crate::ForceAck)); the workstation
//! knows which cursor each of its commands answered. So, per cursor received:
//! `age = servo_tick(this cursor) − servo_tick(the cursor the applied command answers)`.
//! Age 1 is the best possible (the command answering the previous tick's cursor, applied this
//! tick); 2 means the answer missed a tick and the device rendered a model one tick older.
//!
//! Sans-IO and allocation-free: [`AppliedAge::record`] takes the two ticks (or `None` before
//! any command is applied).

use serde::{Deserialize, Serialize};

/// Counts of ticks by the age of the command they applied.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AppliedAge {
    /// Ticks that applied the answer to the previous tick's cursor (age 1, or 0 which a
    /// server cannot produce but is counted here rather than lost).
    pub next: u64,
    /// Age 2: one tick late.
    pub two: u64,
    /// Age 3 or more.
    pub three_or_more: u64,
    /// Ticks with no command yet (or acknowledging one this side does not know).
    pub no_command: u64,
}

impl AppliedAge {
    /// One tick: its servo tick, and the servo tick of the cursor its applied command answers
    /// (`None`: no command applied yet, or not one of ours).
    pub fn record(&mut self, tick: u32, answers_tick: Option<u32>) {
        match answers_tick.map(|a| tick.wrapping_sub(a)) {
            None => self.no_command += 1,
            Some(0 | 1) => self.next += 1,
            Some(2) => self.two += 1,
            // A wrapped difference this large is an answer from the future: not ours.
            Some(a) if a > u32::MAX / 2 => self.no_command += 1,
            Some(_) => self.three_or_more += 1,
        }
    }

    /// Ticks counted.
    pub fn ticks(&self) -> u64 {
        self.next + self.two + self.three_or_more + self.no_command
    }

    /// The fractions, for a report.
    pub fn fractions(&self) -> AppliedAgeFractions {
        let n = self.ticks().max(1) as f64;
        AppliedAgeFractions {
            ticks: self.ticks(),
            next_tick: self.next as f64 / n,
            two_ticks: self.two as f64 / n,
            three_or_more: self.three_or_more as f64 / n,
            no_command: self.no_command as f64 / n,
        }
    }
}

/// [`AppliedAge`] as fractions of the ticks counted (`applied_age_ticks` in reports).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct AppliedAgeFractions {
    /// Ticks counted (cursors received).
    pub ticks: u64,
    /// Applied the answer to the previous tick's cursor.
    pub next_tick: f64,
    /// Applied an answer one tick late.
    pub two_ticks: f64,
    /// Applied an answer two or more ticks late.
    pub three_or_more: f64,
    /// No command applied yet.
    pub no_command: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ages_are_counted_by_ticks_between_the_answered_cursor_and_the_tick() {
        let mut a = AppliedAge::default();
        a.record(10, None);
        a.record(11, Some(10));
        a.record(12, Some(10)); // the next answer missed tick 12
        a.record(13, Some(10));
        a.record(14, Some(13));
        a.record(0, Some(u32::MAX)); // across the tick counter's wrap: age 1
        a.record(5, Some(9)); // from the future: not ours
        assert_eq!(
            a,
            AppliedAge {
                next: 3,
                two: 1,
                three_or_more: 1,
                no_command: 2
            }
        );
        let f = a.fractions();
        assert_eq!(f.ticks, 7);
        assert!((f.next_tick - 3.0 / 7.0).abs() < 1e-12);
    }
}
