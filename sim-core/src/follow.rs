//! Points follow the simulated field (DESIGN §3, papers' Eq. 9), and local fields of moved
//! points are refitted with the precomputed operator.
//!
//! The sculpted surface is the zero set of `F(x) = f_base(x) + Δ(x)`: `f_base` is the point-set
//! field at the start of the stroke (exact, not grid-limited) and `Δ` the trilinear interpolant of
//! the grid displacements `u = d − d⁰`. Each step a point moves along the normal by
//! `ẋ = −Ḟ ∇F/‖∇F‖²` (`Ḟ` = trilinear `u̇`) and is then Newton-projected onto `F = 0`
//! (`x ← x − F ∇F/‖∇F‖²`, each step clamped to one grid spacing) so drift cannot accumulate.
//!
//! Normals: a moved point's normal is its own normal at the stroke's start turned by the
//! sculpted change, `n = (n₀‖∇f_base‖ + ∇Δ) / ‖…‖`: while the stroke lasts with the trilinear
//! interpolant's `∇Δ` (free: it is part of `∇F`), and at the commit
//! ([`Follower::settle_normals`]) with the gradient of the grid displacements' tricubic
//! (Catmull-Rom) interpolant, continuous across cells, unlike the trilinear one's
//! ([`displacement_gradient_smooth`]; computed per moved point once, not per step: at 10⁶
//! points a rope moves ~10⁵ points a step). `∇F` itself would do in exact
//! arithmetic, but at a dense sampling the blended base field's gradient departs from the
//! sampled normals by several degrees in patches (on a dense sampling of a coarse mesh it leans
//! towards the mesh's flat facets), and the trilinear `∇Δ` jumps at every cell face: the
//! sculpted region then shaded in facets while the rest stayed smooth.
//!
//! Cost: `f_base` is expensive (a blend of B-splines), so each point keeps a first-order Taylor
//! model of it, `f_c + g_c·(x − x_c)`, refreshed (one exact evaluation) whenever the point has
//! moved more than `taylor_radius` from `x_c`; the model's error is at most
//! `½ ‖∇²f‖ taylor_radius²` (for a sphere of radius R, `taylor_radius² / 2R`).
//!
//! Contract: a point is visited only if it lies in the grid and the field near it changed since
//! it last moved (`|Δ(x) − Δ_seen| > ε` or `|Ḟ|·Δt > ε`, up to 2ε, see [`Follower`]); every other
//! point is left bit-for-bit unchanged. Results are finite: a step with a non-finite or
//! vanishing gradient is skipped. The [`Follower`] reuses its scratch; it allocates only when
//! it rebuckets (after a stroke, or once points drifted half a block).

use glam::DVec3;
use rayon::prelude::*;

use crate::bspline::eval3;
use crate::dynamics::DynamicGrid;
use crate::field::GlobalField;

mod follower;

pub use follower::Follower;

/// Settings of [`Follower::follow`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FollowOptions {
    /// Newton re-projection steps after the Eq. 9 move.
    pub newton_steps: u32,
    /// A point follows when the displacement at it changed by more than `ε` since it last did,
    /// or `|Ḟ|·Δt > ε` (m). Implicit solves spread exponentially small displacements over the
    /// whole band; below `ε` they are not worth moving points for (the error left is < `ε`).
    pub motion_epsilon: f64,
    /// Radius (m) within which the Taylor model of `f_base` is reused; 0 evaluates it exactly
    /// every time.
    pub taylor_radius: f64,
}

impl Default for FollowOptions {
    fn default() -> Self {
        Self {
            newton_steps: 1,
            motion_epsilon: 1e-8,
            taylor_radius: 5e-4,
        }
    }
}

