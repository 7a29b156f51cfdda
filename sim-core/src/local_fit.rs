//! Local fields (DESIGN §2): per point a frame, a cube domain enclosing its k neighbours and a
//! trivariate uniform B-spline fitted by weighted least squares to the neighbours and two
//! off-surface samples per neighbour.
//!
//! Contract: [`fit_local`] always returns finite coefficients. The normal equations are
//! regularised (Tikhonov, toward the planar field of the point's tangent plane) so coplanar,
//! collinear, duplicated or too few neighbours still give a defined fit whose coefficients are
//! bounded by the data and the domain size. Fitting allocates nothing: scratch lives in
//! [`FitScratch`], one per thread.

use glam::DVec3;

use crate::bspline::{MAX_SIZE, basis1, basis3, greville};
use crate::linalg::{cholesky_solve, cholesky_solve_fixed, tangent_frame};

/// Parameters of the local fits and the blend. Lengths are relative to each point's
/// neighbourhood radius `r` (distance to its farthest used neighbour), so fits are scale-free.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FitParams {
    /// Neighbours per point, the point itself included.
    pub k: usize,
    /// B-spline coefficients per axis (3..=6; the papers use 3).
    pub size: usize,
    /// Off-surface sample offset `ε`, as a fraction of `r`.
    pub offset: f64,
    /// Width `h` of the row weight `θ(d) = exp(−d²/h²)`, as a fraction of `r`.
    pub weight_width: f64,
    /// Weight of a neighbour's two off-surface rows (its normal) against its on-surface row
    /// (its position). 1: equal, the papers' fit. Lower trusts positions over normals, which
    /// suits normals averaged across edges, as a mesh's vertex normals are at a CAD part's
    /// creases and a coarse mesh's corners: such a normal bends a fit that follows it fully
    /// into a bulge beside the edge.
    #[serde(default = "default_normal_weight")]
    pub normal_weight: f64,
    /// Tikhonov weight toward the planar field, relative to the mean diagonal of the normal matrix.
    pub regularization: f64,
    /// Radius of the blending weight `φ`, as a fraction of the domain half-size (≤ 1 keeps the
    /// support inside the domain).
    pub support: f64,
    /// Neighbours whose normal has a dot product below this with the point's own are ignored
    /// (the other sheet of a thin shell, a flipped normal).
    pub normal_agreement: f64,
    /// A point whose `r` exceeds this multiple of its neighbours' median `r` (or 3× this
    /// multiple of the global median) is an outlier: it gets no local field and is nobody's
    /// neighbour. So is a point whose normal opposes three quarters of its neighbours'.
    pub outlier_ratio: f64,
    /// Where the zero set is trusted: within this fraction of its support radius of the nearest
    /// (inlier) point. Beyond it a local fit is extrapolating, and a zero set there is a
    /// spurious sheet or blob: meshing, projection, haptic grids and CSG classification ignore
    /// it (see [`crate::field::GlobalField::is_trusted`]).
    #[serde(default = "default_trust")]
    pub trust: f64,
    /// The least total blending weight `Σ φᵢ(x)` at which the zero set is trusted. A surface
    /// point is covered by some twenty supports (`Σ φ` ≈ 5 at k = 20, ≈ 2.5 on an open scan's
    /// rim); the fringe a few rim fields reach alone (a fit continuing past a crease over the
    /// void) has a fraction of one.
    #[serde(default = "default_trust_weight")]
    pub trust_weight: f64,
    /// A point disowns a zero-set point lying more than this many of its support radii off
    /// its tangent plane; where points holding three quarters of the vouching weight disown
    /// it, the zero set is not trusted (fins beside a crease). Infinite: no such test.
    #[serde(default = "default_trust_plane")]
    pub trust_plane: f64,
    /// Meshing keeps the zero set only where it faces the way the points vouching for it do
    /// (see [`crate::field::GlobalField::trusted_facing_near`]): the backs of bumps and dents
    /// single noisy points' fits make are left out. `false`: no such test.
    #[serde(default = "default_trust_facing")]
    pub trust_facing: bool,
    /// Local fields at a thinned subset of the points, for a static surface (meshing, not
    /// sculpting): a point gets its own field only where no point already given one lies within
    /// this fraction (0..=1) of its neighbourhood radius; every fit still uses its `k` nearest
    /// of all the points. Fewer fields cover each place, so the fits and every evaluation of the
    /// blend cost less; the trust tests still consult every point. Such a field is static
    /// ([`crate::field::GlobalField::relocate_point`] leaves it unchanged). 0: a field at every
    /// point (the papers' model, which sculpting needs: each point carries its own field).
    #[serde(default)]
    pub centre_spacing: f64,
    /// [`FitParams::centre_spacing`] where the surface is flat, for a thinned field only (a
    /// larger value, or 0 for the same): a point whose neighbours all face within 1.8° of it,
    /// lie within 0.5 % of its neighbourhood radius of its tangent plane and surround it (their
    /// mean offset along the plane under 0.2 of that radius) gets a field only where no centre
    /// lies within this fraction of its radius. A plane is any local fit's exact answer, so a
    /// flat face needs fewer fields than a curved one; a crease, a rim or a bend keeps the
    /// closer spacing. 0: the same spacing everywhere.
    #[serde(default)]
    pub flat_spacing: f64,
    /// Gap fields, for a thinned (static) field only ([`FitParams::centre_spacing`] > 0; with
    /// a field at every point this has no effect): where a centre's neighbours lean to one
    /// side (their mean offset along its tangent plane is at least this fraction of its
    /// neighbourhood radius) and a point lies across the gap on the other side, one more local
    /// field is fitted in the gap, at the place between them clearest of the points if no point
    /// lies within 0.4 radius of it, to that place's own `k` nearest points (see
    /// [`crate::gaps`]). The points' own fits would reach the gap from one side only, carrying
    /// that side's curvature across it. 0: none.
    #[serde(default)]
    pub gap_fields: f64,
    /// Smaller neighbourhoods where they suffice, for a thinned (static) field only: a point
    /// whose `k_even` nearest facing its way (itself included) surround it evenly, their mean
    /// offset along its tangent plane under [`FitParams::even_lean`] of their radius, fits to
    /// those alone, following the detail they sample more closely; otherwise to the fewest
    /// beyond that which do, or to `k`. A neighbour facing more than 90° away (a crease, a
    /// tube about a spacing thick) keeps `k`; one facing against it (a thin part's other
    /// sheet, which the fit leaves out) is skipped. The fit's domain and support shrink with
    /// the neighbourhood; outliers and the trust radius still come from all `k`. 0 (or ≥ `k`):
    /// every point uses `k`.
    #[serde(default)]
    pub k_even: usize,
    /// How far a neighbourhood's mean tangent offset may lean, relative to its radius, for
    /// [`FitParams::k_even`] to count it as surrounding the point.
    #[serde(default)]
    pub even_lean: f64,
    /// Blending weight by how well each fit follows its own points, for a thinned (static)
    /// field only: a local field's weight is scaled by `1 / (1 + (m / (misfit_width·half))²)`,
    /// where `m` is the RMS of its value at the points its fit used and `half` its domain's half
    /// edge, so a fit that cannot follow its points (two sheets meeting in a corner tighter than
    /// its domain) gives way to its neighbours' better ones; at `m = misfit_width·half` it has
    /// half its weight. On the bench's shapes the fits' median misfit is 0–2 % of `half`,
    /// their largest 2–4 %. 0: every field weighs the same.
    #[serde(default)]
    pub misfit_width: f64,
    /// Gap samples, for a thinned (static) field only ([`FitParams::centre_spacing`] > 0): in
    /// each gap among the points at least this fraction (in `(0, 1)`) of the nearest point's
    /// neighbourhood radius wide, one sample on the sphere APSS would fit there joins the points
    /// (see [`crate::gap_samples`]), so the fits around the gap follow the surface across it
    /// instead of carrying their own side's curvature over it; the points alone still decide
    /// where the zero set is trusted. The field's point indices past the given points' are the
    /// samples. 0: none.
    #[serde(default)]
    pub gap_samples: f64,
}

