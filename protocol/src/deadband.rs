//! Perceptual deadband (in the spirit of IEEE 1918.1.1 and Hinterseer et al., "Perception-based
//! data reduction and transmission of haptic data in telepresence and teleaction systems",
//! 2008): send a new sample only when it differs from the last one *sent* by more than a
//! fraction of it (Weber's law: a change below `k × |value|` is not felt), with an absolute
//! floor (so noise around zero is not sent either) and a heartbeat.
//!
//! Sans-IO: each call takes `now` and answers "send it or not"; the receiver just keeps the
//! last sample (zero-order hold, as the server and the workstation already do).
//!
//! - [`Deadband`]: one vector quantity, `|v − v_sent| > max(k·|v_sent|, floor)`.
//! - [`CursorDeadband`]: the server's cursor stream, one knob `k`: the velocity deadband
//!   `(k, k × 10 mm/s)`, the position deadband `(0, k × 1 mm)` (a plane contact's force error
//!   from a stale cursor is `Δx / depth` of the force: below `k` for contacts deeper than 1 mm),
//!   and any change of buttons or flags.
//! - [`ForceDeadband`]: the workstation's command stream, one knob `k`: the force deadband
//!   `(k, k × 0.5 N)`, and the local model: kind, a normal turning by more than about `k` rad (the
//!   chord between the unit normals), a point
//!   moving more than `k × 1 mm`, or a stiffness, damping or friction changing by more than `k`
//!   of itself.
//!
//! Every stream also sends at least every `heartbeat_ns`: cursors every [`HEARTBEAT_NS`]
//! (10 ms), commands every [`FORCE_HEARTBEAT_NS`] (5 ms). The workstation can only answer a
//! cursor that arrived, so with both deadbands on, the longest silence of the command stream is
//! the sum, 15 ms: below the server watchdog's default fade start (20 ms) and the local models'
//! lifetime (20 ms), so a quiet but live contact is never faded out on a clean link. (Two 10 ms
//! heartbeats measured an 18 ms gap in the delay study: too close to the fade.)
//! `k = 0` turns a deadband off (every sample is sent). Non-finite values are always sent (the
//! receiver's validation rejects them; the deadband does not hide them).

use glam::Vec3;

use crate::packet::{CursorSample, ForceCommand, LocalModel};

/// Default longest silence of the cursor stream, ns (10 ms).
pub const HEARTBEAT_NS: u64 = 10_000_000;
/// Default longest silence of the command stream once a cursor arrives, ns (5 ms).
pub const FORCE_HEARTBEAT_NS: u64 = 5_000_000;
/// Position floor of the cursor deadband per unit `k`, m.
pub const CURSOR_POSITION_SCALE_M: f32 = 1e-3;
/// Velocity floor of the cursor deadband per unit `k`, m/s.
pub const CURSOR_VELOCITY_SCALE_M_S: f32 = 1e-2;
/// Force floor of the command deadband per unit `k`, N.
pub const FORCE_SCALE_N: f32 = 0.5;

/// One vector deadband's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeadbandParams {
    /// Weber fraction `k` (≥ 0): relative change that is felt.
    pub weber: f32,
    /// Absolute threshold, in the quantity's unit (≥ 0).
    pub floor: f32,
    /// Longest silence, ns.
    pub heartbeat_ns: u64,
}

/// A deadband on one vector quantity; see the module doc.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Deadband {
    params: DeadbandParams,
    sent: Option<(Vec3, u64)>,
}

impl Deadband {
    /// A deadband that has sent nothing yet.
    pub const fn new(params: DeadbandParams) -> Self {
        Self { params, sent: None }
    }

    /// The settings.
    pub fn params(&self) -> &DeadbandParams {
        &self.params
    }

    /// `value` differs enough from the last one sent (or nothing was sent, or it is not finite).
    pub fn exceeds(&self, value: Vec3) -> bool {
        let Some((sent, _)) = self.sent else {
            return true;
        };
        let p = &self.params;
        !value.is_finite()
            || (p.weber <= 0.0 && p.floor <= 0.0)
            || (value - sent).length() > (p.weber * sent.length()).max(p.floor)
    }

    /// The heartbeat is due at `now_ns`.
    pub fn heartbeat_due(&self, now_ns: u64) -> bool {
        self.sent
            .is_none_or(|(_, t)| now_ns.saturating_sub(t) >= self.params.heartbeat_ns)
    }

    /// Record that `value` was sent at `now_ns`.
    pub fn mark_sent(&mut self, now_ns: u64, value: Vec3) {
        self.sent = Some((value, now_ns));
    }

    /// Decide for `value` at `now_ns`: `true` = send it (and it becomes the reference).
    pub fn update(&mut self, now_ns: u64, value: Vec3) -> bool {
        let send = self.exceeds(value) || self.heartbeat_due(now_ns);
        if send {
            self.mark_sent(now_ns, value);
        }
        send
    }

