//! The TOML configuration: every setting, its default, and validation that names the field.
//!
//! Parsing is pure (no file system, no environment): [`ServerConfig::from_toml`] then
//! [`ServerConfig::validate`]. Command-line flags override fields after parsing (in `main`).
//! `deploy/haptics-server.example.toml` documents every field; a test parses it.

use std::net::SocketAddr;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::server::TransportKind;

mod device;

pub use device::{
    DeviceKind, DeviceSection, DhdSection, FakeSection, HidSection, OpenHapticsSection,
    ReplaySection,
};

/// The whole configuration file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct ServerConfig {
    /// Servo loop timing and real-time requests.
    pub servo: ServoSection,
    /// Safety limits.
    pub safety: SafetySection,
    /// Transport and timeouts.
    pub network: NetworkSection,
    /// Device selection and per-backend settings.
    pub device: DeviceSection,
    /// Logs and recording.
    pub telemetry: TelemetrySection,
}

/// `[servo]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ServoSection {
    /// Loop rate, Hz (100 … 10000).
    pub rate_hz: u32,
    /// Busy-wait this long before each deadline, µs (< the period).
    pub spin_us: u32,
    /// SCHED_FIFO priority 1 … 99; 0 = do not ask.
    pub realtime_priority: i32,
    /// Pin the servo thread to this CPU (omit: no pinning).
    pub cpu: Option<usize>,
    /// Lock all memory (mlockall).
    pub mlockall: bool,
    /// Buttons (bit mask) that latch the emergency stop; 0 = none.
    pub estop_button_mask: u16,
    /// Passivity observer/controller on the output (damping bounded by
    /// `safety.max_damping_n_s_per_m`).
    pub passivity: bool,
}

impl Default for ServoSection {
    fn default() -> Self {
        Self {
            rate_hz: 1000,
            spin_us: 50,
            realtime_priority: 80,
            cpu: None,
            mlockall: false,
            estop_button_mask: 0,
            passivity: false,
        }
    }
}

/// `[safety]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SafetySection {
    /// Force limit, N (the device's own limit also applies).
    pub max_force_n: f32,
    /// Largest stiffness rendered, N/m (the device's own limit also applies).
    pub max_stiffness_n_per_m: f32,
    /// Largest damping rendered, N·s/m.
    pub max_damping_n_s_per_m: f32,
    /// Output engages only when the commanded force is at most this, N.
    pub engage_threshold_n: f32,
    /// Ramp-in time, ms.
    pub ramp_ms: u32,
    /// Largest force change rate, N/s.
    pub slew_n_per_s: f32,
    /// Watchdog: start fading this long after the last command, ms.
    pub watchdog_fade_start_ms: f32,
    /// Watchdog: zero force this long after the last command, ms.
    pub watchdog_zero_ms: f32,
    /// Smoothing `E ← αE + (1−α)F` between updates, α in [0, 1); 0 = off.
    pub smoothing_alpha: f32,
}

impl Default for SafetySection {
    fn default() -> Self {
        Self {
            max_force_n: 3.3,
            max_stiffness_n_per_m: 700.0,
            max_damping_n_s_per_m: 5.0,
            engage_threshold_n: 0.5,
            ramp_ms: 200,
            slew_n_per_s: 200.0,
            watchdog_fade_start_ms: 20.0,
            watchdog_zero_ms: 30.0,
            smoothing_alpha: 0.0,
        }
    }
}

/// `[network]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NetworkSection {
    /// `udp` or `quic`.
    pub transport: TransportKind,
    /// Listen address.
    pub listen: SocketAddr,
    /// Certificate (PEM); omit for the default location.
    pub cert: Option<PathBuf>,
    /// Private key (PEM); omit for the default location.
    pub key: Option<PathBuf>,
    /// The workstations' client certificates that may open a session (PEM, one or more);
    /// omit for `authorized_clients.pem` next to the certificate.
    pub authorized_clients: Option<PathBuf>,
    /// Drop a session silent this long, ms.
    pub idle_timeout_ms: u64,
    /// Send `Stats` this often, ms.
    pub stats_interval_ms: u64,
    /// Perceptual deadband on the cursor stream, Weber fraction in [0, 1]; 0 = every tick.
    pub cursor_deadband: f32,
}

