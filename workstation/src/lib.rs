//! `workstation`: the commands and threads around `sim-core`. [`live`] is the workstation
//! process itself (network, force-mapping, simulation and rendering threads), [`session`] the
//! commands that drive it (`run`, `demo`), [`view`] its window.
//!
//! Every subcommand of the `workstation` binary is a module here, so it can be tested
//! without spawning a process. Library code returns errors; only the binary prints them.

pub mod bench_force;
pub mod bench_sim;
pub mod bench_view;
pub mod bigscan;
#[cfg(feature = "demo-server")]
pub mod delay_study;
pub mod fit;
pub mod latency;
pub mod limits;
pub mod live;
pub mod logging;
pub mod plot;
pub mod relay;
pub mod scenes;
pub mod sculpt;
pub mod session;
pub mod share;
pub mod status;
pub mod view;