fn default_normal_weight() -> f64 {
    FitParams::default().normal_weight
}

fn default_trust_facing() -> bool {
    true
}

fn default_trust() -> f64 {
    FitParams::default().trust
}

fn default_trust_weight() -> f64 {
    FitParams::default().trust_weight
}

fn default_trust_plane() -> f64 {
    FitParams::default().trust_plane
}

impl Default for FitParams {
    fn default() -> Self {
        Self {
            k: 20,
            size: 3,
            offset: 0.1,
            weight_width: 0.7,
            normal_weight: 1.0,
            regularization: 1e-5,
            support: 1.0,
            normal_agreement: -0.5,
            outlier_ratio: 4.0,
            trust: 0.7,
            trust_weight: 1.0,
            trust_plane: 0.2,
            trust_facing: true,
            centre_spacing: 0.0,
            flat_spacing: 0.0,
            gap_fields: 0.0,
            k_even: 0,
            even_lean: 0.0,
            misfit_width: 0.0,
            gap_samples: 0.0,
        }
    }
}

impl FitParams {
    /// The wider spacing flat faces are thinned at ([`FitParams::flat_spacing`]), where it
    /// applies: for a thinned field ([`FitParams::centre_spacing`] > 0) with a flat spacing
    /// above the base one; `None` where every point keeps the base spacing.
    pub fn flat_thinning(&self) -> Option<f64> {
        (self.centre_spacing > 0.0 && self.flat_spacing > self.centre_spacing)
            .then_some(self.flat_spacing)
    }
}

