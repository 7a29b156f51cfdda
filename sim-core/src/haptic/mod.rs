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
//!
//! One tick of a force-mapping thread (the grid is the simulation's latest `Arc` snapshot):
//!
//! ```
//! use std::sync::Arc;
//! use glam::DVec3;
//! use sim_core::grid::{GridSpec, ScalarGrid};
//! use sim_core::haptic::{FieldContactParams, FieldForce};
//!
//! let spec = GridSpec::covering(DVec3::splat(-0.03), DVec3::splat(0.03), 0.001);
//! let snapshot = Arc::new(ScalarGrid::from_fn(spec, |p| p.length() - 0.02)); // a 2 cm ball
//! let mut field_force = FieldForce::new(FieldContactParams {
//!     stiffness: 500.0,      // N/m
//!     damping: 1.0,          // N·s/m
//!     friction: 0.3,
//!     max_search: 0.02,      // m
//!     approach_margin: 0.002, // m: send the surface plane before contact
//!     validity_radius: 0.003, // m
//!     lifetime_s: 0.02,
//! })?;
//! let (cursor, velocity) = (DVec3::new(0.0, 0.0, 0.019), DVec3::ZERO); // 1 mm inside
//! let q = field_force.query(&snapshot, cursor, velocity);
//! assert!((q.output.force.z - 0.5).abs() < 0.01); // k × 1 mm, outward
//! let command = q.output.to_command(42, 0); // answers cursor sample 42; send it
//! assert_eq!(command.model.kind, protocol::ModelKind::Plane);
//! # Ok::<(), sim_core::haptic::HapticError>(())
//! ```

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
