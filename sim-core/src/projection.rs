//! Newton projection of a point onto the zero set of a [`GlobalField`]:
//! `x ← x − f ∇f / ‖∇f‖²`, with each step clamped to a fraction of the field's length scale.
//!
//! Contract: at most `max_iterations` field evaluations, no allocation, a finite result for any
//! finite start; when it does not converge the last iterate is returned with `converged: false`.
//! A non-finite start is returned unchanged with `converged: false`. Every result says whether
//! it is [`Projection::trusted`].

use glam::DVec3;

use crate::field::GlobalField;

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
    let tol = opt.tolerance * field.scale();
    let max_step = opt.max_step * field.scale();
    let mut p = x;
    let (mut f, mut g) = field.value_and_gradient(p);
    if !x.is_finite() {
        // No point of the zero set is nearer a NaN or infinite start than another.
        return Projection {
            point: x,
            value: f,
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
                iterations: it,
                converged: true,
                trusted: field.is_trusted(p),
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
        let (fq, gq) = field.value_and_gradient(q);
        // Backtrack once if the step overshot into a larger residual.
        if fq.abs() > f.abs() {
            let half = p - step * 0.5;
            let (fh, gh) = field.value_and_gradient(half);
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
        iterations: opt.max_iterations,
        converged,
        trusted: field.is_trusted(p),
    }
}