/// Where a local field lives: centre, orthonormal axes (two tangents, then the normal) and the
/// half edge `half` of its cube domain. Local coordinates are `(x−c)·axisₖ/(2·half) + ½ ∈ [0,1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFrame {
    /// Centre of the domain (the point).
    pub center: DVec3,
    /// Tangent, tangent, outward normal.
    pub axes: [DVec3; 3],
    /// Half edge of the cube domain, in metres.
    pub half: f64,
}

impl LocalFrame {
    /// Local `(u,v,w)` of a world point (outside `[0,1]³` when outside the domain).
    #[inline]
    pub fn to_local(&self, x: DVec3) -> [f64; 3] {
        let d = x - self.center;
        let s = 0.5 / self.half;
        [
            d.dot(self.axes[0]) * s + 0.5,
            d.dot(self.axes[1]) * s + 0.5,
            d.dot(self.axes[2]) * s + 0.5,
        ]
    }

    /// World point of local `(u,v,w)`.
    #[inline]
    pub fn to_world(&self, q: [f64; 3]) -> DVec3 {
        let s = 2.0 * self.half;
        self.center
            + self.axes[0] * ((q[0] - 0.5) * s)
            + self.axes[1] * ((q[1] - 0.5) * s)
            + self.axes[2] * ((q[2] - 0.5) * s)
    }
}

/// Reusable per-thread scratch for [`fit_local`].
#[derive(Debug, Clone)]
pub struct FitScratch {
    /// The normal matrix of a spline other than 3×3×3, `c × c` for `c` coefficients.
    ata: Vec<f64>,
    /// The right-hand side, then the solution (any size).
    rhs: Vec<f64>,
    /// The 27×27 normal matrix of the common 3×3×3 spline, in fixed-size rows.
    dense: Box<[[f64; 27]; 27]>,
}

impl FitScratch {
    /// Scratch for splines of up to `size` coefficients per axis.
    pub fn new(size: usize) -> Self {
        let c = size.clamp(3, MAX_SIZE).pow(3);
        Self {
            ata: vec![0.0; c * c],
            rhs: vec![0.0; c],
            dense: Box::new([[0.0; 27]; 27]),
        }
    }
}

/// The neighbourhood of one point: its position and normal and the candidate neighbours.
#[derive(Debug, Clone, Copy)]
pub struct Neighbourhood<'a> {
    /// The point.
    pub center: DVec3,
    /// Its unit normal (the frame's third axis).
    pub normal: DVec3,
    /// Neighbour positions (the point itself may be among them).
    pub points: &'a [DVec3],
    /// Neighbour unit normals, matching `points`.
    pub normals: &'a [DVec3],
    /// Radius used when the neighbours span no distance (all duplicates, or alone).
    pub fallback_radius: f64,
}

/// Whether a local fit about `normal` uses a neighbour whose normal is `neighbour`: not the
/// other sheet of a thin part, facing against it (below [`FitParams::normal_agreement`]).
fn fit_uses(neighbour: DVec3, normal: DVec3, params: &FitParams) -> bool {
    neighbour.dot(normal) >= params.normal_agreement
}

/// How far a local field fitted by [`fit_local`] (its `frame` and `coeffs`) misses the points
/// of `hood` that its fit used: the RMS of its value there, in world units (0 with none).
pub fn fit_misfit(
    hood: &Neighbourhood<'_>,
    params: &FitParams,
    frame: &LocalFrame,
    coeffs: &[f64],
) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    // A plane's value is the offset along its normal (as the blend evaluates it).
    let planar = is_tangent_plane(params.size, frame, coeffs);
    for (p, n) in hood.points.iter().zip(hood.normals) {
        if fit_uses(*n, frame.axes[2], params) {
            let f = if planar {
                (*p - frame.center).dot(frame.axes[2])
            } else {
                let [u, v, w] = frame.to_local(*p);
                crate::bspline::eval3_value(params.size, coeffs, u, v, w)
            };
            sum += f * f;
            count += 1;
        }
    }
    (sum / count.max(1) as f64).sqrt()
}

