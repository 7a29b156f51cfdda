//! Control messages: serde + postcard, in length-prefixed frames over a reliable channel.
//!
//! Frame: `u32` little-endian payload length (at most [`MAX_FRAME_BYTES`]), then the postcard
//! encoding of one [`Control`]. Postcard writes an enum as its variant index (a varint), so the
//! order of [`Control`]'s variants is part of the wire format: append, never reorder.
//! [`FrameDecoder`] is sans-IO: feed it whatever bytes arrived, take out whole messages.
//! Every decoded message is validated ([`Control::validate`]) before it is returned.

use serde::{Deserialize, Serialize};

use crate::error::RejectCounts;
use crate::seq::SequenceStats;

/// Largest payload of one frame.
pub const MAX_FRAME_BYTES: usize = 64 * 1024;
/// Longest name (client or device) in bytes.
pub const MAX_NAME_BYTES: usize = 128;
/// Longest free-text message in bytes.
pub const MAX_TEXT_BYTES: usize = 1024;

/// One control message. Variant order is wire format.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Control {
    /// Client → server, first message.
    Hello(Hello),
    /// Server → client, answer to an accepted `Hello`.
    Welcome(Welcome),
    /// Client → server clock-sync request.
    ClockPing(ClockPing),
    /// Server → client clock-sync answer.
    ClockPong(ClockPong),
    /// Client → server settings for the servo loop.
    Config(Config),
    /// Server → client telemetry.
    Stats(Stats),
    /// Either way: latch (`engage: true`) or release an emergency stop.
    EmergencyStop(EmergencyStop),
    /// Either way: the session ends.
    Bye(Bye),
    /// Either way: a request was refused.
    Error(ErrorMessage),
}

/// Opens a session.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Hello {
    /// The client's [`crate::PROTOCOL_VERSION`].
    pub protocol_version: u8,
    /// Free-form client name for logs.
    pub client_name: String,
    /// Cursor stream rate the client wants, Hz (the server may send at its servo rate instead).
    pub requested_rate_hz: u32,
}

/// Accepts a session: what the device is and the keys of the hot path.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Welcome {
    /// The server's [`crate::PROTOCOL_VERSION`].
    pub protocol_version: u8,
    /// Device model name.
    pub device_name: String,
    /// Degrees of freedom sensed (3 = position, 6 = position + orientation).
    pub dof_input: u8,
    /// Degrees of freedom actuated (0 = no force output, 3 = force, 6 = force + torque).
    pub dof_output: u8,
    /// Workspace box minimum corner, m, device frame.
    pub workspace_min: [f32; 3],
    /// Workspace box maximum corner, m, device frame.
    pub workspace_max: [f32; 3],
    /// Largest force the server will output, N.
    pub max_force_n: f32,
    /// Largest stiffness the server will render, N/m.
    pub max_stiffness_n_per_m: f32,
    /// Servo loop rate, Hz.
    pub servo_rate_hz: u32,
    /// Session id carried in every hot-path header.
    pub session_id: u32,
    /// Key of the hot-path MACs (UDP); sent only over an authenticated, encrypted channel.
    pub session_key: [u8; 32],
}

/// Clock-sync request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ClockPing {
    /// Matches the pong to its ping.
    pub id: u32,
    /// Client send time, client clock, ns.
    pub t0_ns: u64,
}

/// Clock-sync answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ClockPong {
    /// The ping's id.
    pub id: u32,
    /// Echoed client send time, ns.
    pub t0_ns: u64,
    /// Server receive time, server clock, ns.
    pub t1_ns: u64,
    /// Server send time, server clock, ns.
    pub t2_ns: u64,
}

/// Servo-loop settings a client may change.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Config {
    /// Smoothing `E ← αE + (1−α)F` between updates; 0 turns it off; in `[0, 1)`.
    pub smoothing_alpha: f32,
    /// Watchdog: start fading force this long after the last command, µs.
    pub watchdog_fade_start_us: u32,
    /// Watchdog: force is zero this long after the last command, µs (> fade start).
    pub watchdog_zero_us: u32,
    /// Force limit, N (the server also applies its device's own limit).
    pub force_limit_n: f32,
}