impl Default for NetworkSection {
    fn default() -> Self {
        Self {
            transport: TransportKind::Udp,
            listen: SocketAddr::from(([127, 0, 0, 1], 7700)),
            cert: None,
            key: None,
            authorized_clients: None,
            idle_timeout_ms: 2000,
            stats_interval_ms: 1000,
            cursor_deadband: 0.0,
        }
    }
}

/// `[telemetry]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TelemetrySection {
    /// Log a servo summary this often, s (0 = never).
    pub log_interval_s: f32,
    /// Record every tick to this file (for `--device replay`).
    pub record: Option<PathBuf>,
}

impl Default for TelemetrySection {
    fn default() -> Self {
        Self {
            log_interval_s: 5.0,
            record: None,
        }
    }
}

/// A configuration problem, naming the field.
#[derive(Debug, thiserror::Error, PartialEq)]
#[non_exhaustive]
pub enum ConfigError {
    /// The TOML does not parse or has unknown or mistyped fields.
    #[error("{file}: {message}")]
    Parse {
        /// The file.
        file: String,
        /// The parser's message (with line, column and key).
        message: String,
    },
    /// A value is out of range.
    #[error("invalid {field}: {reason}")]
    Invalid {
        /// Dotted field name, e.g. `safety.ramp_ms`.
        field: &'static str,
        /// Why.
        reason: String,
    },
}

fn invalid(field: &'static str, reason: impl Into<String>) -> Result<(), ConfigError> {
    Err(ConfigError::Invalid {
        field,
        reason: reason.into(),
    })
}

impl ServerConfig {
    /// Parse `text` (from `file`, for messages); unknown fields are errors.
    pub fn from_toml(text: &str, file: &str) -> Result<Self, ConfigError> {
        toml::from_str(text).map_err(|e| ConfigError::Parse {
            file: file.into(),
            message: e.to_string(),
        })
    }

