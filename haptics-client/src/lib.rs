//! `haptics-client`: the workstation side of a session with a `haptics-server`.
//!
//! Why a crate of its own: a workstation connects to a server but never owns a device, so it
//! must not build the device backends (HID, the OpenHaptics loader), the servo loop or the
//! certificate generator. This crate holds exactly what both ends share on the wire side plus
//! the client: `haptics-server` depends on it and re-exports it at the old paths
//! (`haptics_server::client`, `::clock`, `::tls`), `workstation` depends on it alone.
//!
//! - [`client`]: [`client::Client::connect`] (pinned TLS, `Hello`/`Welcome`), the
//!   [`client::ControlChannel`] and the [`client::HotPath`], which splits into a receiver for
//!   the network task and a [`client::HotSender`] a force thread owns.
//! - [`clock`]: [`clock::MonoClock`], monotonic nanoseconds both ends stamp packets with.
//! - [`tls`]: the pinned-certificate verifier and client configuration.
//! - [`framing`]: control messages over a byte stream, shared with the server.
//! - [`quic`]: QUIC transport settings shared with the server.

pub mod client;
pub mod clock;
pub mod framing;
pub mod quic;
pub mod tls;

pub use client::{
    BlockingReceiver, Client, ClientConfig, ClientError, HotPath, HotReceiver, HotSender,
};
pub use framing::TransportError;

/// Which transport serves the workstation.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum TransportKind {
    /// TLS-over-TCP control + MAC'd UDP datagrams.
    Udp,
    /// QUIC: one bidi stream for control, unreliable datagrams for the hot path.
    Quic,
}