    /// Forget what was sent: the next sample goes out.
    pub fn reset(&mut self) {
        self.sent = None;
    }
}

/// The cursor stream's deadband (server → workstation); see the module doc.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CursorDeadband {
    k: f32,
    position: Deadband,
    velocity: Deadband,
    discrete: Option<u32>,
}

impl CursorDeadband {
    /// The Weber fraction (0: off).
    pub fn weber(&self) -> f32 {
        self.k
    }

    /// Weber fraction `k` (≤ 0 or non-finite: off), heartbeat [`HEARTBEAT_NS`].
    pub fn new(k: f32) -> Self {
        Self::with_heartbeat(k, HEARTBEAT_NS)
    }

    /// Weber fraction `k` with another heartbeat.
    pub fn with_heartbeat(k: f32, heartbeat_ns: u64) -> Self {
        let k = if k.is_finite() { k.max(0.0) } else { 0.0 };
        let db = |weber, floor| {
            Deadband::new(DeadbandParams {
                weber,
                floor,
                heartbeat_ns,
            })
        };
        Self {
            k,
            position: db(0.0, k * CURSOR_POSITION_SCALE_M),
            velocity: db(k, k * CURSOR_VELOCITY_SCALE_M_S),
            discrete: None,
        }
    }

    /// The deadband is on.
    pub fn enabled(&self) -> bool {
        self.k > 0.0
    }

    /// Decide for `cursor` at `now_ns`: `true` = send it.
    pub fn should_send(&mut self, now_ns: u64, cursor: &CursorSample) -> bool {
        let flags = u32::from(cursor.buttons)
            | u32::from(cursor.engaged) << 16
            | u32::from(cursor.estop) << 17;
        self.should_send_parts(now_ns, cursor.position, cursor.velocity, flags)
    }

    /// [`Self::should_send`] on the parts that matter: position, velocity, and the discrete
    /// state (buttons and flags packed in any way; any change is sent).
    pub fn should_send_parts(
        &mut self,
        now_ns: u64,
        position: Vec3,
        velocity: Vec3,
        discrete: u32,
    ) -> bool {
        let send = !self.enabled()
            || self.discrete != Some(discrete)
            || self.position.exceeds(position)
            || self.velocity.exceeds(velocity)
            || self.position.heartbeat_due(now_ns);
        if send {
            self.position.mark_sent(now_ns, position);
            self.velocity.mark_sent(now_ns, velocity);
            self.discrete = Some(discrete);
        }
        send
    }

    /// Forget what was sent (a new session): the next cursor goes out.
    pub fn reset(&mut self) {
        self.position.reset();
        self.velocity.reset();
        self.discrete = None;
    }
}

/// The force command stream's deadband (workstation → server); see the module doc.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceDeadband {
    k: f32,
    force: Deadband,
    model: Option<LocalModel>,
}

impl ForceDeadband {
    /// The Weber fraction (0: off).
    pub fn weber(&self) -> f32 {
        self.k
    }

    /// Weber fraction `k` (≤ 0 or non-finite: off), heartbeat [`FORCE_HEARTBEAT_NS`].
    pub fn new(k: f32) -> Self {
        Self::with_heartbeat(k, FORCE_HEARTBEAT_NS)
    }

    /// Weber fraction `k` with another heartbeat.
    pub fn with_heartbeat(k: f32, heartbeat_ns: u64) -> Self {
        let k = if k.is_finite() { k.max(0.0) } else { 0.0 };
        Self {
            k,
            force: Deadband::new(DeadbandParams {
                weber: k,
                floor: k * FORCE_SCALE_N,
                heartbeat_ns,
            }),
            model: None,
        }
    }

    /// The deadband is on.
    pub fn enabled(&self) -> bool {
        self.k > 0.0
    }

    /// Decide for `command` at `now_ns`: `true` = send it.
    pub fn should_send(&mut self, now_ns: u64, command: &ForceCommand) -> bool {
        let send = !self.enabled()
            || self.force.exceeds(command.force)
            || self.force.heartbeat_due(now_ns)
            || self
                .model
                .is_none_or(|m| self.model_differs(&m, &command.model));
        if send {
            self.force.mark_sent(now_ns, command.force);
            self.model = Some(command.model);
        }
        send
    }

    fn model_differs(&self, sent: &LocalModel, new: &LocalModel) -> bool {
        let k = self.k;
        let rel = |a: f32, b: f32| (a - b).abs() > k * a.abs().max(b.abs());
        sent.kind != new.kind
            || sent.point.distance(new.point) > k * CURSOR_POSITION_SCALE_M
            || sent.normal.distance(new.normal) > k
            || rel(sent.stiffness, new.stiffness)
            || rel(sent.damping, new.damping)
            || rel(sent.friction, new.friction)
            || rel(sent.validity_radius, new.validity_radius)
            || sent.lifetime_us != new.lifetime_us
    }

