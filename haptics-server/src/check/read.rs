//! The read phase: the stylus is read for a while with zero force written, and the readings
//! are summarised as they come (no per-tick storage): the rate, the position range and noise,
//! the buttons pressed, and whether every orientation was a finite unit quaternion.
//!
//! Noise is estimated from second differences, `σ ≈ rms(x[i+1] − 2x[i] + x[i−1]) / √6`:
//! white noise passes with variance `6σ²` while a hand's smooth motion (accelerations of a
//! few m/s², 1 µm per tick² at 1 kHz) hardly does, so the stylus need not be still.

use glam::{DVec3, Quat, Vec3};
use serde::Serialize;

use super::{Item, Phase, Status, mm};
use crate::device::{DeviceInfo, DeviceSample};

/// What the read phase saw.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReadSummary {
    /// Seconds read.
    pub seconds: f64,
    /// Successful readings.
    pub readings: u64,
    /// Failed readings.
    pub read_errors: u64,
    /// Failed zero-force writes.
    pub write_errors: u64,
    /// Readings per second achieved.
    pub rate_hz: f64,
    /// Mean and largest time between ticks, µs.
    pub period_mean_us: f64,
    /// See `period_mean_us`.
    pub period_max_us: f64,
    /// Ticks more than 1.5 periods after the previous one.
    pub late_ticks: u64,
    /// Smallest position per axis, m (device frame).
    pub position_min: [f32; 3],
    /// Largest position per axis, m.
    pub position_max: [f32; 3],
    /// Readings with a non-finite position.
    pub nonfinite_positions: u64,
    /// Position noise per axis (second-difference estimate), µm RMS.
    pub noise_um: [f64; 3],
    /// Every button bit seen pressed.
    pub buttons_seen: u16,
    /// Presses (0 → 1 transitions of any bit).
    pub button_presses: u32,
    /// Orientations that were not finite.
    pub nonfinite_orientations: u64,
    /// Orientations whose norm was off 1 by more than 1e-3.
    pub nonunit_orientations: u64,
    /// Largest rotation from the first orientation, degrees.
    pub rotation_range_deg: f64,
}

/// The read phase; see the module doc.
#[derive(Debug, Clone)]
pub struct ReadPhase {
    duration_ns: u64,
    start_ns: Option<u64>,
    last_ns: Option<u64>,
    finished: bool,
    readings: u64,
    read_errors: u64,
    write_errors: u64,
    period_sum_ns: u64,
    period_max_ns: u64,
    periods: u64,
    late: u64,
    nominal_ns: u64,
    min: Vec3,
    max: Vec3,
    nonfinite_pos: u64,
    prev: Option<(Vec3, Option<Vec3>)>,
    d2_sq: DVec3,
    d2_n: u64,
    buttons_prev: u16,
    buttons_seen: u16,
    presses: u32,
    first_q: Option<Quat>,
    max_angle: f32,
    nonfinite_q: u64,
    nonunit_q: u64,
}

impl ReadPhase {
    /// Read for `seconds` at a nominal `rate_hz`.
    pub fn new(seconds: f64, rate_hz: u32) -> Self {
        Self {
            duration_ns: (seconds.max(0.0) * 1e9) as u64,
            start_ns: None,
            last_ns: None,
            finished: false,
            readings: 0,
            read_errors: 0,
            write_errors: 0,
            period_sum_ns: 0,
            period_max_ns: 0,
            periods: 0,
            late: 0,
            nominal_ns: 1_000_000_000 / u64::from(rate_hz.max(1)),
            min: Vec3::splat(f32::INFINITY),
            max: Vec3::splat(f32::NEG_INFINITY),
            nonfinite_pos: 0,
            prev: None,
            d2_sq: DVec3::ZERO,
            d2_n: 0,
            buttons_prev: 0,
            buttons_seen: 0,
            presses: 0,
            first_q: None,
            max_angle: 0.0,
            nonfinite_q: 0,
            nonunit_q: 0,
        }
    }

    fn observe(&mut self, s: &DeviceSample) {
        self.readings += 1;
        let p = s.position;
        if p.is_finite() {
            self.min = self.min.min(p);
            self.max = self.max.max(p);
            if let Some((p1, p0)) = self.prev {
                if let Some(p0) = p0 {
                    let d2 = (p - 2.0 * p1 + p0).as_dvec3();
                    self.d2_sq += d2 * d2;
                    self.d2_n += 1;
                }
                self.prev = Some((p, Some(p1)));
            } else {
                self.prev = Some((p, None));
            }
        } else {
            self.nonfinite_pos += 1;
            self.prev = None;
        }
        let pressed = s.buttons & !self.buttons_prev;
        if pressed != 0 {
            self.presses += pressed.count_ones();
        }
        self.buttons_seen |= s.buttons;
        self.buttons_prev = s.buttons;
        let q = s.orientation;
        if !q.is_finite() {
            self.nonfinite_q += 1;
        } else if (q.length() - 1.0).abs() > 1e-3 {
            self.nonunit_q += 1;
        } else {
            let first = *self.first_q.get_or_insert(q);
            self.max_angle = self.max_angle.max(first.angle_between(q));
        }
    }

