//! The deterministic servo core: no I/O, no clock, no allocation, no locks.
//!
//! Driven by its owner in this order (the driver thread does it once per period):
//! 1. [`ServoCore::on_event`] for every session event (start, config, emergency stop, end),
//! 2. [`ServoCore::on_command`] for every force command that arrived (the newest wins),
//! 3. [`ServoCore::tick`]`(now, sample)` with the device reading; it returns the cursor to
//!    publish and the force to write: the newest command's local model rendered at the
//!    *current* position ([`protocol::ModelRenderer`]), optionally smoothed
//!    (`E ← αE + (1−α)F`), plus the passivity controller's damping when
//!    [`ServoParams::passivity`] is on ([`Passivity`]; its observer always runs), then passed
//!    through the [`Safety`] stages.
//!
//! Everything is plain arithmetic on fixed-size state, so a tick costs well under a microsecond
//! and the same inputs give bit-identical outputs.

use glam::Vec3;
use protocol::control::Config;
use protocol::{CursorSample, ForceAck, ForceCommand, ModelKind, ModelRenderer};

use super::passivity::Passivity;
use super::safety::{Safety, SafetyOutcome, SafetyParams, Stage};
use crate::device::{DeviceInfo, DeviceSample};

/// Servo parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoParams {
    /// Loop rate, Hz.
    pub rate_hz: u32,
    /// Safety limits (`max_force_n` already the device limit ∧ the configured one).
    pub safety: SafetyParams,
    /// Smoothing `α` in `[0, 1)`; 0 = off.
    pub smoothing_alpha: f32,
    /// The device's force limit, N: `Config.force_limit_n` can only lower the limit below this
    /// (and below `safety.max_force_n`, the server's own).
    pub device_max_force_n: f32,
    /// Largest stiffness rendered, N/m: local models are clamped to it.
    pub max_stiffness_n_per_m: f32,
    /// Largest damping rendered, N·s/m: local models are clamped to it (virtual damping far
    /// above what the device's mass and the servo period support makes the stylus buzz).
    pub max_damping_n_s_per_m: f32,
    /// Buttons that latch the emergency stop while pressed (0 = none).
    pub estop_button_mask: u16,
    /// Add the passivity controller's damping (bounded by `max_damping_n_s_per_m`) whenever
    /// the observer sees the output generating energy ([`Passivity`]).
    pub passivity: bool,
}

impl ServoParams {
    /// A Phantom Omni-class device at 1 kHz (CHAI3D's table: 3.3 N peak, ~700 N/m usable
    /// stiffness; 5 N·s/m damping) with the default safety stages, no smoothing, no
    /// emergency-stop button and no passivity controller: what tests, benches and virtual
    /// runs start from.
    pub fn omni_at_1khz() -> Self {
        Self {
            rate_hz: 1000,
            safety: SafetyParams::default(),
            smoothing_alpha: 0.0,
            device_max_force_n: 3.3,
            max_stiffness_n_per_m: 700.0,
            max_damping_n_s_per_m: 5.0,
            estop_button_mask: 0,
            passivity: false,
        }
    }

    /// Nominal period, ns.
    pub fn period_ns(&self) -> u64 {
        1_000_000_000 / u64::from(self.rate_hz.max(1))
    }

    /// These parameters under `info`'s limits: force (zero for an input-only device) and
    /// stiffness; the lower of the server's and the device's wins.
    pub fn limited_to(mut self, info: &DeviceInfo) -> Self {
        let device_limit = if info.dof_output == 0 {
            0.0
        } else {
            info.max_force_n
        };
        self.device_max_force_n = self.device_max_force_n.min(device_limit);
        self.safety.max_force_n = self.safety.max_force_n.min(self.device_max_force_n);
        self.max_stiffness_n_per_m = self.max_stiffness_n_per_m.min(info.max_stiffness_n_per_m);
        self
    }
}

/// Something the network side tells the servo loop, outside the hot path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SessionEvent {
    /// A workstation session is up: arm the output.
    Start,
    /// New settings from the workstation (already validated); the next `Start` restores the
    /// server's own.
    Config(Config),
    /// Latch (`true`) or release the emergency stop.
    EmergencyStop(bool),
    /// The session is over: output falls to zero.
    End,
}

/// The result of one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TickOutput {
    /// What to publish to the workstation (its `output_force` is what the device outputs from
    /// this tick on).
    pub cursor: CursorSample,
    /// What the safety stages did; `safety.force` is what to write.
    pub safety: SafetyOutcome,
}

/// The servo core; see the module doc.
#[derive(Debug, Clone)]
pub struct ServoCore {
    params: ServoParams,
    /// The server's own settings: every session starts from them (a `Config` lasts one session).
    base: ServoParams,
    renderer: ModelRenderer,
    command: Option<(ForceCommand, u64)>,
    /// The newest command's sequence and arrival, echoed in every cursor.
    ack: Option<ForceAck>,
    smoothed: Vec3,
    safety: Safety,
    passivity: Passivity,
    session_up: bool,
    tick: u32,
}

