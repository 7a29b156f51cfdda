//! The shaped probe of seed 004: an ellipsoid (or sphere) tool touching surface samples through
//! distributed springs.
//!
//! - [`Probe`]: the implicit ellipsoid `f_p(x) = ‖S⁻¹Rᵀ(x − c)‖² − 1` (negative inside), posed by
//!   the device's 6-DOF transform, semi-axes changeable at run time.
//! - [`SampleGrid`]: surface samples (position, outward unit normal, area) binned in a uniform
//!   grid so a query only tests samples in cells that overlap the probe's bounding box and
//!   bounding ball.
//! - [`ProbeRenderer`]: the force query. A sample strictly inside the probe is in contact; its
//!   depth `d_i` is the distance along its normal line to the *nearer* probe-surface crossing
//!   (analytic quadratic root). Magnitude `max(0, k_s Σ a_i d_i − b_s A (v·u))`, direction `u`
//!   the depth-and-area-weighted mean of the surface normals `N_i` ([`DirectionMethod::SurfaceNormal`])
//!   or of the inward probe normals at the samples ([`DirectionMethod::ProbeNormal`]). With
//!   [`MagnitudeMethod::VectorSum`] the springs add as vectors instead (continuous where the
//!   direction sum cancels).
//!
//! Units and signs: metres, newtons, seconds; `k_s` in N/m per m² of contact area (N/m³), `b_s`
//! in N·s/m per m²; sample normals point out of the sampled material; the force is the force *on
//! the probe* (what the user feels). Sample areas make the force independent of sampling density:
//! a plane sampled at spacing `h` with area `h²` per sample feels like the continuous integral.
//!
//! ```
//! use glam::{DQuat, DVec3};
//! use sim_core::probe::fixtures::sheet;
//! use sim_core::probe::*;
//!
//! let samples = sheet(0.05, 0.001); // a 10 cm plate, 1 mm samples, normal +z
//! let grid = SampleGrid::new(&samples, 0.004)?; // built once (re-bin with `update`)
//! let params = ContactParams {
//!     surface_stiffness: 2e6, // N/m per m²
//!     surface_damping: 50.0,  // N·s/m per m²
//!     method: DirectionMethod::SurfaceNormal,
//!     magnitude: MagnitudeMethod::SpringSum,
//! };
//! let mut renderer = ProbeRenderer::new(params, 0)?; // 0: force only, no contact list
//! let mut probe = Probe::ellipsoid(DVec3::new(0.015, 0.008, 0.008))?;
//! probe.set_pose(ProbePose { position: DVec3::new(0.0, 0.0, 0.006), orientation: DQuat::IDENTITY })?;
//! let f = renderer.query(&probe, &grid, DVec3::ZERO); // every haptic tick
//! assert!(f.force.z > 0.0 && f.contact_count > 0);
//! let command = f.output(probe.center(), 0.003, 0.02).to_command(7, 0); // to the server
//! # Ok::<(), ProbeError>(())
//! ```
//!
//! Contract: pure and deterministic (summation order is the grid's storage order); no
//! allocation per query — contacts are kept in scratch sized at construction; non-finite poses,
//! samples or velocities never produce non-finite forces (they give zero force or are skipped).

mod contact;
mod ellipsoid;
pub mod fixtures;
mod index;

pub use contact::{
    Contact, ContactParams, DirectionMethod, MagnitudeMethod, ProbeForce, ProbeRenderer,
};
pub use ellipsoid::{Probe, ProbePose, RayCrossing};
pub use index::{SampleGrid, SurfaceSample};

/// Tolerances of the probe queries, in one place.
pub mod tolerance {
    /// Smallest semi-axis accepted, m (below it the probe is numerically a point).
    pub const MIN_SEMI_AXIS_M: f64 = 1e-6;
    /// A direction sum shorter than this fraction of `Σ a_i d_i` is a cancellation: no direction,
    /// zero force (the probe-normal method at the instant its centre crosses a plane).
    pub const DIRECTION_CANCEL: f64 = 1e-9;
    /// Sample normals whose length differs from 1 by more than this are rejected when binning.
    pub const UNIT_NORMAL: f64 = 1e-6;
}

/// Why a probe or a sample set could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProbeError {
    /// A semi-axis is non-finite or smaller than [`tolerance::MIN_SEMI_AXIS_M`].
    #[error("semi-axes {0:?} must be finite and at least {min} m", min = tolerance::MIN_SEMI_AXIS_M)]
    BadSemiAxes([f64; 3]),
    /// The pose holds a non-finite number or a non-unit orientation.
    #[error("pose is non-finite or its orientation is not a unit quaternion")]
    BadPose,
    /// A contact parameter is negative or non-finite.
    #[error("contact parameter {name} = {value} must be finite and non-negative")]
    BadParameter {
        /// Which parameter.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// The sample grid's cell size is not a positive finite length.
    #[error("cell size {0} must be positive and finite")]
    BadCellSize(f64),
    /// A sample has a non-finite position, a non-unit normal or a negative or non-finite area.
    #[error("sample {index} is invalid (non-finite position, non-unit normal or bad area)")]
    BadSample {
        /// Index of the first bad sample.
        index: usize,
    },
    /// An update changed the number of samples; the grid's storage is fixed at construction.
    #[error("expected {expected} samples, got {got}")]
    SampleCountChanged {
        /// Samples at construction.
        expected: usize,
        /// Samples supplied.
        got: usize,
    },
}