    /// What was seen.
    pub fn summary(&self) -> ReadSummary {
        let seconds = match (self.start_ns, self.last_ns) {
            (Some(a), Some(b)) => (b - a) as f64 * 1e-9,
            _ => 0.0,
        };
        let noise = if self.d2_n > 0 {
            (self.d2_sq / self.d2_n as f64 / 6.0).map(f64::sqrt) * 1e6
        } else {
            DVec3::ZERO
        };
        let finite = self.min.is_finite() && self.max.is_finite();
        ReadSummary {
            seconds,
            readings: self.readings,
            read_errors: self.read_errors,
            write_errors: self.write_errors,
            rate_hz: if seconds > 0.0 {
                self.periods as f64 / seconds
            } else {
                0.0
            },
            period_mean_us: if self.periods > 0 {
                self.period_sum_ns as f64 / self.periods as f64 * 1e-3
            } else {
                0.0
            },
            period_max_us: self.period_max_ns as f64 * 1e-3,
            late_ticks: self.late,
            position_min: if finite {
                self.min.to_array()
            } else {
                [0.0; 3]
            },
            position_max: if finite {
                self.max.to_array()
            } else {
                [0.0; 3]
            },
            nonfinite_positions: self.nonfinite_pos,
            noise_um: noise.to_array(),
            buttons_seen: self.buttons_seen,
            button_presses: self.presses,
            nonfinite_orientations: self.nonfinite_q,
            nonunit_orientations: self.nonunit_q,
            rotation_range_deg: f64::from(self.max_angle.to_degrees()),
        }
    }
}

impl Phase for ReadPhase {
    fn tick(&mut self, now_ns: u64, sample: Option<&DeviceSample>) -> Vec3 {
        let start = *self.start_ns.get_or_insert(now_ns);
        if let Some(last) = self.last_ns {
            let dt = now_ns.saturating_sub(last);
            self.period_sum_ns += dt;
            self.period_max_ns = self.period_max_ns.max(dt);
            self.periods += 1;
            if dt * 2 > self.nominal_ns * 3 {
                self.late += 1;
            }
        }
        self.last_ns = Some(now_ns);
        match sample {
            Some(s) => self.observe(s),
            None => self.read_errors += 1,
        }
        if now_ns.saturating_sub(start) >= self.duration_ns {
            self.finished = true;
        }
        Vec3::ZERO
    }

    fn write_failed(&mut self) {
        self.write_errors += 1;
    }

    fn done(&self) -> bool {
        self.finished
    }
}

