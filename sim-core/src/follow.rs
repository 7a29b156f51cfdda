//! Points follow the simulated field (DESIGN §3, papers' Eq. 9), and local fields of moved
//! points are refitted with the precomputed operator.
//!
//! The sculpted surface is the zero set of `F(x) = f_base(x) + Δ(x)`: `f_base` is the point-set
//! field at the start of the stroke (exact, not grid-limited) and `Δ` the trilinear interpolant of
//! the grid displacements `u = d − d⁰`. Each step a point moves along the normal by
//! `ẋ = −Ḟ ∇F/‖∇F‖²` (`Ḟ` = trilinear `u̇`) and is then Newton-projected onto `F = 0`
//! (`x ← x − F ∇F/‖∇F‖²`, each step clamped to one grid spacing) so drift cannot accumulate.
//!
//! Contract: a point is visited only if it lies in the grid and some corner of its cell has a
//! non-zero displacement or velocity; every other point is left bit-for-bit unchanged. Results
//! are finite: a step with a non-finite or vanishing gradient is skipped. No allocation per call
//! beyond growth of the caller-owned `moved` list.

use glam::DVec3;

use crate::bspline::eval3;
use crate::dynamics::DynamicGrid;
use crate::field::GlobalField;

/// Settings of [`follow`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FollowOptions {
    /// Newton re-projection steps after the Eq. 9 move.
    pub newton_steps: u32,
}

impl Default for FollowOptions {
    fn default() -> Self {
        Self { newton_steps: 2 }
    }
}

/// What one [`follow`] call did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FollowReport {
    /// Points visited (in a cell with motion).
    pub visited: usize,
    /// Largest `|F|` left after re-projection (m, for a distance-like field).
    pub max_residual: f64,
    /// Largest distance a point moved.
    pub max_move: f64,
}

/// Trilinear displacement, its gradient and the trilinear velocity at `x`; `None` outside the
/// grid or where every corner of the cell is at rest.
pub fn displacement_at(model: &DynamicGrid, x: DVec3) -> Option<(f64, DVec3, f64)> {
    let spec = model.spec();
    let ([ci, cj, ck], t) = spec.locate(x)?;
    let (u, v) = (model.displacement(), model.velocity());
    let mut corner = [(0.0, 0.0); 8];
    let mut moving = false;
    for (c, slot) in corner.iter_mut().enumerate() {
        let g = spec.index(ci + (c & 1), cj + ((c >> 1) & 1), ck + ((c >> 2) & 1));
        if let Some(s) = model.slot(g) {
            *slot = (u[s], v[s]);
            moving |= u[s] != 0.0 || v[s] != 0.0;
        }
    }
    if !moving {
        return None;
    }
    let w = |a: f64, d: usize| if d == 0 { 1.0 - a } else { a };
    let dw = |d: usize| if d == 0 { -1.0 } else { 1.0 };
    let (mut val, mut grad, mut vel) = (0.0, DVec3::ZERO, 0.0);
    for (c, &(uc, vc)) in corner.iter().enumerate() {
        let (dx, dy, dz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
        let (wx, wy, wz) = (w(t.x, dx), w(t.y, dy), w(t.z, dz));
        val += wx * wy * wz * uc;
        vel += wx * wy * wz * vc;
        grad += uc * DVec3::new(dw(dx) * wy * wz, wx * dw(dy) * wz, wx * wy * dw(dz));
    }
    Some((val, grad / spec.spacing, vel))
}

/// `F` and `∇F` at `x` (`Δ` is 0 outside the grid or at rest).
pub fn sculpted_value(base: &GlobalField, model: &DynamicGrid, x: DVec3) -> (f64, DVec3) {
    let (f, g) = base.value_and_gradient(x);
    match displacement_at(model, x) {
        Some((d, dg, _)) => (f + d, g + dg),
        None => (f, g),
    }
}

/// Move every candidate point in a moving cell by Eq. 9 over `dt`, re-project it onto `F = 0`,
/// update its normal, and append its index to `moved` (once per stroke: already-listed points
/// are skipped via `is_moved`, which the caller sizes to the point count). `candidates` lists the
/// points worth checking (those inside the region), so cost scales with the region.
#[allow(clippy::too_many_arguments)]
pub fn follow(
    base: &GlobalField,
    model: &DynamicGrid,
    candidates: &[u32],
    points: &mut [DVec3],
    normals: &mut [DVec3],
    dt: f64,
    opts: &FollowOptions,
    moved: &mut Vec<u32>,
    is_moved: &mut [bool],
) -> FollowReport {
    let mut report = FollowReport::default();
    let h = model.spec().spacing;
    for &i in candidates {
        let i = i as usize;
        let x0 = points[i];
        let Some((_, _, fdot)) = displacement_at(model, x0) else {
            continue;
        };
        report.visited += 1;
        let mut x = x0;
        let (_, g) = sculpted_value(base, model, x);
        if let Some(step) = newton_step(-dt * fdot, g, h) {
            x += step;
        }
        let mut f = 0.0;
        for _ in 0..opts.newton_steps {
            let (fx, gx) = sculpted_value(base, model, x);
            f = fx;
            match newton_step(-fx, gx, h) {
                Some(step) => x += step,
                None => break,
            }
        }
        let (fx, gx) = sculpted_value(base, model, x);
        if fx.abs() <= f.abs() || opts.newton_steps == 0 {
            f = fx;
        }
        report.max_residual = report.max_residual.max(f.abs());
        report.max_move = report.max_move.max(x.distance(x0));
        points[i] = x;
        if let Some(n) = gx.try_normalize() {
            normals[i] = n;
        }
        if !is_moved[i] {
            is_moved[i] = true;
            moved.push(i as u32);
        }
    }
    report
}

/// `δ ∇F/‖∇F‖²` clamped to length `h`; `None` for a vanishing or non-finite gradient.
fn newton_step(delta: f64, g: DVec3, h: f64) -> Option<DVec3> {
    let g2 = g.length_squared();
    if !(g2 > 1e-24 && g2.is_finite() && delta.is_finite()) {
        return None;
    }
    let step = g * (delta / g2);
    let len = step.length();
    Some(if len > h { step * (h / len) } else { step })
}

/// Refit the local fields of `moved` points in `live` so they represent `F = f_base + Δ`:
/// sample the base local spline plus `Δ` at the operator's grid nodes of each point's domain
/// and apply the precomputed operator (papers' Eq. 4). `samples` is reusable scratch.
pub fn refit_moved(
    base: &GlobalField,
    live: &mut GlobalField,
    model: &DynamicGrid,
    moved: &[u32],
    samples: &mut Vec<f64>,
) {
    let op = std::sync::Arc::clone(base.refit_operator());
    let (size, n) = (op.size(), op.samples());
    samples.resize(n * n * n, 0.0);
    for &i in moved {
        let i = i as usize;
        if base.support_radius(i) == 0.0 {
            continue; // outlier: no local field
        }
        let frame = *base.frame(i);
        let coeffs = base.coefficients(i);
        for a in 0..n {
            for b in 0..n {
                for c in 0..n {
                    let q = op.node(a, b, c);
                    let (s, _) = eval3(size, coeffs, q[0], q[1], q[2]);
                    let d = displacement_at(model, frame.to_world(q)).map_or(0.0, |(d, _, _)| d);
                    samples[(a * n + b) * n + c] = s + d;
                }
            }
        }
        live.refit_local(i, samples);
    }
}