impl ServoCore {
    /// A core with no session: zero output.
    pub fn new(params: ServoParams) -> Self {
        Self {
            safety: Safety::new(params.safety, params.period_ns()),
            params,
            base: params,
            renderer: ModelRenderer::new(),
            command: None,
            ack: None,
            smoothed: Vec3::ZERO,
            passivity: Passivity::new(),
            session_up: false,
            tick: 0,
        }
    }

    /// Apply a session event at `now_ns`.
    pub fn on_event(&mut self, _now_ns: u64, event: SessionEvent) {
        match event {
            SessionEvent::Start => {
                self.session_up = true;
                self.params = self.base;
                self.safety.set_params(self.base.safety);
                self.command = None;
                self.ack = None;
                self.smoothed = Vec3::ZERO;
                self.renderer.reset();
                self.passivity.reset();
                self.safety.session_started();
            }
            SessionEvent::End => {
                self.session_up = false;
                self.command = None;
                self.ack = None;
                self.safety.session_ended();
            }
            SessionEvent::EmergencyStop(engage) => {
                self.safety.emergency_stop(engage, self.session_up);
            }
            SessionEvent::Config(c) => {
                self.params.smoothing_alpha = c.smoothing_alpha;
                let mut s = *self.safety.params();
                s.watchdog_fade_start_ns = u64::from(c.watchdog_fade_start_us) * 1_000;
                s.watchdog_zero_ns = u64::from(c.watchdog_zero_us) * 1_000;
                s.max_force_n = c
                    .force_limit_n
                    .min(self.base.safety.max_force_n)
                    .min(self.params.device_max_force_n);
                self.safety.set_params(s);
            }
        }
    }

    /// A validated force command arrived at `arrived_ns`; it replaces the previous one.
    /// Ignored without a session. Stiffness and damping are clamped to their limits here.
    pub fn on_command(&mut self, arrived_ns: u64, mut command: ForceCommand) {
        if !self.session_up {
            return;
        }
        let model = &mut command.model;
        model.stiffness = model.stiffness.min(self.params.max_stiffness_n_per_m);
        model.damping = model.damping.min(self.params.max_damping_n_s_per_m);
        if self.command.is_none_or(|(c, _)| c.model.kind != model.kind)
            || model.kind == ModelKind::None
        {
            self.renderer.reset();
        }
        self.command = Some((command, arrived_ns));
    }

    /// [`ServoCore::on_command`] for a command that came in a packet with header `sequence`:
    /// the cursors from now on acknowledge it ([`CursorSample::ack`]), so the client can time
    /// the round trip.
    pub fn on_command_packet(&mut self, arrived_ns: u64, sequence: u32, command: ForceCommand) {
        if self.session_up {
            self.ack = Some(ForceAck {
                sequence,
                arrival_ns: arrived_ns,
            });
        }
        self.on_command(arrived_ns, command);
    }

    /// One servo tick at `now_ns` with the device reading `sample`.
    pub fn tick(&mut self, now_ns: u64, sample: &DeviceSample) -> TickOutput {
        let output_before = self.safety.last_force();
        if sample.buttons & self.params.estop_button_mask != 0 && !self.safety.stopped() {
            self.safety.emergency_stop(true, self.session_up);
        }
        let (rendered, since) = match &self.command {
            Some((cmd, arrived)) => {
                let age_ns = now_ns.saturating_sub(*arrived);
                let f = self
                    .renderer
                    .render(cmd, sample.position, sample.velocity, age_ns / 1_000);
                (f, Some(age_ns))
            }
            None => (Vec3::ZERO, None),
        };
        let a = self.params.smoothing_alpha;
        self.smoothed = if a > 0.0 && a < 1.0 && self.smoothed.is_finite() {
            a * self.smoothed + (1.0 - a) * rendered
        } else {
            rendered
        };
        // The gate engages on the commanded force too: smoothing must not hide a large one.
        let wanted =
            if self.safety.stage() == Stage::Armed && rendered.length() > self.smoothed.length() {
                rendered
            } else {
                self.smoothed
            };
        self.passivity
            .observe(sample.position, wanted != Vec3::ZERO);
        let pc = if self.params.passivity {
            let period_s = self.params.period_ns() as f32 * 1e-9;
            self.passivity
                .control(sample.velocity, period_s, self.params.max_damping_n_s_per_m)
        } else {
            Vec3::ZERO
        };
        let safety = self.safety.apply(now_ns, wanted + pc, since);
        self.passivity.record(sample.position, safety.force, pc);
        let cursor = CursorSample {
            position: sample.position,
            orientation: sample.orientation,
            velocity: sample.velocity,
            buttons: sample.buttons,
            output_force: if safety.force.is_finite() {
                safety.force
            } else {
                output_before
            },
            servo_tick: self.tick,
            engaged: self.safety.engaged(),
            estop: self.safety.stopped(),
            ack: self.ack,
        };
        self.tick = self.tick.wrapping_add(1);
        TickOutput { cursor, safety }
    }

    /// The safety filter (stage, limits).
    pub fn safety(&self) -> &Safety {
        &self.safety
    }

    /// The smoothed force before safety, N.
    pub fn smoothed(&self) -> Vec3 {
        self.smoothed
    }

    /// The passivity observer (and controller state).
    pub fn passivity(&self) -> &Passivity {
        &self.passivity
    }

    /// A session is up.
    pub fn session_up(&self) -> bool {
        self.session_up
    }
}