    /// Check every range; the first problem is returned with its field name.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let s = &self.servo;
        if !(100..=10_000).contains(&s.rate_hz) {
            invalid(
                "servo.rate_hz",
                format!("{} is outside 100 … 10000 Hz", s.rate_hz),
            )?;
        }
        let period_us = 1_000_000 / s.rate_hz.max(1);
        if s.spin_us >= period_us {
            invalid(
                "servo.spin_us",
                format!(
                    "{} µs is not shorter than the {period_us} µs period",
                    s.spin_us
                ),
            )?;
        }
        if !(0..=99).contains(&s.realtime_priority) {
            invalid("servo.realtime_priority", "must be 0 (off) or 1 … 99")?;
        }
        let f = &self.safety;
        let finite_nonneg = |v: f32| v.is_finite() && v >= 0.0;
        if !finite_nonneg(f.max_force_n) || f.max_force_n > 100.0 {
            invalid("safety.max_force_n", "must be in 0 … 100 N")?;
        }
        if !finite_nonneg(f.max_stiffness_n_per_m) || f.max_stiffness_n_per_m > 100_000.0 {
            invalid("safety.max_stiffness_n_per_m", "must be in 0 … 100000 N/m")?;
        }
        if !finite_nonneg(f.max_damping_n_s_per_m) || f.max_damping_n_s_per_m > 1_000.0 {
            invalid("safety.max_damping_n_s_per_m", "must be in 0 … 1000 N·s/m")?;
        }
        if !finite_nonneg(f.engage_threshold_n) {
            invalid("safety.engage_threshold_n", "must be finite and >= 0")?;
        }
        if f.ramp_ms > 10_000 {
            invalid("safety.ramp_ms", "must be at most 10000 ms")?;
        }
        if !(f.slew_n_per_s.is_finite() && f.slew_n_per_s > 0.0) {
            invalid("safety.slew_n_per_s", "must be finite and > 0")?;
        }
        if !(finite_nonneg(f.watchdog_fade_start_ms) && f.watchdog_zero_ms.is_finite()) {
            invalid("safety.watchdog_fade_start_ms", "must be finite and >= 0")?;
        }
        if f.watchdog_zero_ms <= f.watchdog_fade_start_ms || f.watchdog_zero_ms > 1000.0 {
            invalid(
                "safety.watchdog_zero_ms",
                "must exceed watchdog_fade_start_ms and be at most 1000 ms",
            )?;
        }
        if !(f.smoothing_alpha.is_finite() && (0.0..1.0).contains(&f.smoothing_alpha)) {
            invalid("safety.smoothing_alpha", "must be in [0, 1)")?;
        }
        if s.passivity && f.max_damping_n_s_per_m <= 0.0 {
            invalid(
                "servo.passivity",
                "needs safety.max_damping_n_s_per_m > 0 (it bounds the controller's damping)",
            )?;
        }
        let n = &self.network;
        if !(n.cursor_deadband.is_finite() && (0.0..=1.0).contains(&n.cursor_deadband)) {
            invalid("network.cursor_deadband", "must be in [0, 1] (0 = off)")?;
        }
        if !(50..=600_000).contains(&n.idle_timeout_ms) {
            invalid("network.idle_timeout_ms", "must be in 50 … 600000 ms")?;
        }
        if !(10..=600_000).contains(&n.stats_interval_ms) {
            invalid("network.stats_interval_ms", "must be in 10 … 600000 ms")?;
        }
        if n.cert.is_some() != n.key.is_some() {
            invalid("network.cert", "give both cert and key, or neither")?;
        }
        let d = &self.device;
        if !["idle", "circle", "line", "press", "file"].contains(&d.fake.path.as_str()) {
            invalid(
                "device.fake.path",
                format!(
                    "{:?} is not one of idle, circle, line, press, file",
                    d.fake.path
                ),
            )?;
        }
        if d.fake.path == "file" && d.fake.path_file.is_none() {
            invalid("device.fake.path_file", "required when path = \"file\"")?;
        }
        if !(d.fake.size_m.is_finite() && d.fake.size_m > 0.0 && d.fake.size_m <= 1.0) {
            invalid("device.fake.size_m", "must be in (0, 1] m")?;
        }
        if !(d.fake.period_s.is_finite() && d.fake.period_s > 0.0) {
            invalid("device.fake.period_s", "must be finite and > 0")?;
        }
        if !(finite_nonneg(d.fake.tremor_m) && d.fake.tremor_m <= 0.01) {
            invalid("device.fake.tremor_m", "must be in 0 … 0.01 m")?;
        }
        if let Err(e) = crate::device::axes::AxisMap::parse(&d.fake.axes) {
            invalid("device.fake.axes", e)?;
        }
        if d.dhd.index.is_some_and(|i| i > 15) {
            invalid("device.dhd.index", "must be 0 … 15")?;
        }
        if d.kind == DeviceKind::Replay && d.replay.file.is_none() {
            invalid(
                "device.replay.file",
                "required for the replay device (or pass --replay-file)",
            )?;
        }
        if !["spacemouse", "layout"].contains(&d.hid.profile.as_str()) {
            invalid(
                "device.hid.profile",
                format!("{:?} is not spacemouse or layout", d.hid.profile),
            )?;
        }
        if d.kind == DeviceKind::Hid && d.hid.profile == "layout" && d.hid.layout_file.is_none() {
            invalid(
                "device.hid.layout_file",
                "required when profile = \"layout\"",
            )?;
        }
        if !(finite_nonneg(self.telemetry.log_interval_s)) {
            invalid("telemetry.log_interval_s", "must be finite and >= 0")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