/// What one [`Follower::follow`] call did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FollowReport {
    /// Points visited (in a cell with motion).
    pub visited: usize,
    /// Largest `|F|` left after re-projection (m, for a distance-like field).
    pub max_residual: f64,
    /// Largest distance a point moved.
    pub max_move: f64,
    /// Exact evaluations of `f_base` (Taylor-model refreshes).
    pub exact_evaluations: usize,
    /// Points currently stranded: left where they were because no zero set was within one grid
    /// spacing (the surface vanished under them, e.g. a thin shell pushed through itself). A
    /// point stays stranded until an update succeeds.
    pub stranded: usize,
}

/// Per-point cache: Taylor model of `f_base` and the displacement last followed.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PointCache {
    valid: bool,
    x: DVec3,
    f: f64,
    g: DVec3,
    seen: f64,
    /// The point's normal when the stroke first moved it (zero before that).
    start_normal: DVec3,
}

/// A computed point update, applied by the [`Follower`] unless the point is stranded.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PointUpdate {
    pub(crate) position: DVec3,
    pub(crate) normal: DVec3,
    pub(crate) residual: f64,
    pub(crate) exact: bool,
    pub(crate) cache: PointCache,
}

/// Trilinear displacement, its gradient and the trilinear velocity at `x`; `None` outside the
/// grid or where every corner of the cell is exactly at rest.
pub fn displacement_at(model: &DynamicGrid, x: DVec3) -> Option<(f64, DVec3, f64)> {
    displacement_above(model, x, 0.0, 0.0)
}