    /// Forget what was sent (a new session): the next command goes out.
    pub fn reset(&mut self) {
        self.force.reset();
        self.model = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::packet::ModelKind;

    const MS: u64 = 1_000_000;

    #[test]
    fn weber_fraction_and_floor_decide() {
        let mut d = Deadband::new(DeadbandParams {
            weber: 0.1,
            floor: 0.05,
            heartbeat_ns: 10 * MS,
        });
        assert!(d.update(0, Vec3::X), "first sample always goes");
        assert!(!d.update(MS, Vec3::X * 1.09), "9 % is below k = 10 %");
        assert!(d.update(2 * MS, Vec3::X * 1.11), "11 % is above");
        // Near zero the floor rules: 0.04 N is not sent, 0.06 N is.
        let mut z = d;
        z.mark_sent(3 * MS, Vec3::ZERO);
        assert!(!z.update(4 * MS, Vec3::Y * 0.04));
        assert!(z.update(5 * MS, Vec3::Y * 0.06));
        // A direction change of the same magnitude is a change.
        assert!(d.update(6 * MS, Vec3::Y * 1.11));
        assert!(d.update(7 * MS, Vec3::NAN), "non-finite always goes");
    }

    #[test]
    fn heartbeat_keeps_a_quiet_stream_alive() {
        let mut d = Deadband::new(DeadbandParams {
            weber: 0.5,
            floor: 1.0,
            heartbeat_ns: 10 * MS,
        });
        let sent: Vec<u64> = (0..=50).filter(|&t| d.update(t * MS, Vec3::ONE)).collect();
        assert_eq!(sent, [0, 10, 20, 30, 40, 50]);
    }

    #[test]
    fn zero_k_sends_everything() {
        let mut c = CursorDeadband::new(0.0);
        let mut f = ForceDeadband::new(0.0);
        let cmd = command(Vec3::X, 0.0);
        assert!(!c.enabled() && !f.enabled());
        assert!((0..100).all(|t| c.should_send_parts(t * MS, Vec3::ZERO, Vec3::ZERO, 0)));
        assert!((0..100).all(|t| f.should_send(t * MS, &cmd)));
    }

    #[test]
    fn cursor_deadband_thins_a_slow_slide_and_never_misses_a_button() {
        let mut c = CursorDeadband::new(0.1);
        // Sliding at 15 mm/s: the position floor (0.1 mm) is crossed every 7 ms.
        let v = Vec3::X * 0.015;
        let mut sent = 0;
        for t in 0..1000u64 {
            let x = v * (t as f32 * 1e-3);
            let buttons = u32::from(t == 500);
            if c.should_send_parts(t * MS, x, v, buttons) {
                sent += 1;
            } else {
                assert_ne!(t, 500, "a button press is always sent");
                assert_ne!(t, 501, "and its release");
            }
        }
        assert!((100..200).contains(&sent), "{sent} of 1000");
        // A sudden stop (velocity change 100 %) goes at once.
        assert!(c.should_send_parts(1000 * MS, v * 1.0005, Vec3::ZERO, 0));
    }

    fn command(force: Vec3, point_x: f32) -> ForceCommand {
        ForceCommand {
            force,
            torque: None,
            answers_sequence: 0,
            answers_timestamp_ns: 0,
            model: LocalModel {
                kind: ModelKind::Plane,
                point: Vec3::new(point_x, 0.0, 0.0),
                normal: Vec3::Y,
                stiffness: 700.0,
                damping: 0.5,
                friction: 0.2,
                validity_radius: 0.004,
                lifetime_us: 20_000,
            },
        }
    }

    #[test]
    fn force_deadband_sends_felt_changes_and_model_changes() {
        let mut f = ForceDeadband::new(0.1);
        assert!(f.should_send(0, &command(Vec3::Y, 0.0)));
        assert!(!f.should_send(MS, &command(Vec3::Y * 1.05, 0.0)));
        assert!(f.should_send(2 * MS, &command(Vec3::Y * 1.2, 0.0)));
        // The same force from a plane whose point moved 0.2 mm (> k × 1 mm).
        assert!(!f.should_send(3 * MS, &command(Vec3::Y * 1.2, 5e-5)));
        assert!(f.should_send(4 * MS, &command(Vec3::Y * 1.2, 2e-4)));
        let mut other = command(Vec3::Y * 1.2, 2e-4);
        other.model.kind = ModelKind::Anchor;
        assert!(f.should_send(5 * MS, &other), "a new model kind");
        // Quiet: only the heartbeat.
        let quiet = (6..60)
            .filter(|&t| f.should_send(t * MS, &other))
            .collect::<Vec<_>>();
        assert_eq!(quiet, (10..60).step_by(5).collect::<Vec<_>>());
        f.reset();
        assert!(f.should_send(61 * MS, &other), "after a reset");
    }
}
