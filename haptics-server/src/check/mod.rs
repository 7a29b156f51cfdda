//! `haptics-server check`: a guided self-test of a new installation.
//!
//! Two phases, each a deterministic state machine driven with `now` and the device reading
//! (the [`Phase`] trait), run by [`run::run_phase`] on the real clock or by
//! [`run::run_virtual`] on a virtual one (tests):
//!
//! 1. [`read::ReadPhase`]: the stylus is read for a few seconds with zero force: the rate
//!    achieved, position range and noise, buttons pressed, orientation validity.
//! 2. [`force::ForcePhase`] (only with `--force-test`, after confirmation): a real
//!    [`crate::servo::ServoCore`] with the configured safety stages (gate and ramp-in, clamp,
//!    slew limit, watchdog) renders a small force ramped along +x, −x, +y, −y, +z, −z; the
//!    motion each produced is compared with the command, which catches swapped and inverted
//!    axes in the device's frame; then commands stop and the watchdog must fade the output to
//!    zero in time.
//!
//! [`report::Report`] gathers the verdicts ([`Item`]), the workspace seen and declared, and
//! the scene transform for a region ([`calibration`]); it prints as a summary and as JSON.

pub mod calibration;
pub mod force;
pub mod read;
pub mod report;
pub mod run;

use glam::Vec3;
use serde::Serialize;

use crate::clock::MonoClock;
use crate::config::DeviceKind;
use crate::device::{Device, DeviceError, DeviceSample};
use crate::servo::ServoParams;

/// One phase of the check: called once per tick with the reading (`None`: the read failed);
/// returns the force to write.
pub trait Phase {
    /// One tick at `now_ns`.
    fn tick(&mut self, now_ns: u64, sample: Option<&DeviceSample>) -> Vec3;
    /// The device refused the force written on the last tick.
    fn write_failed(&mut self);
    /// Nothing more to do: the runner stops calling `tick`.
    fn done(&self) -> bool;
}

/// How a check came out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// As it should be.
    Pass,
    /// Works, but look at it.
    Warn,
    /// Wrong: the exit code is non-zero.
    Fail,
    /// Not tested (nothing to test, or not asked for).
    Skip,
}

impl Status {
    /// Fixed-width label for the summary.
    pub fn label(self) -> &'static str {
        match self {
            Status::Pass => "PASS",
            Status::Warn => "WARN",
            Status::Fail => "FAIL",
            Status::Skip => "SKIP",
        }
    }
}

/// One verdict: what was checked, how it came out, and the evidence in words.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Item {
    /// Short name (`rate`, `position`, `axes`, `watchdog`, ...).
    pub name: String,
    /// Outcome.
    pub status: Status,
    /// What was seen, and what to do when it is wrong.
    pub detail: String,
}

impl Item {
    /// An item.
    pub fn new(name: &str, status: Status, detail: impl Into<String>) -> Self {
        Self {
            name: name.into(),
            status,
            detail: detail.into(),
        }
    }
}

/// `+x`, `-y`, ... for a signed axis.
pub fn axis_name(axis: usize, negative: bool) -> String {
    format!(
        "{}{}",
        if negative { '-' } else { '+' },
        ['x', 'y', 'z'][axis]
    )
}

/// A vector in millimetres with one decimal, for the summary.
pub fn mm(v: Vec3) -> String {
    format!(
        "({:+.1}, {:+.1}, {:+.1}) mm",
        v.x * 1e3,
        v.y * 1e3,
        v.z * 1e3
    )
}

/// What to check and how.
#[derive(Debug, Clone)]
pub struct CheckOptions {
    /// The backend (for its frame and advice).
    pub kind: DeviceKind,
    /// Seconds of reading.
    pub seconds: f64,
    /// Run the force test with this force, N (`None`: no force test).
    pub force_n: Option<f32>,
    /// Servo parameters from the configuration (limited to the device here).
    pub params: ServoParams,
    /// Spin before each deadline.
    pub spin: std::time::Duration,
    /// Map the workspace onto this region.
    pub region: Option<calibration::Aabb>,
    /// How to scale onto the region.
    pub fit: calibration::Fit,
}

