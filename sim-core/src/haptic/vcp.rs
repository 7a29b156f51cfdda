//! The virtual contact point: where the ray from the tool tip along the normal meets `f = 0`.
//!
//! Bracketing by doubling steps from a first-order guess, then Illinois regula falsi (the
//! field along a ray through a trilinear grid is a piecewise cubic, so it converges in a few
//! steps); it stops when `|f| ≤ ‖∇f‖·ROOT_TOLERANCE_M` or the bracket is that short. Both
//! loops are capped; if no sign change is found within `max_search` (or the ray
//! leaves the grid) the first-order distance `|f| / ‖∇f‖` is returned as a documented fallback.

use glam::DVec3;

use crate::grid::ScalarGrid;

/// At most this many step doublings while bracketing.
pub const MAX_BRACKET_STEPS: u32 = 12;
/// At most this many regula falsi iterations.
pub const MAX_ROOT_ITERATIONS: u32 = 40;
/// The root is accepted when the bracket is shorter than this, m.
pub const ROOT_TOLERANCE_M: f64 = 1e-9;

/// How the distance along the ray was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RootStatus {
    /// A sign change was bracketed and refined in this many iterations.
    Bracketed {
        /// Regula falsi iterations used.
        iterations: u32,
    },
    /// No sign change within reach: the first-order estimate `|f| / ‖∇f‖` (capped) was used.
    Fallback,
}

/// Trilinear value only (the gradient is not needed along the ray): the same interpolant as
/// [`ScalarGrid::sample`]'s value, at an eighth of the memory reads.
#[inline]
pub fn value_at(grid: &ScalarGrid, x: DVec3) -> Option<f64> {
    let spec = grid.spec();
    let ([i, j, k], t) = spec.locate(x)?;
    let v = grid.values();
    let at = |di: usize, dj: usize, dk: usize| v[spec.index(i + di, j + dj, k + dk)];
    let lerp = |a: f64, b: f64, s: f64| a + (b - a) * s;
    let x00 = lerp(at(0, 0, 0), at(1, 0, 0), t.x);
    let x10 = lerp(at(0, 1, 0), at(1, 1, 0), t.x);
    let x01 = lerp(at(0, 0, 1), at(1, 0, 1), t.x);
    let x11 = lerp(at(0, 1, 1), at(1, 1, 1), t.x);
    Some(lerp(lerp(x00, x10, t.y), lerp(x01, x11, t.y), t.z))
}

/// Distance `t ≥ 0` along the unit `dir` from `x` (where the field is `f0 ≠ 0` with gradient
/// norm `grad_norm`) to the zero set, searching no farther than `max_search` m.
pub fn distance_to_zero(
    grid: &ScalarGrid,
    x: DVec3,
    dir: DVec3,
    f0: f64,
    grad_norm: f64,
    max_search: f64,
) -> (f64, RootStatus) {
    let guess = (f0.abs() / grad_norm).min(max_search);
    let fallback = (guess, RootStatus::Fallback);
    let step0 = (1.25 * guess)
        .max(0.25 * grid.spec().spacing)
        .min(max_search);
    let (mut t_lo, mut f_lo) = (0.0, f0);
    let mut t_hi = step0;
    let mut f_hi;
    let mut steps = 0;
    loop {
        let Some(f) = value_at(grid, x + t_hi * dir) else {
            return fallback;
        };
        f_hi = f;
        if f_hi == 0.0 {
            return (t_hi, RootStatus::Bracketed { iterations: 0 });
        }
        if (f_hi > 0.0) != (f0 > 0.0) {
            break;
        }
        steps += 1;
        if t_hi >= max_search || steps >= MAX_BRACKET_STEPS {
            return fallback;
        }
        (t_lo, f_lo) = (t_hi, f_hi);
        t_hi = (2.0 * t_hi).min(max_search);
    }
    // Illinois: regula falsi that halves the stale end's value so both ends converge.
    let mut side = 0i8;
    for iteration in 1..=MAX_ROOT_ITERATIONS {
        let t = (t_lo * f_hi - t_hi * f_lo) / (f_hi - f_lo);
        let t = if t.is_finite() && t > t_lo && t < t_hi {
            t
        } else {
            0.5 * (t_lo + t_hi)
        };
        let Some(f) = value_at(grid, x + t * dir) else {
            return fallback;
        };
        if f.abs() <= grad_norm * ROOT_TOLERANCE_M || t_hi - t_lo <= ROOT_TOLERANCE_M {
            return (
                t,
                RootStatus::Bracketed {
                    iterations: iteration,
                },
            );
        }
        if (f > 0.0) == (f_lo > 0.0) {
            (t_lo, f_lo) = (t, f);
            if side == -1 {
                f_hi *= 0.5;
            }
            side = -1;
        } else {
            (t_hi, f_hi) = (t, f);
            if side == 1 {
                f_lo *= 0.5;
            }
            side = 1;
        }
        if (t_hi - t_lo).abs() <= ROOT_TOLERANCE_M {
            return (
                0.5 * (t_lo + t_hi),
                RootStatus::Bracketed {
                    iterations: iteration,
                },
            );
        }
    }
    // Still bracketed after the cap: the bracket midpoint is within the bracket's width.
    (
        0.5 * (t_lo + t_hi),
        RootStatus::Bracketed {
            iterations: MAX_ROOT_ITERATIONS,
        },
    )
}