/// Fit the local field of one point; writes `size³` world-unit coefficients into `coeffs` and
/// returns the frame. `hood.points.len()` ≤ 64 rows are expected; more are used but cost more.
pub fn fit_local(
    hood: &Neighbourhood<'_>,
    params: &FitParams,
    scratch: &mut FitScratch,
    coeffs: &mut [f64],
) -> LocalFrame {
    let size = params.size;
    let c = size * size * size;
    debug_assert_eq!(coeffs.len(), c);
    let normal = hood.normal.try_normalize().unwrap_or(DVec3::Z);
    let (t1, t2) = tangent_frame(normal);
    let mut r = 0.0f64;
    for (p, n) in hood.points.iter().zip(hood.normals) {
        if fit_uses(*n, normal, params) {
            r = r.max((*p - hood.center).length());
        }
    }
    if !(r > 0.0 && r.is_finite()) {
        r = hood.fallback_radius;
    }
    let eps = params.offset * r;
    let frame = LocalFrame {
        center: hood.center,
        axes: [t1, t2, normal],
        half: r + eps,
    };
    let inv_h2 = 1.0 / (params.weight_width * r).powi(2);
    // Each usable neighbour's three rows: the point itself, and ±ε along its normal.
    let rows = hood
        .points
        .iter()
        .zip(hood.normals)
        .filter(|(_, n)| fit_uses(**n, normal, params))
        .map(|(&p, &n)| {
            let theta = (-(p - hood.center).length_squared() * inv_h2).exp();
            let off = theta * params.normal_weight;
            [
                FitRow {
                    at: p,
                    target: 0.0,
                    weight: theta,
                },
                FitRow {
                    at: p + n * eps,
                    target: eps,
                    weight: off,
                },
                FitRow {
                    at: p - n * eps,
                    target: -eps,
                    weight: off,
                },
            ]
        });
    // A neighbourhood on the centre's tangent plane needs no solve: its answer is the plane.
    let solved = !on_tangent_plane(size, &frame, rows.clone(), params.regularization)
        && if size == 3 {
            let rhs: &mut [f64; 27] = (&mut scratch.rhs[..27])
                .try_into()
                .expect("27 coefficients");
            solve_tensor_3(&frame, rows, params.regularization, &mut scratch.dense, rhs)
        } else {
            let (ata, rhs) = (&mut scratch.ata[..c * c], &mut scratch.rhs[..c]);
            solve_general(size, &frame, rows, params.regularization, ata, rhs)
        };
    let offsets = &scratch.rhs[..c];
    let edge = 2.0 * frame.half;
    for a in 0..size {
        for b in 0..size {
            for cc in 0..size {
                let flat = (a * size + b) * size + cc;
                let delta = if solved { offsets[flat] } else { 0.0 };
                coeffs[flat] = coefficient(size, cc, delta, edge);
            }
        }
    }
    frame
}

/// How far the solve's answer may be from the plane for [`on_tangent_plane`] to skip it, in
/// the domain's edge lengths: far below rounding's reach in the mesh (the Newton projection
/// stops at 1e-6 of the field's length scale).
const PLANE_SKIP: f64 = 1e-9;

/// Whether every row lies so near the planar prior that the regularised solve's offsets are
/// certainly within [`PLANE_SKIP`] of zero, so [`fit_local`] may write the plane without
/// solving. The solve minimises `Σ θ·(B·x − r)² + λ·|x|²`, and `x = 0` costs `S = Σ θ·r²`, so
/// its answer has `λ·|x|² ≤ S`; and a value of the spline moves by at most `max |xᵢ| ≤ |x|`
/// edge lengths (its basis values are non-negative and sum to 1). So `S ≤ PLANE_SKIP²·λ`
/// bounds the difference everywhere in the domain. `λ` is taken at a lower bound of the
/// normal matrix's trace, `Σ θ / 27` (a row adds `θ·|b_u|²·|b_v|²·|b_w|²`, and three
/// non-negative values summing to 1 have squares summing to at least 1/3), which saves the
/// basis evaluations. A sampled plane (a CAD face in double precision) passes, with residuals
/// at rounding's level; a curved neighbourhood fails on its first row off the plane.
fn on_tangent_plane(
    size: usize,
    frame: &LocalFrame,
    rows: impl Iterator<Item = [FitRow; 3]>,
    regularization: f64,
) -> bool {
    let (mut cost, mut weight) = (0.0, 0.0);
    for row in rows.flatten() {
        let (_, residual) = row.local(frame);
        if residual.abs() > PLANE_SKIP {
            return false;
        }
        cost += row.weight * residual * residual;
        weight += row.weight;
    }
    cost <= PLANE_SKIP * PLANE_SKIP * tikhonov(regularization, weight / 27.0, size.pow(3))
}

