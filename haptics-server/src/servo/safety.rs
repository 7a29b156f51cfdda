//! The safety stages between the rendered force and the device, as a deterministic state
//! machine driven with `now`.
//!
//! Order per tick (each stage sees the previous one's output):
//! 1. **Gate**: [`Stage::Idle`] (no session) and [`Stage::Stopped`] (emergency stop) output zero.
//!    [`Stage::Armed`] waits for a command whose force is at most `engage_threshold_n`, then
//!    [`Stage::Ramping`] scales the force linearly from 0 to 1 over `ramp_ns`, then
//!    [`Stage::Engaged`].
//! 2. **Watchdog**: weight 1 until `watchdog_fade_start_ns` after the last command, falling
//!    linearly to 0 at `watchdog_zero_ns`; reaching zero re-arms (the next command ramps in).
//! 3. **Clamp**: magnitude limited to `max_force_n`, direction kept.
//! 4. **Slew**: the change per tick is limited to `slew_n_per_s × dt` (emergency stop bypasses
//!    it: zero at once). `dt` is capped at two periods, so a loop that stalled cannot jump to a
//!    new force; but while the watchdog fades, the magnitude may fall by what the real elapsed
//!    time grants at the slew rate (never below the fade's own target), so late ticks on a
//!    loaded machine do not carry force past the watchdog's zero time.
//! 5. **Finite**: a non-finite value anywhere becomes zero and is counted.
//!
//! No allocation, no I/O: plain arithmetic on `Vec3`.

use glam::Vec3;

/// Safety limits and timings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SafetyParams {
    /// Force magnitude limit, N (device limit ∧ configured limit).
    pub max_force_n: f32,
    /// Output engages only when the commanded force is at most this, N.
    pub engage_threshold_n: f32,
    /// Ramp-in duration, ns.
    pub ramp_ns: u64,
    /// Largest force change rate, N/s.
    pub slew_n_per_s: f32,
    /// Watchdog: start fading this long after the last command, ns.
    pub watchdog_fade_start_ns: u64,
    /// Watchdog: zero this long after the last command, ns.
    pub watchdog_zero_ns: u64,
}

impl Default for SafetyParams {
    fn default() -> Self {
        Self {
            max_force_n: 3.3,
            engage_threshold_n: 0.5,
            ramp_ns: 200_000_000,
            slew_n_per_s: 200.0,
            watchdog_fade_start_ns: 20_000_000,
            watchdog_zero_ns: 30_000_000,
        }
    }
}

/// Where the output gate stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// No session: zero output.
    Idle,
    /// Session up, waiting for a small enough command.
    Armed,
    /// Ramping in since `since_ns`.
    Ramping {
        /// When the ramp started, ns.
        since_ns: u64,
    },
    /// Full output.
    Engaged,
    /// Emergency stop latched: zero until released.
    Stopped,
}

/// What the safety stage did on one tick.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SafetyOutcome {
    /// The force to write.
    pub force: Vec3,
    /// The clamp cut the magnitude.
    pub clamped: bool,
    /// The slew limit cut the change.
    pub slewed: bool,
    /// A non-finite value was replaced by zero.
    pub nonfinite: bool,
    /// The watchdog began fading on this tick.
    pub fade_started: bool,
}

/// The staged safety filter; see the module doc.
#[derive(Debug, Clone)]
pub struct Safety {
    params: SafetyParams,
    stage: Stage,
    last_force: Vec3,
    last_ns: Option<u64>,
    fading: bool,
    max_dt_ns: u64,
}

impl Safety {
    /// A filter in [`Stage::Idle`]; `period_ns` bounds the `dt` the slew limit grants.
    pub fn new(params: SafetyParams, period_ns: u64) -> Self {
        Self {
            params,
            stage: Stage::Idle,
            last_force: Vec3::ZERO,
            last_ns: None,
            fading: false,
            max_dt_ns: period_ns.saturating_mul(2).max(1),
        }
    }

    /// Current stage.
    pub fn stage(&self) -> Stage {
        self.stage
    }

    /// The limits in force.
    pub fn params(&self) -> &SafetyParams {
        &self.params
    }

    /// Replace the limits (from `Config`); the stage is kept.
    pub fn set_params(&mut self, params: SafetyParams) {
        self.params = params;
    }

    /// Force output is live (ramping or engaged).
    pub fn engaged(&self) -> bool {
        matches!(self.stage, Stage::Ramping { .. } | Stage::Engaged)
    }