/// Latch or release the emergency stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct EmergencyStop {
    /// `true` latches the stop (zero force now); `false` releases it (ramp-in again).
    pub engage: bool,
}

/// Percentiles of a latency distribution, ns.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Percentiles {
    /// Median.
    pub p50: u64,
    /// 99th percentile.
    pub p99: u64,
    /// 99.9th percentile.
    pub p999: u64,
    /// Maximum.
    pub max: u64,
}

/// Server telemetry.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Stats {
    /// Time since the servo loop started, ns.
    pub uptime_ns: u64,
    /// Servo ticks run.
    pub ticks: u64,
    /// Ticks that started after their deadline plus one period.
    pub overruns: u64,
    /// Tick-to-tick period.
    pub period_ns: Percentiles,
    /// Work inside one tick.
    pub tick_cost_ns: Percentiles,
    /// Hot-path packets received.
    pub packets_in: u64,
    /// Hot-path packets sent.
    pub packets_out: u64,
    /// Received packets rejected, by reason.
    pub rejected: RejectCounts,
    /// Sequence statistics of accepted force commands.
    pub force_sequence: SequenceStats,
    /// Ticks on which the force was clamped to the limit.
    pub clamped_ticks: u64,
    /// Times the watchdog began fading because commands stopped.
    pub watchdog_fades: u64,
    /// Force output is live.
    pub engaged: bool,
    /// Cursor → force round trip as the server sees it: the arrival of each applied force
    /// command minus the timestamp of the cursor sample it answers (both server clock), ns.
    pub force_rtt_ns: Percentiles,
}

/// Closes a session.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Bye {
    /// Why, for logs.
    pub reason: String,
}

/// Machine-readable cause of an [`ErrorMessage`]. Variant order is wire format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ErrorCode {
    /// The peer speaks another protocol version.
    VersionMismatch,
    /// Another session is active; one at a time.
    Busy,
    /// A message could not be decoded or failed validation.
    InvalidMessage,
    /// A `Config` value is out of range.
    InvalidConfig,
    /// The message is not expected in this state (e.g. `Config` before `Hello`).
    UnexpectedMessage,
    /// Something failed inside the server.
    Internal,
    /// The client did not prove an authorized identity (no client certificate, or one the
    /// server does not list in its authorized clients); it gets no session.
    Unauthenticated,
}

/// A refusal with its reason.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ErrorMessage {
    /// The cause.
    pub code: ErrorCode,
    /// Human-readable detail.
    pub message: String,
}

/// Why a control frame was not accepted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ControlError {
    /// The length prefix exceeds [`MAX_FRAME_BYTES`]; the stream cannot be resynchronised.
    #[error("control frame of {len} bytes exceeds the {MAX_FRAME_BYTES}-byte limit")]
    FrameTooLarge { len: usize },
    /// The payload is not a valid postcard `Control` (or has bytes left over).
    #[error("malformed control message: {0}")]
    Malformed(String),
    /// A field is out of range.
    #[error("invalid {field}: {reason}")]
    Invalid {
        field: &'static str,
        reason: &'static str,
    },
}

impl Control {
    /// Check ranges and lengths of every field.
    pub fn validate(&self) -> Result<(), ControlError> {
        let invalid = |field, reason| Err(ControlError::Invalid { field, reason });
        match self {
            Control::Hello(h) => {
                if h.client_name.len() > MAX_NAME_BYTES {
                    return invalid("hello.client_name", "longer than 128 bytes");
                }
                if h.requested_rate_hz == 0 || h.requested_rate_hz > 100_000 {
                    return invalid("hello.requested_rate_hz", "must be 1..=100000");
                }
            }
            Control::Welcome(w) => {
                if w.device_name.len() > MAX_NAME_BYTES {
                    return invalid("welcome.device_name", "longer than 128 bytes");
                }
                let all = w.workspace_min.iter().chain(&w.workspace_max);
                if !all.clone().all(|v| v.is_finite()) {
                    return invalid("welcome.workspace", "non-finite");
                }
                if w.workspace_min
                    .iter()
                    .zip(&w.workspace_max)
                    .any(|(a, b)| a > b)
                {
                    return invalid("welcome.workspace", "min exceeds max");
                }
                if !(w.max_force_n.is_finite() && w.max_force_n >= 0.0) {
                    return invalid("welcome.max_force_n", "must be finite and >= 0");
                }
                if !(w.max_stiffness_n_per_m.is_finite() && w.max_stiffness_n_per_m >= 0.0) {
                    return invalid("welcome.max_stiffness_n_per_m", "must be finite and >= 0");
                }
                if w.servo_rate_hz == 0 {
                    return invalid("welcome.servo_rate_hz", "must be > 0");
                }
            }
            Control::Config(c) => c.validate()?,
            Control::Bye(b) if b.reason.len() > MAX_TEXT_BYTES => {
                return invalid("bye.reason", "longer than 1024 bytes");
            }
            Control::Error(e) if e.message.len() > MAX_TEXT_BYTES => {
                return invalid("error.message", "longer than 1024 bytes");
            }
            _ => {}
        }
        Ok(())
    }