/// Whether `coeffs` are exactly the tangent plane of `frame` that [`fit_local`] writes when
/// its offsets are zero (a skipped or failed solve, or a plane's exact answer): inside its
/// domain such a field's value is the signed distance along the frame's normal, which a blend
/// may evaluate without the spline.
pub fn is_tangent_plane(size: usize, frame: &LocalFrame, coeffs: &[f64]) -> bool {
    let edge = 2.0 * frame.half;
    coeffs.len() == size.pow(3)
        && coeffs.chunks_exact(size).all(|along_normal| {
            along_normal
                .iter()
                .enumerate()
                .all(|(cc, &x)| x == coefficient(size, cc, 0.0, edge))
        })
}

/// Coefficient `cc` along the normal of a field `offset` (normalised units) off its tangent
/// plane, in world units for a domain `edge` long: the one formula [`fit_local`] writes and
/// [`is_tangent_plane`] compares against bit for bit.
#[inline]
fn coefficient(size: usize, cc: usize, offset: f64, edge: f64) -> f64 {
    (greville(size, cc) - 0.5 + offset) * edge
}

/// One row of a local fit's least squares: the field's value at `at` should be `target`
/// (world units: the signed offset along the neighbour's normal), with weight `weight`.
#[derive(Debug, Clone, Copy)]
struct FitRow {
    at: DVec3,
    target: f64,
    weight: f64,
}

impl FitRow {
    /// The row's local coordinates and its residual against the planar prior `w − ½`
    /// (normalised units).
    #[inline]
    fn local(&self, frame: &LocalFrame) -> ([f64; 3], f64) {
        let q = frame.to_local(self.at);
        (q, self.target * (0.5 / frame.half) - (q[2] - 0.5))
    }
}

/// The Tikhonov weight λ added to the normal matrix's diagonal, relative to its mean `trace / c`.
#[inline]
fn tikhonov(regularization: f64, trace: f64, c: usize) -> f64 {
    regularization * trace / c as f64 + f64::MIN_POSITIVE
}

/// Solve the 3×3×3 spline's regularised normal equations for the coefficient offsets from the
/// planar field, into `rhs`; false if the matrix is not positive definite.
///
/// The normal matrix comes from its tensor structure. Entry ((a,b,c),(a',b',c')) is
/// Σ θ·Bₐ(u)Bₐ'(u)·B_b(v)B_b'(v)·B_c(w)B_c'(w): each axis's pair of basis functions is
/// unordered, so 6·6·6 sums carry all 27·27 entries, and a row adds the outer product of its
/// three axes' 6 pair products: 216 sums updated per neighbour (its three rows at once)
/// against the upper triangle's 378, in fixed-size rows. About a fifth less time per fit
/// (9.3–12.6 against 10.5–17.5 µs, interleaved in one process on a noisy VM); the same matrix
/// up to rounding (coefficients within 4e-12).
fn solve_tensor_3(
    frame: &LocalFrame,
    rows: impl Iterator<Item = [FitRow; 3]>,
    regularization: f64,
    dense: &mut [[f64; 27]; 27],
    rhs: &mut [f64; 27],
) -> bool {
    let mut pairs = [0.0f64; 216];
    rhs.fill(0.0);
    for neighbour in rows {
        // The neighbour's three rows' pair products, then one pass over the sums (each
        // loaded and stored once per neighbour, not once per row).
        let mut uv = [[0.0; 36]; 3];
        let mut pw = [[0.0; 6]; 3];
        for (k, row) in neighbour.iter().enumerate() {
            let ([u, v, w], residual) = row.local(frame);
            let (bu, bv, bw) = (basis1(3, u).value, basis1(3, v).value, basis1(3, w).value);
            let wr = row.weight * residual;
            for a in 0..3 {
                for b in 0..3 {
                    let ab = bu[a] * bv[b] * wr;
                    for cc in 0..3 {
                        rhs[(a * 3 + b) * 3 + cc] += ab * bw[cc];
                    }
                }
            }
            let (pu, pv) = (pair_products(bu), pair_products(bv));
            for (out, pu) in uv[k].chunks_exact_mut(6).zip(pu) {
                for (x, pv) in out.iter_mut().zip(pv) {
                    *x = pu * pv;
                }
            }
            pw[k] = pair_products(bw).map(|x| x * row.weight);
        }
        for (k, sums) in pairs.chunks_exact_mut(6).enumerate() {
            let (a0, a1, a2) = (uv[0][k], uv[1][k], uv[2][k]);
            for (cc, acc) in sums.iter_mut().enumerate() {
                *acc += a0 * pw[0][cc] + a1 * pw[1][cc] + a2 * pw[2][cc];
            }
        }
    }
    // The upper triangle, which the solve reads, from the pair sums.
    for ((row, from), a) in dense.iter_mut().zip(&PAIR_OF_ENTRY).zip(0..) {
        for (entry, &k) in row.iter_mut().zip(from).skip(a) {
            *entry = pairs[k as usize];
        }
    }
    let trace: f64 = (0..27).map(|a| dense[a][a]).sum();
    let lambda = tikhonov(regularization, trace, 27);
    (0..27).for_each(|a| dense[a][a] += lambda);
    cholesky_solve_fixed(dense, rhs)
}

