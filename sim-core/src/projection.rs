//! Newton projection of a point onto the zero set of a [`GlobalField`]:
//! `x ← x − f ∇f / ‖∇f‖²`, with each step clamped to a fraction of the field's length scale.
//!
//! Contract: at most `max_iterations` field evaluations, no allocation, a finite result for any
//! finite start; when it does not converge the last iterate is returned with `converged: false`.
//! A non-finite start is returned unchanged with `converged: false`. Every result says whether
//! it is [`Projection::trusted`].

use glam::DVec3;

use crate::field::{GlobalField, SupportList};

/// Settings of [`project_to_zero_set_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProjectOptions {
    /// Iteration cap.
    pub max_iterations: u32,
    /// Stop when `|f| ≤ tolerance · field.scale()`.
    pub tolerance: f64,
    /// Largest step, as a multiple of `field.scale()`.
    pub max_step: f64,
}

impl Default for ProjectOptions {
    fn default() -> Self {
        Self {
            max_iterations: 40,
            tolerance: 1e-10,
            max_step: 0.5,
        }
    }
}

/// Result of a projection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    /// The projected point (last iterate if not converged).
    pub point: DVec3,
    /// `f` at `point`.
    pub value: f64,
    /// `∇f` at `point` (what a caller wanting the surface normal there would compute again).
    pub gradient: DVec3,
    /// Newton steps taken.
    pub iterations: u32,
    /// Whether `|f|` reached the tolerance.
    pub converged: bool,
    /// Whether the field is trusted at `point` ([`GlobalField::is_trusted`]): a converged
    /// projection that is not trusted landed on a spurious piece of the zero set, away from the
    /// data, and callers must not treat it as the surface.
    pub trusted: bool,
}

impl GlobalField {
    /// Project `x` onto `f = 0` with the default [`ProjectOptions`].
    pub fn project_to_zero_set(&self, x: DVec3) -> Projection {
        project_to_zero_set_with(self, x, &ProjectOptions::default())
    }
}

/// Project `x` onto `f = 0` with explicit options.
pub fn project_to_zero_set_with(field: &GlobalField, x: DVec3, opt: &ProjectOptions) -> Projection {
    project_over(
        field,
        x,
        opt,
        |p| field.value_and_gradient(p),
        |p| field.is_trusted(p),
    )
}

/// [`project_to_zero_set_with`] evaluating the field with `supports`, a list gathered for the
/// box `[lo, hi]` ([`GlobalField::gather_supports`]), while the iterate stays in that box, and
/// with the field's own index outside it: the same result, bit for bit, without the index
/// lookups where the projection is short (a mesh vertex moving within its cell).
pub fn project_to_zero_set_near(
    field: &GlobalField,
    x: DVec3,
    opt: &ProjectOptions,
    supports: &SupportList,
    bounds: (DVec3, DVec3),
) -> Projection {
    project_to_zero_set_near_from(field, x, opt, supports, bounds, false)
}

/// [`project_to_zero_set_near`] from a start `x` where the caller has already found the field
/// trusted (`trusted_at_x`, by the same test): a projection that ends where it started (no
/// step was needed) does not test it again. The same result, bit for bit.
pub fn project_to_zero_set_near_from(
    field: &GlobalField,
    x: DVec3,
    opt: &ProjectOptions,
    supports: &SupportList,
    (lo, hi): (DVec3, DVec3),
    trusted_at_x: bool,
) -> Projection {
    let inside = |p: DVec3| p.cmpge(lo).all() && p.cmple(hi).all();
    project_over(
        field,
        x,
        opt,
        |p| {
            if inside(p) {
                field.value_and_gradient_near(p, supports)
            } else {
                field.value_and_gradient(p)
            }
        },
        |p| {
            if trusted_at_x && p == x {
                true
            } else if inside(p) {
                field.is_trusted_near(p, supports)
            } else {
                field.is_trusted(p)
            }
        },
    )
}

/// Newton's iteration along the gradient with one backtracking halving per step, evaluating
/// with `eval` and judging the end point with `trusted`.
fn project_over(
    field: &GlobalField,
    x: DVec3,
    opt: &ProjectOptions,
    eval: impl Fn(DVec3) -> (f64, DVec3),
    trusted: impl Fn(DVec3) -> bool,
) -> Projection {
    let tol = opt.tolerance * field.scale();
    let max_step = opt.max_step * field.scale();
    let mut p = x;
    let (mut f, mut g) = eval(p);
    if !x.is_finite() {
        // No point of the zero set is nearer a NaN or infinite start than another.
        return Projection {
            point: x,
            value: f,
            gradient: g,
            iterations: 0,
            converged: false,
            trusted: false,
        };
    }
    for it in 0..opt.max_iterations {
        if f.abs() <= tol {
            return Projection {
                point: p,
                value: f,
                gradient: g,
                iterations: it,
                converged: true,
                trusted: trusted(p),
            };
        }
        let g2 = g.length_squared();
        if !(g2 > 0.0 && g2.is_finite()) {
            break;
        }
        let mut step = g * (f / g2);
        let len = step.length();
        if !len.is_finite() {
            // f/‖∇f‖² overflowed (|f| near f64::MAX, far from the surface): a full step along ∇f.
            step = g * (max_step.copysign(f) / g2.sqrt());
        } else if len > max_step {
            step *= max_step / len;
        }
        let q = p - step;
        let (fq, gq) = eval(q);
        // Backtrack once if the step overshot into a larger residual.
        if fq.abs() > f.abs() {
            let half = p - step * 0.5;
            let (fh, gh) = eval(half);
            if fh.abs() < fq.abs() {
                (p, f, g) = (half, fh, gh);
                continue;
            }
        }
        (p, f, g) = (q, fq, gq);
    }
    let converged = f.abs() <= tol;
    Projection {
        point: p,
        value: f,
        gradient: g,
        iterations: opt.max_iterations,
        converged,
        trusted: trusted(p),
    }
}
