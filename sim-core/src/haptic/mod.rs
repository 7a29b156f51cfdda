//! Haptic queries for the workstation's force-mapping thread (DESIGN §5).
//!
//! Each query is a deterministic struct method taking an immutable snapshot (`&ScalarGrid`,
//! samples, a mesh) plus the cursor state and returning a [`HapticOutput`]: the force and the
//! local model the haptics server renders at its own 1 kHz. Nothing here locks, waits or
//! allocates per query; non-finite inputs give zero force, never a non-finite one.
//!
//! - [`field_force`]: Kim-style contact with the field (VCP, damping, friction).
//! - [`reaction`]: what the user feels while a tool deforms material (Newton's third law), and
//!   the Hua–Qin field force-mapping as an alternative.
//! - [`local_model`]: the model in scene units and its one conversion to the wire.
//! - The shaped probe lives in [`crate::probe`]; it returns the same [`HapticOutput`].

pub mod field_force;
pub mod fixtures;
pub mod local_model;
pub mod reaction;
pub mod vcp;

pub use field_force::{FieldContact, FieldContactParams, FieldForce, FieldQuery};
pub use local_model::{ContactModel, HapticOutput};
pub use reaction::{
    ToolReaction, dynamic_stiffness, hua_qin_force, series_stiffness, value_forces_in_space,
};
pub use vcp::RootStatus;

/// Why a haptic renderer could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HapticError {
    /// A parameter is negative, zero where it must not be, or non-finite.
    #[error("parameter {name} = {value} is out of range")]
    BadParameter {
        /// Which parameter.
        name: &'static str,
        /// Its value.
        value: f64,
    },
}