    /// A session started: arm (unless stopped).
    pub fn session_started(&mut self) {
        if self.stage != Stage::Stopped {
            self.stage = Stage::Armed;
        }
    }

    /// The session ended: idle (an emergency stop stays latched).
    pub fn session_ended(&mut self) {
        if self.stage != Stage::Stopped {
            self.stage = Stage::Idle;
        }
    }

    /// Latch (`true`) or release the emergency stop; release re-arms, output ramps in again.
    /// Releasing a stop that is not latched changes nothing.
    pub fn emergency_stop(&mut self, engage: bool, session_up: bool) {
        self.stage = match (engage, session_up) {
            (true, _) => Stage::Stopped,
            (false, _) if self.stage != Stage::Stopped => self.stage,
            (false, true) => Stage::Armed,
            (false, false) => Stage::Idle,
        };
    }

    /// Emergency stop is latched.
    pub fn stopped(&self) -> bool {
        self.stage == Stage::Stopped
    }

    /// Filter `wanted` (the smoothed, rendered force) at `now_ns`; `since_command_ns` is the
    /// time since the last command arrived (`None`: none yet).
    pub fn apply(
        &mut self,
        now_ns: u64,
        wanted: Vec3,
        since_command_ns: Option<u64>,
    ) -> SafetyOutcome {
        let p = self.params;
        let mut out = SafetyOutcome::default();
        let elapsed_ns = self.last_ns.map_or(0, |t| now_ns.saturating_sub(t));
        let dt_ns = elapsed_ns.min(self.max_dt_ns);
        self.last_ns = Some(now_ns);
        let wanted = if wanted.is_finite() {
            wanted
        } else {
            out.nonfinite = true;
            Vec3::ZERO
        };

        // 2. Watchdog weight.
        let weight = match since_command_ns {
            None => 0.0,
            Some(age) if age <= p.watchdog_fade_start_ns => 1.0,
            Some(age) if age >= p.watchdog_zero_ns => 0.0,
            Some(age) => {
                let span = (p.watchdog_zero_ns - p.watchdog_fade_start_ns) as f32;
                1.0 - (age - p.watchdog_fade_start_ns) as f32 / span
            }
        };
        let fading = since_command_ns.is_some_and(|a| a > p.watchdog_fade_start_ns);
        out.fade_started = fading && !self.fading && self.engaged();
        self.fading = fading;

        // 1. Gate.
        let gain = match self.stage {
            Stage::Idle | Stage::Stopped => 0.0,
            Stage::Armed => {
                if weight > 0.0 && wanted.length() <= p.engage_threshold_n {
                    self.stage = Stage::Ramping { since_ns: now_ns };
                }
                0.0
            }
            Stage::Ramping { since_ns } => {
                let g = (now_ns.saturating_sub(since_ns) as f64 / p.ramp_ns.max(1) as f64) as f32;
                if g >= 1.0 {
                    self.stage = Stage::Engaged;
                }
                g.min(1.0)
            }
            Stage::Engaged => 1.0,
        };
        if self.engaged() && since_command_ns.is_some_and(|a| a >= p.watchdog_zero_ns) {
            self.stage = Stage::Armed;
        }
        let mut target = wanted * (gain * weight);

        // 3. Clamp, keeping direction.
        let limit = p.max_force_n.max(0.0);
        let mag = target.length();
        if mag > limit {
            target *= limit / mag;
            out.clamped = true;
        }

        // 4. Slew (emergency stop bypasses it).
        if self.stage == Stage::Stopped {
            target = Vec3::ZERO;
        } else {
            let slew = p.slew_n_per_s.max(0.0);
            let faded = target.length();
            let max_step = slew * dt_ns as f32 * 1e-9;
            let delta = target - self.last_force;
            let step = delta.length();
            if step > max_step {
                target = self.last_force + delta * (max_step / step);
                out.slewed = true;
            }
            // The fade is a schedule in time: after a late tick the capped step above would
            // leave the output behind it. Shrink only, by real time at the slew rate.
            if fading {
                let reachable =
                    (self.last_force.length() - slew * elapsed_ns as f32 * 1e-9).max(faded);
                let mag = target.length();
                if mag > reachable {
                    target *= reachable / mag;
                }
            }
        }

        // 5. Finite, always.
        if !target.is_finite() {
            out.nonfinite = true;
            target = Vec3::ZERO;
        }
        self.last_force = target;
        out.force = target;
        out
    }

    /// The force output on the last tick.
    pub fn last_force(&self) -> Vec3 {
        self.last_force
    }
}
