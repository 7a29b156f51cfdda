//! The servo loop: a deterministic core ([`ServoCore`], [`safety`]) and a thin driver thread
//! ([`driver`]) with its real-time setup ([`rt`]).

pub mod core;
pub mod driver;
pub mod passivity;
pub mod rt;
pub mod safety;

pub use self::core::{ServoCore, ServoParams, SessionEvent, TickOutput};
pub use passivity::Passivity;
pub use safety::{Safety, SafetyParams, Stage};

#[cfg(test)]
mod tests;