/// [`solve_tensor_3`] for any other spline size: each row's 27 nonzero basis products added to
/// the upper triangle of the `c × c` normal matrix `ata` (`c = size³`).
fn solve_general(
    size: usize,
    frame: &LocalFrame,
    rows: impl Iterator<Item = [FitRow; 3]>,
    regularization: f64,
    ata: &mut [f64],
    rhs: &mut [f64],
) -> bool {
    let c = rhs.len();
    ata.fill(0.0);
    rhs.fill(0.0);
    let (mut vals, mut idx) = ([0.0; 27], [0usize; 27]);
    for row in rows.flatten() {
        let ([u, v, w], residual) = row.local(frame);
        basis3(size, u, v, w, &mut vals, &mut idx);
        for a in 0..27 {
            let wa = row.weight * vals[a];
            rhs[idx[a]] += wa * residual;
            let out = &mut ata[idx[a] * c..idx[a] * c + c];
            for b in a..27 {
                out[idx[b]] += wa * vals[b];
            }
        }
    }
    let trace: f64 = (0..c).map(|a| ata[a * c + a]).sum();
    let lambda = tikhonov(regularization, trace, c);
    (0..c).for_each(|a| ata[a * c + a] += lambda);
    cholesky_solve(ata, rhs, c)
}

/// Index of the unordered pair `{i, j}` of the three quadratic basis functions in
/// [`pair_products`].
const PAIR: [[usize; 3]; 3] = [[0, 1, 2], [1, 3, 4], [2, 4, 5]];

/// Where entry `(a, b)` of the 3×3×3 spline's normal matrix is summed in [`fit_local`]'s pair
/// sums: `(pair of u · 6 + pair of v) · 6 + pair of w`, the flat coefficient `(i·3 + j)·3 + k`
/// taking `i` along u, `j` along v, `k` along w.
const PAIR_OF_ENTRY: [[u8; 27]; 27] = {
    let mut table = [[0u8; 27]; 27];
    let mut a = 0;
    while a < 27 {
        let mut b = 0;
        while b < 27 {
            let (ia, ja, ka) = (a / 9, (a / 3) % 3, a % 3);
            let (ib, jb, kb) = (b / 9, (b / 3) % 3, b % 3);
            table[a][b] = ((PAIR[ia][ib] * 6 + PAIR[ja][jb]) * 6 + PAIR[ka][kb]) as u8;
            b += 1;
        }
        a += 1;
    }
    table
};

/// The products of the three basis values two at a time, `b₀b₀, b₀b₁, b₀b₂, b₁b₁, b₁b₂, b₂b₂`
/// (indexed by [`PAIR`]).
#[inline]
fn pair_products(b: [f64; 3]) -> [f64; 6] {
    [
        b[0] * b[0],
        b[0] * b[1],
        b[0] * b[2],
        b[1] * b[1],
        b[1] * b[2],
        b[2] * b[2],
    ]
}