/// [`displacement_at`], `None` unless some corner has `|u| > eps` or `|u̇|·dt > eps`.
pub fn displacement_above(
    model: &DynamicGrid,
    x: DVec3,
    eps: f64,
    dt: f64,
) -> Option<(f64, DVec3, f64)> {
    let spec = model.spec();
    let ([ci, cj, ck], t) = spec.locate(x)?;
    let (u, v) = (model.displacement(), model.velocity());
    let mut corner = [(0.0, 0.0); 8];
    let mut moving = false;
    for (c, slot) in corner.iter_mut().enumerate() {
        let g = spec.index(ci + (c & 1), cj + ((c >> 1) & 1), ck + ((c >> 2) & 1));
        if let Some(s) = model.slot(g) {
            *slot = (u[s], v[s]);
            moving |= u[s].abs() > eps || (v[s] * dt).abs() > eps || (eps == 0.0 && v[s] != 0.0);
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

/// The displacement's gradient at `x`, continuous across cells: the gradient of the
/// Catmull-Rom (tricubic) interpolant of `u` over the 4×4×4 nodes around `x`'s cell (indices
/// clamped at the grid's faces; nodes outside the band count as at rest, as in
/// [`displacement_at`]). `None` outside the grid. What the points' normals are turned by (the
/// module doc): on a Gaussian bump of 1.5 slope sampled every 2/6 of its width, its error
/// is 0.06 against 0.41 for the trilinear interpolant's own gradient, which is constant along
/// each cell's axis and jumps at its faces.
pub fn displacement_gradient_smooth(model: &DynamicGrid, x: DVec3) -> Option<DVec3> {
    let spec = model.spec();
    let ([ci, cj, ck], t) = spec.locate(x)?;
    let u = model.displacement();
    // Catmull-Rom weights of the nodes at offsets −1, 0, 1, 2 and their derivatives in `t`.
    let weights = |t: f64| -> ([f64; 4], [f64; 4]) {
        let (t2, t3) = (t * t, t * t * t);
        (
            [
                0.5 * (-t3 + 2.0 * t2 - t),
                0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
                0.5 * (-3.0 * t3 + 4.0 * t2 + t),
                0.5 * (t3 - t2),
            ],
            [
                0.5 * (-3.0 * t2 + 4.0 * t - 1.0),
                0.5 * (9.0 * t2 - 10.0 * t),
                0.5 * (-9.0 * t2 + 8.0 * t + 1.0),
                0.5 * (3.0 * t2 - 2.0 * t),
            ],
        )
    };
    let (wx, dx) = weights(t.x);
    let (wy, dy) = weights(t.y);
    let (wz, dz) = weights(t.z);
    let node = |c: usize, o: usize, n: usize| (c + o).saturating_sub(1).min(n - 1);
    let mut grad = DVec3::ZERO;
    for c in 0..4 {
        let k = node(ck, c, spec.dims[2]);
        for b in 0..4 {
            let j = node(cj, b, spec.dims[1]);
            for a in 0..4 {
                let i = node(ci, a, spec.dims[0]);
                let Some(s) = model.slot(spec.index(i, j, k)) else {
                    continue;
                };
                let v = u[s];
                grad += v * DVec3::new(
                    dx[a] * wy[b] * wz[c],
                    wx[a] * dy[b] * wz[c],
                    wx[a] * wy[b] * dz[c],
                );
            }
        }
    }
    Some(grad / spec.spacing)
}

/// `F` and `∇F` at `x` (`Δ` is 0 outside the grid or at rest).
pub fn sculpted_value(base: &GlobalField, model: &DynamicGrid, x: DVec3) -> (f64, DVec3) {
    let (f, g) = base.value_and_gradient(x);
    match displacement_at(model, x) {
        Some((d, dg, _)) => (f + d, g + dg),
        None => (f, g),
    }
}

/// One point's update: `None` when the field near it has not changed. The Eq. 9 predictor uses
/// the stored unit normal (the field is distance-like, `‖∇F‖ ≈ 1`; Newton corrects the rest),
/// then `newton_steps` Newton steps on `F`, then one evaluation for the normal and residual.
/// The caller discards updates whose residual exceeds a grid spacing (stranded points).
/// The flag says whether `f_base` was evaluated exactly.
pub(crate) fn follow_point(
    base: &GlobalField,
    model: &DynamicGrid,
    mut cache: PointCache,
    x0: DVec3,
    n0: DVec3,
    dt: f64,
    opts: &FollowOptions,
) -> Option<PointUpdate> {
    let here = displacement_at(model, x0);
    let (d0, fdot) = here.map_or((0.0, 0.0), |(d, _, v)| (d, v));
    if here.is_none() && cache.seen == 0.0 {
        return None;
    }
    if (d0 - cache.seen).abs() <= opts.motion_epsilon && (fdot * dt).abs() <= opts.motion_epsilon {
        return None;
    }
    let h = model.spec().spacing;
    let mut exact = false;
    let mut eval = |x: DVec3| -> (f64, DVec3) {
        if !cache.valid || x.distance(cache.x) > opts.taylor_radius {
            let (f, g) = base.value_and_gradient(x);
            cache = PointCache {
                valid: true,
                x,
                f,
                g,
                ..cache
            };
            exact = true;
        }
        let fb = cache.f + cache.g.dot(x - cache.x);
        match displacement_at(model, x) {
            Some((d, dg, _)) => (fb + d, cache.g + dg),
            None => (fb, cache.g),
        }
    };
    let mut x = x0;
    if let Some(step) = newton_step(-dt * fdot, n0, h) {
        x += step;
    }
    for _ in 0..opts.newton_steps {
        let (fx, gx) = eval(x);
        match newton_step(-fx, gx, h) {
            Some(step) => x += step,
            None => break,
        }
    }
    let (f, g) = eval(x);
    cache.seen = displacement_at(model, x).map_or(0.0, |(d, _, _)| d);
    if cache.start_normal == DVec3::ZERO {
        cache.start_normal = n0;
    }
    // While the stroke lasts, turned by the trilinear gradient (`g` less the base's), which
    // costs nothing more; [`Follower::settle_normals`] turns by the smooth one at the commit.
    let normal = turned_normal(cache.start_normal, cache.g, g - cache.g).unwrap_or(n0);
    Some(PointUpdate {
        position: x,
        normal,
        residual: f.abs(),
        exact,
        cache,
    })
}

/// `start` (a point's unit normal when the stroke began) turned by the displacement's gradient
/// `dg`, with the base field's gradient `base` for the scale (the field is distance-like): in
/// the field's orientation, and back to the point's own (a normal that disagrees with the field
/// keeps its orientation). `None` when the result vanishes.
pub(crate) fn turned_normal(start: DVec3, base: DVec3, dg: DVec3) -> Option<DVec3> {
    let side = if start.dot(base) < 0.0 { -1.0 } else { 1.0 };
    (side * start * base.length() + dg)
        .try_normalize()
        .map(|n| side * n)
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
/// and apply the precomputed operator (papers' Eq. 4). Orphaned local fields (their points were
/// removed, see [`GlobalField::swap_remove_point`], or their fields moved,
/// [`GlobalField::relocate_point`]) centred inside the grid whose domains reach a displaced node
/// are refitted too.
/// `samples` is reusable scratch. [`refit_samples`] then [`apply_refit`].
pub fn refit_moved(
    base: &GlobalField,
    live: &mut GlobalField,
    model: &DynamicGrid,
    moved: &[u32],
    samples: &mut Vec<f64>,
) {
    let slots = refit_samples(base, model, moved, samples);
    apply_refit(live, &slots, samples);
}

/// The reading half of [`refit_moved`]: the storage slots to refit (sorted) and, in
/// `samples`, `n³` values of `F` per slot in that order. Reads only `base` and `model`, so the
/// caller may drop its handle on `base` before [`apply_refit`] (a field no other handle shares
/// is refitted in place instead of copied).
pub fn refit_samples(
    base: &GlobalField,
    model: &DynamicGrid,
    moved: &[u32],
    samples: &mut Vec<f64>,
) -> Vec<u32> {
    let op = std::sync::Arc::clone(base.refit_operator());
    let (size, n) = (op.size(), op.samples());
    let n3 = n * n * n;
    let spec = model.spec();
    // Orphans accumulate (removed points, fields that moved with their points): only those
    // whose domain reaches a displaced node are refitted, not every one inside the grid.
    let displaced = model.displaced_box(0.0);
    let reaches = |s: u32| {
        let f = base.slot_frame(s as usize);
        let r = DVec3::splat(f.half * 3f64.sqrt());
        spec.contains(f.center)
            && displaced.is_some_and(|(lo, hi)| {
                (f.center + r).cmpge(lo).all() && (f.center - r).cmple(hi).all()
            })
    };
    let mut slots: Vec<u32> = moved
        .iter()
        .filter_map(|&i| base.slot_of(i as usize))
        .filter(|&s| base.slot_support(s) > 0.0) // outliers have no local field
        .map(|s| s as u32)
        .chain(base.orphans().iter().copied().filter(|&s| reaches(s)))
        .collect();
    slots.sort_unstable();
    slots.dedup();
    samples.clear();
    samples.resize(slots.len() * n3, 0.0);
    samples
        .par_chunks_mut(n3)
        .zip(slots.par_iter())
        .with_min_len(16)
        .for_each(|(out, &s)| {
            let frame = *base.slot_frame(s as usize);
            let coeffs = base.slot_coefficients(s as usize);
            for a in 0..n {
                for b in 0..n {
                    for c in 0..n {
                        let q = op.node(a, b, c);
                        let (v, _) = eval3(size, coeffs, q[0], q[1], q[2]);
                        let d =
                            displacement_at(model, frame.to_world(q)).map_or(0.0, |(d, _, _)| d);
                        out[(a * n + b) * n + c] = v + d;
                    }
                }
            }
        });
    slots
}

/// The writing half of [`refit_moved`]: refit `slots` of `live` from `samples`.
pub fn apply_refit(live: &mut GlobalField, slots: &[u32], samples: &[f64]) {
    let n3 = samples.len().checked_div(slots.len()).unwrap_or(0);
    for (k, &s) in slots.iter().enumerate() {
        live.refit_slot(s as usize, &samples[k * n3..(k + 1) * n3]);
    }
}
