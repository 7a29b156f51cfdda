//! The force test: a small force along each axis through the servo core's own safety stages,
//! the motion it produced, and the watchdog fading the output when commands stop.
//!
//! Timeline (all on the `now` the runner passes; the safety ramp-in and watchdog times come
//! from the configuration):
//!
//! 1. **settle**: a session starts ([`SessionEvent::Start`]); zero commands let the gate
//!    engage and ramp in.
//! 2. per direction +x, −x, +y, −y, +z, −z: **base** (zero; the last 80 ms give the rest
//!    position), **ramp** (the command rises to `force_n`), **hold** (the last 120 ms give the
//!    pushed position), **release**, **rest**.
//! 3. **watchdog**: ramp to `force_n` along +x, hold, then commands stop: the output must
//!    start fading after `watchdog_fade_start` and be zero by `watchdog_zero`.
//! 4. the session ends ([`SessionEvent::End`]) and the output stays zero.
//!
//! Every command is a [`ForceCommand`] without a local model, given to
//! [`ServoCore::on_command`] as the network side would, and the force written is
//! [`ServoCore::tick`]'s: the gate, clamp, slew limit, watchdog and finite check are the
//! servo loop's, not a copy. The displacement per direction is compared with the command: the
//! axis it moved most along and its sign give a signed axis permutation ([`AxisMap`]) which
//! names the day-one wiring errors ("axis x inverted", "axes x and y swapped").

use glam::Vec3;
use protocol::{ForceCommand, LocalModel};
use serde::Serialize;

use super::{Item, Phase, Status, axis_name, mm};
use crate::device::DeviceSample;
use crate::device::axes::AxisMap;
use crate::servo::safety::Stage;
use crate::servo::{ServoCore, ServoParams, SessionEvent};

const MS: u64 = 1_000_000;
const BASE: u64 = 150 * MS;
const RAMP: u64 = 200 * MS;
const HOLD: u64 = 300 * MS;
const RELEASE: u64 = 150 * MS;
const REST: u64 = 100 * MS;
const BASE_WINDOW: u64 = 80 * MS;
const HOLD_WINDOW: u64 = 120 * MS;
const PER_AXIS: u64 = BASE + RAMP + HOLD + RELEASE + REST;
/// Directions in order: (axis, negative).
const DIRECTIONS: [(usize, bool); 6] = [
    (0, false),
    (0, true),
    (1, false),
    (1, true),
    (2, false),
    (2, true),
];

/// How a direction the loop stalled through is reported (a warning, not a failure).
pub const NOT_MEASURED: &str = "not measured";

/// The smallest displacement counted as motion, m.
pub const MIN_MOTION_M: f32 = 0.3e-3;
/// The share of the displacement that must lie along one axis for "moved mostly along it".
pub const MOSTLY: f32 = 0.8;

/// What one direction produced.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisResult {
    /// Commanded direction, e.g. `+x`.
    pub commanded: String,
    /// Displacement from rest to the end of the hold, mm (device frame).
    pub displacement_mm: [f32; 3],
    /// The axis it moved most along, signed (`None` when it did not move).
    pub moved_mostly: Option<String>,
    /// Share of the displacement along that axis (|d_axis| / |d|).
    pub share: f32,
    /// Cosine between the displacement and the command.
    pub alignment: f32,
    /// Mean output force during the hold, N (after the safety stages).
    pub output_n: [f32; 3],
    /// Readings averaged at rest and pushed (a stalled loop leaves too few to judge by).
    pub samples: [u32; 2],
    /// `ok`, or what is wrong, in words.
    pub verdict: String,
}

/// The watchdog's fade as measured.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WatchdogResult {
    /// Output when the commands stopped, N.
    pub output_at_stop_n: f32,
    /// From the last command to the first reduced output, ms (`None`: it never faded).
    pub fade_started_ms: Option<f64>,
    /// From the last command to zero output, ms (`None`: never zero).
    pub zero_ms: Option<f64>,
    /// The configured fade start, ms.
    pub limit_fade_start_ms: f64,
    /// The configured zero time, ms.
    pub limit_zero_ms: f64,
    /// The gate re-armed (the next command ramps in again).
    pub rearmed: bool,
    /// Ticks after the zero time that still output force (must be 0).
    pub late_nonzero_ticks: u64,
}

