//! The mouse as the haptic device, for a workstation without one (`workstation view` without
//! `--server`): the window writes where the mouse puts the cursor ([`MouseHand`]), and a thread
//! turns it into a 1 kHz cursor stream into the force thread's ring, like the network side
//! does with the server's stream. Forces are computed and shown (arrow, plots) but go nowhere.
//!
//! The cursor stream is sampled, not event-driven: the window updates the target at its frame
//! rate, the thread holds it between updates and differentiates the samples for the velocity
//! the force's damping and the simulation's tools use (smoothed over ~10 ms so a 60 Hz mouse does not
//! give 1 kHz velocity spikes).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::thread::Thread;
use std::time::{Duration, Instant};

use glam::{DVec3, Quat};
use protocol::CursorSample;

use super::shared::{AtomicF64, CursorMsg, Shared};
use super::transform::DeviceTransform;

/// The cursor stream's period.
pub const PERIOD: Duration = Duration::from_millis(1);

/// Where the mouse puts the cursor (scene frame) and whether the tool button is down; written
/// by the window, read by the mouse thread. NaN until the mouse is first over the view.
#[derive(Debug)]
pub struct MouseHand {
    target: [AtomicF64; 3],
    buttons: AtomicU64,
}

impl Default for MouseHand {
    fn default() -> Self {
        let h = Self {
            target: Default::default(),
            buttons: AtomicU64::new(0),
        };
        h.set(DVec3::splat(f64::NAN), 0);
        h
    }
}

impl MouseHand {
    /// Move the cursor to `p` (scene m) with `buttons` (bit 0: the tool button).
    pub fn set(&self, p: DVec3, buttons: u16) {
        for (s, v) in self.target.iter().zip(p.to_array()) {
            s.set(v);
        }
        self.buttons.store(u64::from(buttons), Ordering::Relaxed);
    }

    /// The cursor now.
    pub fn get(&self) -> (DVec3, u16) {
        let [x, y, z] = &self.target;
        (
            DVec3::new(x.get(), y.get(), z.get()),
            self.buttons.load(Ordering::Relaxed) as u16,
        )
    }
}

/// The ends the mouse thread feeds.
#[derive(Debug)]
pub struct MousePorts {
    /// Cursors to the force thread.
    pub cursors: rtrb::Producer<CursorMsg>,
    /// The force thread, unparked on every cursor.
    pub force_thread: Thread,
}

/// Turns the hand's target into cursor samples (device frame) with a smoothed velocity.
#[derive(Debug)]
pub struct MouseSampler {
    transform: DeviceTransform,
    last: Option<DVec3>,
    velocity: DVec3,
    tick: u32,
}

impl MouseSampler {
    /// Velocity smoothing time constant (s).
    pub const SMOOTHING_S: f64 = 0.01;

    /// For a device-to-scene transform.
    pub fn new(transform: DeviceTransform) -> Self {
        Self {
            transform,
            last: None,
            velocity: DVec3::ZERO,
            tick: 0,
        }
    }

    /// The sample for the target `p` (scene) `dt` seconds after the previous one; `None`
    /// while the target is not finite (no cursor: nothing to touch).
    pub fn sample(&mut self, p: DVec3, buttons: u16, dt: f64) -> Option<CursorSample> {
        if !p.is_finite() {
            self.last = None;
            return None;
        }
        let d = self.transform.point_to_device(p);
        let raw = match self.last {
            Some(l) if dt > 0.0 => (d - l) / dt,
            _ => DVec3::ZERO,
        };
        let a = (dt / (Self::SMOOTHING_S + dt)).clamp(0.0, 1.0);
        self.velocity += (raw - self.velocity) * a;
        self.last = Some(d);
        self.tick = self.tick.wrapping_add(1);
        Some(CursorSample {
            position: d.as_vec3(),
            orientation: Quat::IDENTITY,
            velocity: self.velocity.as_vec3(),
            buttons,
            output_force: glam::Vec3::ZERO,
            servo_tick: self.tick,
            engaged: true,
            estop: false,
            ack: None,
        })
    }
}

/// The thread body: a cursor every [`PERIOD`] until stop. The session counts as up while it
/// runs (the simulation lets go of strokes when it is not).
pub fn run(
    hand: Arc<MouseHand>,
    mut sampler: MouseSampler,
    mut ports: MousePorts,
    shared: Arc<Shared>,
) {
    let net = &shared.net;
    net.connected.store(true, Ordering::Release);
    net.sessions.fetch_add(1, Ordering::Relaxed);
    let started = Instant::now();
    let mut next = started;
    let mut last = started;
    let mut sequence = 0u32;
    while !shared.stopping() {
        next += PERIOD;
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        } else if now - next > 5 * PERIOD {
            next = now;
        }
        let now = Instant::now();
        let (p, buttons) = hand.get();
        let dt = now.duration_since(last).as_secs_f64();
        last = now;
        let Some(cursor) = sampler.sample(p, buttons, dt) else {
            continue;
        };
        sequence = sequence.wrapping_add(1);
        let msg = CursorMsg {
            packet_sequence: sequence,
            server_timestamp_ns: now.duration_since(started).as_nanos() as u64,
            received: now,
            cursor,
        };
        net.cursors.fetch_add(1, Ordering::Relaxed);
        if ports.cursors.push(msg).is_err() {
            net.cursors_dropped.fetch_add(1, Ordering::Relaxed);
        }
        ports.force_thread.unpark();
    }
    net.connected.store(false, Ordering::Release);
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    #[test]
    fn samples_are_in_the_device_frame_with_a_smoothed_velocity() {
        let t = DeviceTransform::new(DQuat::IDENTITY, DVec3::new(0.0, 0.1, 0.0), 0.5);
        let mut s = MouseSampler::new(t);
        assert!(s.sample(DVec3::splat(f64::NAN), 0, 1e-3).is_none());
        let c = s.sample(DVec3::new(0.0, 0.1, 0.0), 1, 1e-3).unwrap();
        assert_eq!(c.position, glam::Vec3::ZERO);
        assert_eq!(c.velocity, glam::Vec3::ZERO, "no previous sample: at rest");
        assert_eq!(c.buttons, 1);
        // Move at 0.05 scene m/s = 0.1 device m/s along x for 100 ms: the velocity converges.
        let mut v = 0.0;
        for k in 1..=100 {
            let p = DVec3::new(0.05 * k as f64 * 1e-3, 0.1, 0.0);
            v = s.sample(p, 1, 1e-3).unwrap().velocity.x;
        }
        assert!((v - 0.1).abs() < 1e-3, "velocity {v}");
    }
}
