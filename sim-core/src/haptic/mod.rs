//! Haptic queries for the workstation's force-mapping thread (DESIGN §5).
//!
//! Each query is a deterministic struct method taking an immutable snapshot (`&ScalarGrid`,
//! samples, a mesh) plus the cursor state and returning a [`HapticOutput`]: the force and the
//! local model the haptics server renders at its own 1 kHz. Nothing here locks, waits or
//! allocates per query.

pub mod local_model;

pub use local_model::{ContactModel, HapticOutput};
