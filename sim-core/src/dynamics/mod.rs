//! The dynamic volumetric model (DESIGN §3): a mass-spring system on field values over the
//! sculpting region's narrow band, its integrators, and their measured stability limits.
//!
//! Contract: [`DynamicGrid`] is state, [`Stepper`] is scratch plus the scheme; a step allocates
//! nothing after warm-up and either completes or leaves the state bit-for-bit unchanged
//! (non-finite results are rolled back and reported). Readers on other threads get immutable
//! [`crate::grid::ScalarGrid`] snapshots from [`DynamicGrid::publish`].

// Per-node loops index several parallel arrays by slot; iterator zips would obscure them.
#![allow(clippy::needless_range_loop)]

pub mod cg;
pub mod integrators;
pub mod model;
mod springs;
pub mod stability;

pub use integrators::{Integrator, StepError, StepReport, Stepper};
pub use model::{DynamicGrid, NodeParams};

/// Why a dynamic model could not be built or edited.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DynamicsError {
    /// A node parameter is non-finite or out of range (mass ≤ 0 or a negative coefficient).
    #[error("invalid node parameters {0:?}: mass must be > 0, the others ≥ 0, all finite")]
    Params(NodeParams),
    /// The band half-width is NaN or negative.
    #[error("band half-width {0} must be ≥ 0")]
    Band(f64),
    /// No grid node lies within the band: the region does not meet the surface.
    #[error("no grid node lies within the band around the surface")]
    EmptyBand,
    /// A state vector does not have one entry per active node.
    #[error("state vectors must have {expected} entries (one per active node)")]
    StateLength {
        /// Number of active nodes.
        expected: usize,
    },
    /// A supplied state contains NaN or infinity.
    #[error("state contains a non-finite value")]
    NonFiniteState,
}