    /// Encode as one frame (length prefix + postcard).
    pub fn to_frame(&self) -> Vec<u8> {
        let mut frame = vec![0u8; 4];
        // Serialising plain data to a Vec cannot fail.
        let payload = postcard::to_allocvec(self).unwrap_or_default();
        frame[..4].copy_from_slice(&(payload.len() as u32).to_le_bytes());
        frame.extend_from_slice(&payload);
        frame
    }

    /// Decode and validate one frame's payload (without the length prefix).
    pub fn from_payload(payload: &[u8]) -> Result<Control, ControlError> {
        let (message, rest) = postcard::take_from_bytes::<Control>(payload)
            .map_err(|e| ControlError::Malformed(e.to_string()))?;
        if !rest.is_empty() {
            return Err(ControlError::Malformed(format!(
                "{} trailing bytes",
                rest.len()
            )));
        }
        message.validate()?;
        Ok(message)
    }
}

impl Config {
    /// Defaults: smoothing off, fade from 20 ms to zero at 30 ms, 3.3 N (Phantom Omni peak).
    pub const DEFAULT: Config = Config {
        smoothing_alpha: 0.0,
        watchdog_fade_start_us: 20_000,
        watchdog_zero_us: 30_000,
        force_limit_n: 3.3,
    };

    /// Check ranges.
    pub fn validate(&self) -> Result<(), ControlError> {
        let invalid = |field, reason| Err(ControlError::Invalid { field, reason });
        if !(self.smoothing_alpha.is_finite() && (0.0..1.0).contains(&self.smoothing_alpha)) {
            return invalid("config.smoothing_alpha", "must be in [0, 1)");
        }
        if self.watchdog_zero_us <= self.watchdog_fade_start_us {
            return invalid(
                "config.watchdog_zero_us",
                "must exceed watchdog_fade_start_us",
            );
        }
        if self.watchdog_zero_us > 1_000_000 {
            return invalid("config.watchdog_zero_us", "must be at most 1 s");
        }
        if !(self.force_limit_n.is_finite() && self.force_limit_n >= 0.0) {
            return invalid("config.force_limit_n", "must be finite and >= 0");
        }
        Ok(())
    }
}

impl Default for Config {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Reassembles [`Control`] messages from a byte stream; see the module doc.
#[derive(Debug, Default)]
pub struct FrameDecoder {
    buffer: Vec<u8>,
}

impl FrameDecoder {
    /// An empty decoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Append received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buffer.extend_from_slice(bytes);
    }

    /// The next whole message, `Ok(None)` if more bytes are needed. After
    /// [`ControlError::FrameTooLarge`] the stream is unusable: close it. After other errors the
    /// bad frame has been consumed and decoding may continue.
    pub fn next_message(&mut self) -> Result<Option<Control>, ControlError> {
        let Some(prefix) = self.buffer.first_chunk::<4>() else {
            return Ok(None);
        };
        let len = u32::from_le_bytes(*prefix) as usize;
        if len > MAX_FRAME_BYTES {
            return Err(ControlError::FrameTooLarge { len });
        }
        if self.buffer.len() < 4 + len {
            return Ok(None);
        }
        let result = Control::from_payload(&self.buffer[4..4 + len]);
        self.buffer.drain(..4 + len);
        result.map(Some)
    }

    /// Bytes held waiting for the rest of a frame.
    pub fn buffered(&self) -> usize {
        self.buffer.len()
    }
}
