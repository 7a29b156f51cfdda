//! `haptics-server`: owns the haptic device and serves it to one workstation at a time.
//!
//! - [`device`]: the [`device::Device`] trait and its backends (`fake`, `replay`, `hid`,
//!   `openhaptics`, `dhd`).
//! - [`servo`]: the deterministic servo core ([`servo::ServoCore`], no I/O, no clock), its
//!   safety stages, and the thin real-time driver thread around it.
//! - [`telemetry`]: HDR histograms of period and tick cost, counters, session recording.
//! - [`transport`]: the UDP (TLS-over-TCP control + MAC'd datagrams) and QUIC transports.
//! - [`client`], [`clock`]: re-exported from the `haptics-client` crate (the workstation side of
//!   the handshake and hot path; the workstation depends on that crate alone).
//! - [`server`]: [`server::Server::start`] wires a device, the servo thread and a transport;
//!   tests start servers in-process with it.
//! - [`config`]: the TOML configuration, validated with field names in every error.
//! - [`setup`]: config → devices, certificates, servo and network settings.
//! - [`tls`]: self-signed certificates (`gen-cert`) and the pinned-certificate verifier.
//! - [`inventory`]: `devices`: what is attached, which backend drives it, why it cannot open.
//! - [`check`]: `check`: the guided self-test of a new installation (stylus, force axes,
//!   safety stages, workspace and scene transform).

pub use haptics_client::{client, clock};
pub mod check;
pub mod config;
pub mod device;
pub mod inventory;
pub mod loop_bench;
pub mod server;
pub mod servo;
pub mod setup;
pub mod telemetry;
pub mod tls;
pub mod transport;
