//! `protocol`: everything the haptics server and the workstation say to each other.
//!
//! Contract: no I/O, no clock, no global state, no allocation on the hot path. Every function
//! here is a pure transformation of bytes and values; time enters as arguments.
//!
//! - [`packet`]: the hot-path packets ([`CursorSample`] server→workstation at the servo rate,
//!   [`ForceCommand`] workstation→server) in a fixed little-endian layout, documented byte by
//!   byte in `docs/PROTOCOL.md`, with validation of every decoded value.
//! - [`session`]: [`Outbound`] numbers and seals packets; [`Inbound`] authenticates, decodes,
//!   checks session and replay window, and counts every rejection by reason.
//! - [`mac`]: the 16-byte MAC on UDP packets, keyed by the per-session [`SessionKey`].
//! - [`control`]: control messages (serde + postcard, length-prefixed frames) over a reliable
//!   channel: hello/welcome, configuration, clock-sync pings, statistics, bye, errors.
//! - [`clock`]: the NTP-style clock-offset estimator with a hard uncertainty bound.
//! - [`seq`]: the sequence tracker (loss, reordering, duplicates) that also serves as replay window.
//! - [`deadband`]: perceptual deadbands that thin the cursor and force streams (Weber fraction,
//!   floor, heartbeat under the watchdog's fade start).
//! - [`sim_link`]: a simulated link on a virtual clock (delay, jitter, loss, reordering,
//!   duplication) for deterministic tests and studies of the whole exchange.
//!
//! A malformed, forged, replayed or out-of-range packet is rejected with a specific
//! [`DecodeError`] variant; nothing here panics on any input.

pub mod applied_age;
pub mod clock;
pub mod control;
pub mod deadband;
pub mod error;
pub mod mac;
pub mod model;
pub mod packet;
pub mod seq;
pub mod session;
pub mod sim_link;
mod wire;

pub use applied_age::{AppliedAge, AppliedAgeFractions};
pub use clock::{ClockEstimate, ClockEstimator, ClockSample};
pub use control::{Control, FrameDecoder};
pub use deadband::{CursorDeadband, Deadband, DeadbandParams, ForceDeadband};
pub use error::{DecodeError, Reject, RejectCounts};
pub use mac::SessionKey;
pub use model::ModelRenderer;
pub use packet::{Body, CursorSample, ForceAck, ForceCommand, LocalModel, ModelKind, Packet};
pub use seq::{Arrival, SequenceStats, SequenceTracker};
pub use session::{Inbound, Outbound};
pub use sim_link::{LinkCounters, LinkParams, SimLink};

/// Version byte carried in every packet header and in `Hello`/`Welcome`.
pub const PROTOCOL_VERSION: u8 = 3;

/// First two bytes of every hot-path packet: ASCII `"HP"`.
pub const MAGIC: [u8; 2] = *b"HP";