/// The person (or rig) at the device: told what comes, asked before anything moves.
pub trait Operator {
    /// The read phase is about to start.
    fn before_read(&mut self, seconds: f64);
    /// The force test would start now (`force_n` along each axis, `duration_s` in all);
    /// `true` to go ahead.
    fn confirm_force(&mut self, force_n: f32, duration_s: f64) -> bool;
    /// A progress line.
    fn progress(&mut self, line: &str);
}

/// What to change when the force axes disagree with the position axes, per backend.
pub fn axis_fix_hint(kind: DeviceKind) -> &'static str {
    match kind {
        DeviceKind::Fake => {
            "this fake was configured so (--fake-axes / device.fake.axes); x,y,z is correct"
        }
        DeviceKind::Hid => {
            "in the report layout file, swap the [force] x/y/z fields or negate a scale until \
             force and position axes agree"
        }
        DeviceKind::Openhaptics => {
            "recalibrate the device (Touch Setup / Touch Diagnostic) and check the driver \
             version; OpenHaptics reports position and force in one frame"
        }
        DeviceKind::Dhd => {
            "check the device with Force Dimension's HapticDesk (a left-handed model or a base \
             angle set with dhdSetBaseAngle turns the frame); DHD reports position and force \
             in one frame"
        }
        DeviceKind::Replay => "a recording cannot output force",
    }
}

/// Run the check on an opened `device`: read, then (when asked and confirmed) the force test;
/// the report says what passed. Errors are the device's (start, a scheduler that failed).
pub fn run_check(
    device: &mut dyn Device,
    opts: &CheckOptions,
    operator: &mut dyn Operator,
) -> Result<report::Report, DeviceError> {
    let info = device.info().clone();
    let clock = MonoClock::new();
    let period = std::time::Duration::from_nanos(opts.params.period_ns());
    device.start()?;
    operator.before_read(opts.seconds);
    let mut read = read::ReadPhase::new(opts.seconds, opts.params.rate_hz);
    let result = run::run_phase(device, &mut read, clock, period, opts.spin);
    let read = read.summary();
    let mut items = read::evaluate(&read, &info, opts.params.rate_hz);
    if let Err(e) = result {
        device.stop();
        return Err(e);
    }
    let mut force_summary = None;
    if let Some(force_n) = opts.force_n {
        let params = opts.params.limited_to(&info);
        let readings_ok = read.readings > 0;
        if info.dof_output == 0 || params.safety.max_force_n <= 0.0 {
            items.push(Item::new(
                "force test",
                Status::Fail,
                format!(
                    "{} has no force output (dof_output {}, force limit {:.1} N): nothing to test",
                    info.name, info.dof_output, params.safety.max_force_n
                ),
            ));
        } else if !readings_ok {
            items.push(Item::new(
                "force test",
                Status::Skip,
                "not run: no reading succeeded, so motion could not be measured",
            ));
        } else {
            let mut phase = force::ForcePhase::new(params, force_n);
            if operator.confirm_force(force_n, phase.duration_s()) {
                operator.progress(&format!(
                    "force test: {force_n:.2} N along +x, -x, +y, -y, +z, -z, then the watchdog \
                     ({:.0} s)",
                    phase.duration_s()
                ));
                let result = run::run_phase(device, &mut phase, clock, period, opts.spin);
                let s = phase.summary();
                items.extend(force::evaluate(&s, axis_fix_hint(opts.kind)));
                force_summary = Some(s);
                if let Err(e) = result {
                    device.stop();
                    return Err(e);
                }
            } else {
                items.push(Item::new(
                    "force test",
                    Status::Skip,
                    "not confirmed: no force was output",
                ));
            }
        }
    }
    device.stop();
    let workspace = report::workspace(opts.kind, &info, &read, opts.region, opts.fit);
    let device_report = report::DeviceReport {
        kind: format!("{:?}", opts.kind).to_lowercase(),
        name: info.name.clone(),
        dof_input: info.dof_input,
        dof_output: info.dof_output,
        max_force_n: info.max_force_n,
        max_stiffness_n_per_m: info.max_stiffness_n_per_m,
        frame: calibration::frame(opts.kind).description.into(),
    };
    Ok(report::Report::new(
        device_report,
        items,
        read,
        force_summary,
        workspace,
    ))
}
