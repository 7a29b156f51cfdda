//! The servo loop: a deterministic core ([`ServoCore`], [`safety`]) and a thin driver thread
//! ([`driver`]) with its real-time setup ([`rt`]) and, on UDP, the hot-path socket it drains
//! itself ([`hot_socket`]).

pub mod core;
pub mod driver;
pub mod hot_socket;
pub mod passivity;
pub mod rt;
pub mod safety;

pub use self::core::{ServoCore, ServoParams, SessionEvent, TickOutput};
pub use passivity::Passivity;
pub use safety::{Safety, SafetyParams, Stage};

#[cfg(test)]
mod tests;
