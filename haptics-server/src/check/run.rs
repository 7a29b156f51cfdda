//! Running a [`Phase`] against a device: on the real clock at the servo rate (the driver's
//! deadline wait, or the vendor scheduler for devices that run their own, as in the server),
//! or on a virtual clock for tests.

use std::time::{Duration, Instant};

use crate::clock::MonoClock;
use crate::device::{Device, DeviceError};
use crate::servo::rt;

use super::Phase;

fn step(device: &mut dyn Device, phase: &mut dyn Phase, now_ns: u64) {
    let sample = device.read(now_ns).ok();
    let force = phase.tick(now_ns, sample.as_ref());
    if device.write_force(force).is_err() {
        phase.write_failed();
    }
}

/// Run `phase` until it is done, one tick per `period` on `clock` (deadlines as the servo
/// driver keeps them: sleep, then spin the last `spin`; missed deadlines are skipped). A
/// device with its own scheduler ([`Device::run_scheduled`]) drives the ticks instead.
pub fn run_phase(
    device: &mut dyn Device,
    phase: &mut dyn Phase,
    clock: MonoClock,
    period: Duration,
    spin: Duration,
) -> Result<(), DeviceError> {
    let scheduled = device.run_scheduled(&mut |dev| {
        if phase.done() {
            return false;
        }
        step(dev, phase, clock.now_ns());
        true
    });
    if let Some(result) = scheduled {
        return result;
    }
    let mut deadline = Instant::now() + period;
    while !phase.done() {
        let started = rt::wait_until(deadline, spin);
        step(device, phase, clock.ns_at(started));
        deadline += period;
        let now = Instant::now();
        if now > deadline + period {
            let behind =
                now.saturating_duration_since(deadline).as_nanos() / period.as_nanos().max(1);
            deadline += period * u32::try_from(behind).unwrap_or(u32::MAX);
        }
    }
    Ok(())
}

/// Run `phase` on a virtual clock from `start_ns`, one tick every `period_ns`, without
/// sleeping (for devices that take their time from `now`, such as the fake). Returns the
/// clock after the last tick.
pub fn run_virtual(
    device: &mut dyn Device,
    phase: &mut dyn Phase,
    period_ns: u64,
    start_ns: u64,
) -> u64 {
    let mut now = start_ns;
    while !phase.done() {
        now += period_ns;
        step(device, phase, now);
    }
    now
}