/// Everything the force test measured.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ForceSummary {
    /// The force asked for, N.
    pub force_n: f32,
    /// Clamp limit in force (device ∧ configuration), N.
    pub clamp_n: f32,
    /// Slew limit, N/s.
    pub slew_n_per_s: f32,
    /// Per direction.
    pub axes: Vec<AxisResult>,
    /// The device's force axes as measured, `--fake-axes` style (`None`: not a clean signed
    /// permutation, or no motion).
    pub axis_map: Option<String>,
    /// The map's errors in words (empty: correct).
    pub diagnosis: Vec<String>,
    /// Largest output magnitude, N.
    pub max_output_n: f32,
    /// Largest output change rate, N/s.
    pub max_slew_n_per_s: f32,
    /// Ticks the clamp cut.
    pub clamped_ticks: u64,
    /// Ticks the emergency stop held the output at zero.
    pub estop_ticks: u64,
    /// Failed reads and writes.
    pub device_errors: u64,
    /// The watchdog.
    pub watchdog: WatchdogResult,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Segment {
    Settle,
    Axis { index: usize, part: Part, at: u64 },
    WatchRamp { at: u64 },
    WatchHold,
    Silence { at: u64 },
    Done,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Part {
    Base,
    Ramp,
    Hold,
    Release,
    Rest,
}

#[derive(Debug, Clone, Copy, Default)]
struct Acc {
    base: Vec3,
    base_n: u32,
    hold: Vec3,
    hold_n: u32,
    out: Vec3,
    out_n: u32,
}

/// The force phase; see the module doc.
#[derive(Debug, Clone)]
pub struct ForcePhase {
    core: ServoCore,
    params: ServoParams,
    force_n: f32,
    settle: u64,
    silence: u64,
    start_ns: Option<u64>,
    last_sample: DeviceSample,
    acc: [Acc; 6],
    last_command_ns: u64,
    stop: Option<(u64, f32)>,
    fade_ns: Option<u64>,
    zero_ns: Option<u64>,
    rearmed: bool,
    late_nonzero: u64,
    prev_out: Option<(u64, Vec3)>,
    max_out: f32,
    max_slew: f32,
    clamped: u64,
    estop: u64,
    errors: u64,
    ended: bool,
}

impl ForcePhase {
    /// A test of `force_n` newtons per direction with `params` (already limited to the
    /// device: [`ServoParams::limited_to`]).
    pub fn new(params: ServoParams, force_n: f32) -> Self {
        let s = params.safety;
        Self {
            core: ServoCore::new(params),
            params,
            force_n,
            settle: (s.ramp_ns + 150 * MS).max(300 * MS),
            silence: s.watchdog_zero_ns + 250 * MS,
            start_ns: None,
            last_sample: DeviceSample::default(),
            acc: [Acc::default(); 6],
            last_command_ns: 0,
            stop: None,
            fade_ns: None,
            zero_ns: None,
            rearmed: false,
            late_nonzero: 0,
            prev_out: None,
            max_out: 0.0,
            max_slew: 0.0,
            clamped: 0,
            estop: 0,
            errors: 0,
            ended: false,
        }
    }

    /// How long the whole test takes, s.
    pub fn duration_s(&self) -> f64 {
        (self.settle + 6 * PER_AXIS + RAMP + HOLD / 2 + self.silence) as f64 * 1e-9
    }

    fn segment(&self, t: u64) -> Segment {
        if t < self.settle {
            return Segment::Settle;
        }
        let t = t - self.settle;
        if t < 6 * PER_AXIS {
            let index = (t / PER_AXIS) as usize;
            let mut at = t % PER_AXIS;
            for (part, len) in [
                (Part::Base, BASE),
                (Part::Ramp, RAMP),
                (Part::Hold, HOLD),
                (Part::Release, RELEASE),
                (Part::Rest, REST),
            ] {
                if at < len {
                    return Segment::Axis { index, part, at };
                }
                at -= len;
            }
            return Segment::Done;
        }
        let t = t - 6 * PER_AXIS;
        if t < RAMP {
            Segment::WatchRamp { at: t }
        } else if t < RAMP + HOLD / 2 {
            Segment::WatchHold
        } else if t < RAMP + HOLD / 2 + self.silence {
            Segment::Silence {
                at: t - RAMP - HOLD / 2,
            }
        } else {
            Segment::Done
        }
    }

    fn command(&self, segment: Segment) -> Option<Vec3> {
        let dir = |i: usize| {
            let (axis, neg) = DIRECTIONS[i];
            let mut v = Vec3::ZERO;
            v[axis] = if neg { -1.0 } else { 1.0 };
            v
        };
        let f = self.force_n;
        Some(match segment {
            Segment::Settle => Vec3::ZERO,
            Segment::Axis { index, part, at } => match part {
                Part::Base | Part::Rest => Vec3::ZERO,
                Part::Ramp => dir(index) * f * (at as f32 / RAMP as f32),
                Part::Hold => dir(index) * f,
                Part::Release => dir(index) * f * (1.0 - at as f32 / RELEASE as f32),
            },
            Segment::WatchRamp { at } => Vec3::X * f * (at as f32 / RAMP as f32),
            Segment::WatchHold => Vec3::X * f,
            Segment::Silence { .. } | Segment::Done => return None,
        })
    }

    fn observe(&mut self, now: u64, segment: Segment, position: Vec3, out: Vec3) {
        if let Segment::Axis { index, part, at } = segment {
            let a = &mut self.acc[index];
            if part == Part::Base && at >= BASE - BASE_WINDOW {
                a.base += position;
                a.base_n += 1;
            }
            if part == Part::Hold && at >= HOLD - HOLD_WINDOW {
                a.hold += position;
                a.hold_n += 1;
                a.out += out;
                a.out_n += 1;
            }
        }
        if let Segment::Silence { .. } = segment {
            let (_, at_stop) = *self
                .stop
                .get_or_insert((self.last_command_ns, out.length()));
            let t = now.saturating_sub(self.last_command_ns);
            if self.fade_ns.is_none() && out.length() < at_stop * 0.999 {
                self.fade_ns = Some(t);
            }
            if self.zero_ns.is_none() && out == Vec3::ZERO {
                self.zero_ns = Some(t);
            }
            if out != Vec3::ZERO && t as f64 * 1e-6 >= self.zero_limit_ms() {
                self.late_nonzero += 1;
            }
            if self.core.safety().stage() == Stage::Armed {
                self.rearmed = true;
            }
        }
    }

    /// What was measured (complete once [`Phase::done`]).
    pub fn summary(&self) -> ForceSummary {
        let axes: Vec<AxisResult> = (0..6).map(|i| self.axis_result(i)).collect();
        let mut map = [(0usize, false); 3];
        let mut clean = true;
        for (slot, pair) in map.iter_mut().zip(self.acc.chunks_exact(2)) {
            match (moved(&pair[0]), moved(&pair[1])) {
                (Some((a, n)), Some((b, m))) if a == b && n != m => *slot = (a, n),
                _ => clean = false,
            }
        }
        let axis_map = clean.then(|| AxisMap::new(map)).flatten();
        let w = &self.params.safety;
        ForceSummary {
            force_n: self.force_n,
            clamp_n: w.max_force_n,
            slew_n_per_s: w.slew_n_per_s,
            axes,
            axis_map: axis_map.map(|m| m.to_string()),
            diagnosis: axis_map.map(|m| m.describe()).unwrap_or_default(),
            max_output_n: self.max_out,
            max_slew_n_per_s: self.max_slew,
            clamped_ticks: self.clamped,
            estop_ticks: self.estop,
            device_errors: self.errors,
            watchdog: WatchdogResult {
                output_at_stop_n: self.stop.map_or(0.0, |(_, f)| f),
                fade_started_ms: self.fade_ns.map(|t| t as f64 * 1e-6),
                zero_ms: self.zero_ns.map(|t| t as f64 * 1e-6),
                limit_fade_start_ms: w.watchdog_fade_start_ns as f64 * 1e-6,
                limit_zero_ms: self.zero_limit_ms(),
                rearmed: self.rearmed,
                late_nonzero_ticks: self.late_nonzero,
            },
        }
    }

    /// When the output must be zero after the last command, ms: the watchdog's zero time, or
    /// later when the slew limit cannot follow its fade (a large force fading over a short
    /// window).
    fn zero_limit_ms(&self) -> f64 {
        let w = &self.params.safety;
        let at_stop = self.stop.map_or(0.0, |(_, f)| f64::from(f));
        let by_slew = w.watchdog_fade_start_ns as f64 * 1e-6
            + at_stop / f64::from(w.slew_n_per_s.max(1e-6)) * 1e3;
        (w.watchdog_zero_ns as f64 * 1e-6).max(by_slew)
    }

    fn axis_result(&self, i: usize) -> AxisResult {
        let a = &self.acc[i];
        let (axis, neg) = DIRECTIONS[i];
        let d = displacement(a);
        let out = if a.out_n > 0 {
            a.out / a.out_n as f32
        } else {
            Vec3::ZERO
        };
        let mut cmd = Vec3::ZERO;
        cmd[axis] = if neg { -1.0 } else { 1.0 };
        let len = d.length();
        let m = moved(a);
        let share = if len > 0.0 {
            d.abs().max_element() / len
        } else {
            0.0
        };
        let period = self.params.period_ns().max(1);
        let expected = [BASE_WINDOW / period, HOLD_WINDOW / period].map(|n| n as u32);
        let stalled = a.base_n * 4 < expected[0] || a.hold_n * 4 < expected[1];
        let verdict = match m {
            _ if stalled => format!(
                "{NOT_MEASURED}: the loop stalled ({} of {} readings at rest, {} of {} pushed); \
                 run it again on a quieter machine",
                a.base_n, expected[0], a.hold_n, expected[1]
            ),
            _ if out.length() < 0.5 * self.force_n => format!(
                "the output reached only {:.2} N of {:.2} N (clamp, emergency stop or force \
                 disabled)",
                out.length(),
                self.force_n
            ),
            None if len < MIN_MOTION_M => format!(
                "did not move ({:.2} mm): force output off, or the stylus held too firmly",
                len * 1e3
            ),
            None => format!(
                "moved {} without a dominant axis ({:.0} % at most along one): the force \
                 frame is rotated against the position frame",
                mm(d),
                share * 100.0
            ),
            Some((b, n)) if b == axis && n == neg => "ok".into(),
            Some((b, _)) if b == axis => format!("axis {} inverted", ['x', 'y', 'z'][axis]),
            Some((b, n)) => format!(
                "moved along {} instead of {}",
                axis_name(b, n),
                axis_name(axis, neg)
            ),
        };
        AxisResult {
            commanded: axis_name(axis, neg),
            displacement_mm: (d * 1e3).to_array(),
            moved_mostly: m.map(|(b, n)| axis_name(b, n)),
            share,
            alignment: if len > 0.0 { d.dot(cmd) / len } else { 0.0 },
            output_n: out.to_array(),
            samples: [a.base_n, a.hold_n],
            verdict,
        }
    }
}

fn displacement(a: &Acc) -> Vec3 {
    if a.base_n == 0 || a.hold_n == 0 {
        return Vec3::ZERO;
    }
    a.hold / a.hold_n as f32 - a.base / a.base_n as f32
}

/// The signed axis a displacement is mostly along, if it moved enough and mostly along one.
fn moved(a: &Acc) -> Option<(usize, bool)> {
    let d = displacement(a);
    let len = d.length();
    if len < MIN_MOTION_M || !d.is_finite() {
        return None;
    }
    let abs = d.abs();
    let axis = if abs.x >= abs.y && abs.x >= abs.z {
        0
    } else if abs.y >= abs.z {
        1
    } else {
        2
    };
    (abs[axis] / len >= MOSTLY).then_some((axis, d[axis] < 0.0))
}

impl Phase for ForcePhase {
    fn tick(&mut self, now_ns: u64, sample: Option<&DeviceSample>) -> Vec3 {
        let start = match self.start_ns {
            Some(s) => s,
            None => {
                self.core.on_event(now_ns, SessionEvent::Start);
                self.start_ns = Some(now_ns);
                now_ns
            }
        };
        match sample {
            Some(s) => self.last_sample = *s,
            None => self.errors += 1,
        }
        let segment = self.segment(now_ns - start);
        if segment == Segment::Done && !self.ended {
            self.core.on_event(now_ns, SessionEvent::End);
            self.ended = true;
        }
        if let Some(f) = self.command(segment) {
            self.core.on_command(now_ns, constant(f));
            self.last_command_ns = now_ns;
        }
        let out = self.core.tick(now_ns, &self.last_sample);
        let force = out.safety.force;
        if out.safety.clamped {
            self.clamped += 1;
        }
        if self.core.safety().stopped() {
            self.estop += 1;
        }
        self.max_out = self.max_out.max(force.length());
        if let Some((t, f)) = self.prev_out {
            // The slew limit grants at most two periods' worth per tick (a late tick), but a
            // fading watchdog may shrink the output by what the real elapsed time grants.
            let elapsed = now_ns.saturating_sub(t);
            let fading = matches!(segment, Segment::Silence { .. }) && force.length() <= f.length();
            let dt = if fading {
                elapsed
            } else {
                elapsed.min(2 * self.params.period_ns())
            };
            let dt = dt.max(1);
            self.max_slew = self.max_slew.max((force - f).length() / (dt as f32 * 1e-9));
        }
        self.prev_out = Some((now_ns, force));
        self.observe(now_ns, segment, self.last_sample.position, force);
        force
    }

    fn write_failed(&mut self) {
        self.errors += 1;
    }

    fn done(&self) -> bool {
        self.ended
    }
}

fn constant(force: Vec3) -> ForceCommand {
    ForceCommand {
        force,
        torque: None,
        answers_sequence: 0,
        answers_timestamp_ns: 0,
        model: LocalModel::default(),
    }
}

/// The verdicts on a force test.
pub fn evaluate(s: &ForceSummary, hint: &str) -> Vec<Item> {
    let mut items = Vec::new();
    let lines: Vec<String> = s
        .axes
        .iter()
        .map(|a| {
            format!(
                "commanded {}, moved {} {}: {}",
                a.commanded,
                a.moved_mostly
                    .as_deref()
                    .map_or("along no single axis".to_owned(), |m| format!("mostly {m}")),
                mm(Vec3::from(a.displacement_mm) * 1e-3),
                a.verdict
            )
        })
        .collect();
    let all_ok = s.axes.iter().all(|a| a.verdict == "ok");
    let only_stalls = s
        .axes
        .iter()
        .all(|a| a.verdict == "ok" || a.verdict.starts_with(NOT_MEASURED));
    let status = if all_ok {
        Status::Pass
    } else if only_stalls {
        Status::Warn
    } else {
        Status::Fail
    };
    let mut detail = lines.join("\n");
    match (&s.axis_map, all_ok) {
        (_, true) => {}
        (_, false) if only_stalls => {}
        (Some(map), false) => detail.push_str(&format!(
            "\nforce axes as measured: {map} ({}). Positions and forces disagree, which no \
             scene transform can fix: {hint}",
            s.diagnosis.join(", ")
        )),
        (None, false) => detail.push_str(&format!("\n{hint}")),
    }
    items.push(Item::new("axes", status, detail));
    let clamp_ok = s.max_output_n <= s.clamp_n * 1.0001 + 1e-6;
    let slew_ok = s.max_slew_n_per_s <= s.slew_n_per_s * 1.001 + 1e-3;
    items.push(Item::new(
        "clamp",
        if clamp_ok { Status::Pass } else { Status::Fail },
        format!(
            "limit {:.2} N; largest output {:.2} N ({} ticks clamped)",
            s.clamp_n, s.max_output_n, s.clamped_ticks
        ),
    ));
    items.push(Item::new(
        "slew",
        if slew_ok { Status::Pass } else { Status::Fail },
        format!(
            "limit {:.0} N/s; fastest change {:.1} N/s",
            s.slew_n_per_s, s.max_slew_n_per_s
        ),
    ));
    // Judged on every tick after the zero time, not on when the first zero tick happened to
    // run: a late tick on a loaded machine must not fail a watchdog that did its job.
    let w = &s.watchdog;
    let (status, detail) = match (w.fade_started_ms, w.zero_ms) {
        (_, Some(z)) if w.late_nonzero_ticks == 0 && w.rearmed => (
            Status::Pass,
            format!(
                "commands stopped at {:.2} N; fading from {} ms, zero {z:.1} ms after the last \
                 command (limits {:.0} / {:.0} ms); re-armed",
                w.output_at_stop_n,
                w.fade_started_ms
                    .map_or("?".to_owned(), |f| format!("{f:.1}")),
                w.limit_fade_start_ms,
                w.limit_zero_ms
            ),
        ),
        (_, Some(z)) => (
            Status::Fail,
            format!(
                "zero {z:.1} ms after the last command, but {} ticks after the {:.0} ms limit \
                 still output force{}",
                w.late_nonzero_ticks,
                w.limit_zero_ms,
                if w.rearmed { "" } else { "; did not re-arm" }
            ),
        ),
        (_, None) => (
            Status::Fail,
            format!(
                "the output never reached zero after commands stopped ({:.2} N at the stop)",
                w.output_at_stop_n
            ),
        ),
    };
    items.push(Item::new("watchdog", status, detail));
    if s.estop_ticks > 0 {
        items.push(Item::new(
            "emergency stop",
            Status::Warn,
            format!(
                "latched for {} ticks (servo.estop_button_mask): a button held during the test",
                s.estop_ticks
            ),
        ));
    }
    if s.device_errors > 0 {
        items.push(Item::new(
            "device errors",
            Status::Warn,
            format!("{} reads or writes failed during the test", s.device_errors),
        ));
    }
    items
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::run::run_virtual;
    use crate::device::Device;
    use crate::device::fake::{FakeDevice, FakeParams, HandPath};

    fn params() -> ServoParams {
        ServoParams::omni_at_1khz()
    }

    fn test(axes: &str) -> ForceSummary {
        let mut dev = FakeDevice::new(FakeParams {
            path: HandPath::Idle { at: Vec3::ZERO },
            axes: AxisMap::parse(axes).unwrap(),
            ..FakeParams::default()
        });
        let mut phase = ForcePhase::new(params(), 1.0);
        run_virtual(&mut dev, &mut phase, 1_000_000, 0);
        phase.summary()
    }

    #[test]
    fn a_correct_device_passes_every_direction_and_the_watchdog() {
        let s = test("x,y,z");
        assert_eq!(s.axis_map.as_deref(), Some("x,y,z"));
        let items = evaluate(&s, "");
        assert!(items.iter().all(|i| i.status == Status::Pass), "{items:#?}");
        // 1 N against the 200 N/m hand: 5 mm.
        for a in &s.axes {
            let d = Vec3::from(a.displacement_mm).length();
            assert!((d - 5.0).abs() < 0.5, "{a:?}");
        }
        let w = &s.watchdog;
        assert!(
            w.zero_ms.unwrap() <= 31.0 && w.fade_started_ms.unwrap() >= 20.0,
            "{w:?}"
        );
    }

    /// The 1 N test on an idle fake hand, each tick at the time `next(phase, now)` gives.
    fn stepped(mut next: impl FnMut(&ForcePhase, u64) -> u64) -> ForceSummary {
        let mut dev = FakeDevice::new(FakeParams {
            path: HandPath::Idle { at: Vec3::ZERO },
            ..FakeParams::default()
        });
        let mut phase = ForcePhase::new(params(), 1.0);
        let mut now = 0;
        while !phase.done() {
            now = next(&phase, now);
            let s = dev.read(now).ok();
            let f = phase.tick(now, s.as_ref());
            dev.write_force(f).unwrap();
        }
        phase.summary()
    }

    #[test]
    fn a_loop_that_stalls_through_a_window_warns_instead_of_blaming_the_axes() {
        // 1 ms ticks, but nothing between 0.85 s and 1.1 s: +x's whole hold.
        let s = stepped(|_, now| {
            now + if (850..1100).contains(&(now / MS)) {
                250 * MS
            } else {
                MS
            }
        });
        assert!(
            s.axes[0].verdict.starts_with(NOT_MEASURED),
            "{:?}",
            s.axes[0]
        );
        assert!(
            s.axes[1..].iter().all(|a| a.verdict == "ok"),
            "{:?}",
            s.axes
        );
        assert_eq!(evaluate(&s, "")[0].status, Status::Warn);
    }

    #[test]
    fn late_ticks_in_the_fade_do_not_fail_a_watchdog_that_did_its_job() {
        // 1 ms ticks, but none from 22 to 29 ms after the last command: the fade's middle.
        let mut stalled = false;
        let s = stepped(|phase, now| {
            let in_fade = phase.stop.is_some() && now - phase.last_command_ns == 22 * MS;
            stalled |= in_fade;
            now + if in_fade { 7 * MS } else { MS }
        });
        assert!(stalled);
        let w = &s.watchdog;
        assert_eq!(w.late_nonzero_ticks, 0, "{w:?}");
        assert!(w.zero_ms.unwrap() <= 30.0, "{w:?}");
        let items = evaluate(&s, "");
        assert!(items.iter().all(|i| i.status == Status::Pass), "{items:#?}");
    }

    #[test]
    fn swapped_and_inverted_axes_are_named() {
        let s = test("-x,z,y");
        assert_eq!(s.axis_map.as_deref(), Some("-x,z,y"));
        assert_eq!(s.diagnosis, ["axis x inverted", "axes y and z swapped"]);
        let items = evaluate(&s, "fix it");
        let axes = &items[0];
        assert_eq!(axes.status, Status::Fail);
        assert!(
            axes.detail.contains("commanded +x, moved mostly -x (-5.0,")
                && axes.detail.contains("mm: axis x inverted"),
            "{}",
            axes.detail
        );
        assert!(
            axes.detail.contains("moved along +z instead of +y"),
            "{}",
            axes.detail
        );
        assert!(axes.detail.contains("fix it"));
    }
}
