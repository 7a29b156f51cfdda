//! Jacobi-preconditioned conjugate gradient for the backward-Euler system of the model,
//! `(M + Δt C + Δt² K) x = b`, over the active slots.
//!
//! Contract: the operator is applied matrix-free from the model's parameter arrays (no matrix is
//! assembled); all vectors live in [`CgScratch`], sized once per model size, so a solve allocates
//! nothing after warm-up. The operator is symmetric positive definite whenever every mass is
//! positive, so CG converges; at the iteration cap the last iterate is returned with its residual.

use crate::dynamics::model::DynamicGrid;

/// Reusable vectors of the solver.
#[derive(Debug, Clone, Default)]
pub struct CgScratch {
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    ap: Vec<f64>,
    inv_diag: Vec<f64>,
}

/// Outcome of one solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CgOutcome {
    /// Iterations used.
    pub iterations: u32,
    /// Final `‖b − A x‖ / ‖b‖` (0 when `b = 0`).
    pub relative_residual: f64,
}

impl CgScratch {
    fn resize(&mut self, n: usize) {
        for v in [
            &mut self.r,
            &mut self.z,
            &mut self.p,
            &mut self.ap,
            &mut self.inv_diag,
        ] {
            v.resize(n, 0.0);
        }
    }
}

/// `y = (M + Δt C + Δt² K) x`.
pub(crate) fn apply_be(model: &DynamicGrid, dt: f64, x: &[f64], y: &mut [f64]) {
    let p = &model.params;
    let dt2 = dt * dt;
    for s in 0..x.len() {
        y[s] = (p.mass[s] + dt * p.damping[s]) * x[s] + dt2 * model.stiffness_apply(x, s);
    }
}

/// Solve `(M + Δt C + Δt² K) x = b` starting from the guess in `x`.
pub fn solve_be(
    model: &DynamicGrid,
    dt: f64,
    b: &[f64],
    x: &mut [f64],
    scratch: &mut CgScratch,
    tolerance: f64,
    max_iterations: u32,
) -> CgOutcome {
    let n = b.len();
    scratch.resize(n);
    let CgScratch {
        r,
        z,
        p,
        ap,
        inv_diag,
    } = scratch;
    let pa = &model.params;
    for s in 0..n {
        let d = pa.mass[s] + dt * pa.damping[s] + dt * dt * model.stiffness_diag(s);
        inv_diag[s] = 1.0 / d;
    }
    let b_norm = dot(b, b).sqrt();
    if b_norm == 0.0 {
        x.fill(0.0);
        return CgOutcome {
            iterations: 0,
            relative_residual: 0.0,
        };
    }
    apply_be(model, dt, x, ap);
    for s in 0..n {
        r[s] = b[s] - ap[s];
        z[s] = r[s] * inv_diag[s];
    }
    p.copy_from_slice(z);
    let mut rz = dot(r, z);
    // Residual norms below ABS_FLOOR are at the edge of subnormal arithmetic: count them as
    // converged (a model that far into its decay is at rest to every physical tolerance).
    const ABS_FLOOR: f64 = 1e-200;
    let rel_norm = |norm: f64| {
        if norm <= ABS_FLOOR {
            0.0
        } else {
            norm / b_norm
        }
    };
    let mut residual = rel_norm(dot(r, r).sqrt());
    let mut it = 0;
    while it < max_iterations && residual > tolerance {
        apply_be(model, dt, p, ap);
        let pap = dot(p, ap);
        if !(pap > 0.0 && pap.is_finite()) {
            break;
        }
        let alpha = rz / pap;
        // One fused pass: update x and r, precondition, and accumulate rᵀz and rᵀr.
        let (mut rz_new, mut rr) = (0.0, 0.0);
        for s in 0..n {
            x[s] += alpha * p[s];
            r[s] -= alpha * ap[s];
            z[s] = r[s] * inv_diag[s];
            rz_new += r[s] * z[s];
            rr += r[s] * r[s];
        }
        let beta = rz_new / rz;
        rz = rz_new;
        for s in 0..n {
            p[s] = z[s] + beta * p[s];
        }
        residual = rel_norm(rr.sqrt());
        it += 1;
    }
    CgOutcome {
        iterations: it,
        relative_residual: residual,
    }
}

#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