/// The verdicts on a read: rate against `rate_hz`, errors, positions against `info`'s
/// workspace, noise, buttons, orientation.
pub fn evaluate(s: &ReadSummary, info: &DeviceInfo, rate_hz: u32) -> Vec<Item> {
    let mut items = Vec::new();
    let total = s.readings + s.read_errors;
    if s.readings == 0 {
        items.push(Item::new(
            "readings",
            Status::Fail,
            format!("no reading succeeded ({} failed)", s.read_errors),
        ));
        return items;
    }
    let ratio = s.rate_hz / f64::from(rate_hz.max(1));
    let rate_status = if ratio >= 0.9 {
        Status::Pass
    } else if ratio >= 0.5 {
        Status::Warn
    } else {
        Status::Fail
    };
    items.push(Item::new(
        "rate",
        rate_status,
        format!(
            "{:.0} readings/s of {rate_hz} asked ({:.0} %); period mean {:.0} µs, max {:.0} µs, \
             {} late ticks (> 1.5 periods){}",
            s.rate_hz,
            ratio * 100.0,
            s.period_mean_us,
            s.period_max_us,
            s.late_ticks,
            if rate_status == Status::Pass {
                ""
            } else {
                "; a loaded machine or a slow device link: see deploy/README.md step 8-9"
            }
        ),
    ));
    let errors = s.read_errors + s.write_errors;
    items.push(Item::new(
        "errors",
        if errors == 0 {
            Status::Pass
        } else if (errors as f64) < 0.01 * total as f64 {
            Status::Warn
        } else {
            Status::Fail
        },
        format!(
            "{} of {total} reads and {} writes failed",
            s.read_errors, s.write_errors
        ),
    ));
    let (min, max) = (Vec3::from(s.position_min), Vec3::from(s.position_max));
    let range = max - min;
    let (wmin, wmax) = (info.workspace_min, info.workspace_max);
    let margin = (wmax - wmin) * 0.25;
    let far = min.abs().max(max.abs()).max_element();
    let (status, hint) = if s.nonfinite_positions > 0 {
        (
            Status::Fail,
            format!("; {} readings were not finite", s.nonfinite_positions),
        )
    } else if far > 2.0 {
        (
            Status::Fail,
            "; positions beyond 2 m: the backend is not reporting metres (millimetres?)".into(),
        )
    } else if min.cmplt(wmin - margin).any() || max.cmpgt(wmax + margin).any() {
        (
            Status::Warn,
            format!(
                "; outside the declared workspace {} … {} by more than a quarter of it: a \
                 wrong origin or scale",
                mm(wmin),
                mm(wmax)
            ),
        )
    } else {
        (Status::Pass, String::new())
    };
    items.push(Item::new(
        "position",
        status,
        format!(
            "range {} … {} (extent {}){hint}",
            mm(min),
            mm(max),
            mm(range)
        ),
    ));
    let noise = s.noise_um.iter().copied().fold(0.0, f64::max);
    items.push(Item::new(
        "noise",
        if noise <= 200.0 {
            Status::Pass
        } else {
            Status::Warn
        },
        format!(
            "{:.1} / {:.1} / {:.1} µm RMS (x / y / z){}",
            s.noise_um[0],
            s.noise_um[1],
            s.noise_um[2],
            if noise > 200.0 {
                ": jittery encoders or a loose cable; contact will buzz"
            } else {
                ""
            }
        ),
    ));
    items.push(if s.button_presses > 0 {
        Item::new(
            "buttons",
            Status::Pass,
            format!(
                "{} presses; bits seen {:#06x}",
                s.button_presses, s.buttons_seen
            ),
        )
    } else if s.buttons_seen != 0 {
        Item::new(
            "buttons",
            Status::Warn,
            format!(
                "bits {:#06x} held the whole time and never released: a stuck button or an \
                 inverted bit",
                s.buttons_seen
            ),
        )
    } else {
        Item::new(
            "buttons",
            Status::Skip,
            "none pressed during the read (press each one while reading to test them)",
        )
    });
    let bad_q = s.nonfinite_orientations + s.nonunit_orientations;
    items.push(if bad_q > 0 {
        Item::new(
            "orientation",
            Status::Fail,
            format!(
                "{} non-finite and {} non-unit orientations of {} readings",
                s.nonfinite_orientations, s.nonunit_orientations, s.readings
            ),
        )
    } else if info.dof_input < 6 {
        Item::new(
            "orientation",
            Status::Pass,
            format!(
                "{}-DOF device: identity throughout, as expected",
                info.dof_input
            ),
        )
    } else {
        Item::new(
            "orientation",
            Status::Pass,
            format!(
                "every reading a unit quaternion; turned up to {:.1}° from the first{}",
                s.rotation_range_deg,
                if s.rotation_range_deg < 1.0 {
                    " (turn the stylus while reading to see it change)"
                } else {
                    ""
                }
            ),
        )
    });
    items
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_from_second_differences_ignores_smooth_motion() {
        let mut r = ReadPhase::new(1.0, 1000);
        let mut rng = 12345u64;
        let mut noise = || {
            rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1);
            ((rng >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 2.0 * 1e-5 * 3f32.sqrt()
        };
        for i in 0..=1000u64 {
            let t = i as f32 * 1e-3;
            // A slow 2 cm sweep plus uniform noise of σ = 10 µm on x.
            let s = DeviceSample {
                position: Vec3::new(0.02 * t + noise(), 0.0, 0.0),
                buttons: u16::from((400..600).contains(&i)),
                ..DeviceSample::default()
            };
            r.tick(i * 1_000_000, Some(&s));
        }
        assert!(r.done());
        let s = r.summary();
        assert!((s.noise_um[0] - 10.0).abs() < 1.5, "{:?}", s.noise_um);
        assert!((s.rate_hz - 1000.0).abs() < 1.0);
        assert_eq!((s.button_presses, s.buttons_seen), (1, 1));
        assert!((s.position_max[0] - 0.02).abs() < 1e-4);
        let items = evaluate(&s, &DeviceInfo::phantom_class("t"), 1000);
        assert!(items.iter().all(|i| i.status == Status::Pass), "{items:?}");
    }

    #[test]
    fn millimetres_and_broken_quaternions_fail() {
        let mut r = ReadPhase::new(0.01, 1000);
        for i in 0..=10u64 {
            let s = DeviceSample {
                position: Vec3::new(40.0, 0.0, 0.0),
                orientation: Quat::from_xyzw(0.0, 0.0, 0.0, 2.0),
                ..DeviceSample::default()
            };
            r.tick(i * 1_000_000, Some(&s));
        }
        let items = evaluate(&r.summary(), &DeviceInfo::phantom_class("t"), 1000);
        let status = |n: &str| items.iter().find(|i| i.name == n).unwrap().status;
        assert_eq!(status("position"), Status::Fail);
        assert_eq!(status("orientation"), Status::Fail);
    }
}
