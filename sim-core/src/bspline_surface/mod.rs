//! A bicubic B-spline surface with a mass-spring dual, sculpted by the shaped probe (seed 004 §4).
//!
//! - [`BicubicPatch`]: clamped uniform cubic B-spline patch on an `n×n` control net.
//! - [`DualMap`]: `M = A P Aᵀ`, `P = A⁻¹ M A⁻ᵀ` with `A[k][j] = N_j(k/(n−1))`, computed and
//!   inverted once.
//! - [`MassSpringMesh`]: the `n×n` mass points, symplectic Euler at the haptic rate.
//! - [`ProbeSculptor`]: the loop of seed 004 §4.2 — probe contacts on the mass points at 1 kHz,
//!   push/pull with the button, reaction force to the user, control net at the display rate.
//!
//! Units: metres, kilograms, seconds, newtons. Heavier meshes deform more locally under the same
//! tool because the disturbance spreads at the wave speed `h·√(k/m)`: tested by the width of
//! the bulge after the same press.

mod basis;
mod dual;
mod mass_spring;
mod patch;
mod sculpt;

pub use basis::{CubicBasis, collocation_matrix, cubic_basis, invert, mass_parameter};
pub use dual::DualMap;
pub use mass_spring::{MAX_SUBSTEPS, MassSpringMesh, MeshParams};
pub use patch::BicubicPatch;
pub use sculpt::{ProbeSculptor, SculptTick};

/// Why a surface, mesh or map could not be made or stepped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SurfaceError {
    /// The size per side is outside the supported range (4..=256 for patches).
    #[error("unsupported size {0} per side")]
    BadSize(usize),
    /// A buffer has the wrong number of points.
    #[error("expected {expected} points, got {got}")]
    WrongLength {
        /// Points required.
        expected: usize,
        /// Points supplied.
        got: usize,
    },
    /// A parameter or input is negative where it must not be, or non-finite.
    #[error("non-finite or out-of-range input")]
    NonFinite,
    /// The collocation matrix `A` is numerically singular.
    #[error("collocation matrix is singular")]
    Singular,
    /// A step produced a non-finite state; it was rolled back.
    #[error("integration diverged; step rolled back")]
    Diverged,
}
