//! The global implicit field (papers' Eq. 5): local B-spline fields blended by compactly
//! supported weights, `f(x) = Σ sᵢ(x) φᵢ(x) / Σ φᵢ(x)`, with the nearest point's signed distance
//! where no support covers `x` (a field at every point, or at a thinned subset of them for a
//! static surface, [`FitParams::centre_spacing`], whose trust tests still consult every
//! point, plus fields centred in the gaps between them, [`FitParams::gap_fields`]); where the
//! covering fields come from the two opposite sides of
//! a thin solid or gap, the sides are blended apart and combined by max / min (see
//! [`GlobalField::value_and_gradient`]). Sign: `f < 0` inside, `f > 0` outside, `∇f` outward.
//!
//! Contract: a [`GlobalField`] is immutable and cheap to clone (one `Arc`), so a simulation can
//! hand snapshots to other threads. [`GlobalField::value_and_gradient`] costs O(supports at x),
//! allocates nothing and returns finite numbers for every finite `x`.

use std::sync::Arc;

use glam::DVec3;
use rayon::prelude::*;

use crate::bspline::{MAX_SIZE, RefitOperator, eval3, eval3_value};
use crate::gaps::GapSite;
use crate::knn::{KnnGraph, PointIndex};
use crate::local_fit::{FitParams, FitScratch, LocalFrame, Neighbourhood, fit_local};
use crate::outliers::flag_outliers;
use crate::spatial::{SupportGrid, SupportItem};

/// Progress sink for long constructions; `advance` is called from worker threads.
pub trait Progress: Sync {
    /// `n` more items are done.
    fn advance(&self, n: usize);
}

/// A progress sink that ignores reports.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoProgress;

impl Progress for NoProgress {
    fn advance(&self, _n: usize) {}
}

/// Why a field could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FieldError {
    /// There are no points.
    #[error("cannot fit an empty point set")]
    Empty,
    /// Points, normals and the k-NN graph disagree in length.
    #[error("{points} points but {normals} normals and a k-NN graph over {graph}")]
    Mismatch {
        /// Number of points.
        points: usize,
        /// Number of normals.
        normals: usize,
        /// Points in the graph.
        graph: usize,
    },
    /// A parameter is out of range.
    #[error("invalid fit parameter: {0}")]
    Param(&'static str),
    /// Every point was classified as an outlier.
    #[error("every point was rejected as an outlier")]
    AllOutliers,
}

/// The blended implicit surface of a point set.
#[derive(Clone)]
pub struct GlobalField {
    inner: Arc<FieldData>,
}

impl std::fmt::Debug for GlobalField {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GlobalField")
            .field("points", &self.len())
            .field("outliers", &self.outlier_count())
            .field("scale", &self.scale())
            .field("params", &self.inner.params)
            .finish_non_exhaustive()
    }
}

struct FieldData {
    params: FitParams,
    frames: Vec<LocalFrame>,
    /// Support radius per point; 0 for outliers.
    support: Vec<f64>,
    /// `size³` world-unit coefficients per point.
    coeffs: Vec<f64>,
    normals: Vec<DVec3>,
    /// Nearest-point fallback over inliers, and the map from its items to point indices.
    nearest: PointIndex,
    /// Slot of each kd-tree item.
    nearest_ids: Vec<u32>,
    /// Storage slot of each point: per-point data is kept in Morton (Z-curve) order so the
    /// fields a query blends sit close together in memory. [`NO_LOCAL`] for a point without a
    /// local field (appended after the fit); points past the end have none either.
    slot: Vec<u32>,
    /// Slots no point owns any more (their points were removed; the fields stay in the blend).
    orphans: Vec<u32>,
    /// Slots the fit made; those from here on were added by [`GlobalField::relocate_point`].
    fitted: usize,
    /// Gap fields ([`crate::gaps`]) fill slots `first_gap..fitted`.
    first_gap: usize,
    grid: SupportGrid,
    /// Every inlier point as a trust witness, where the local fields are thinned
    /// ([`FitParams::centre_spacing`]); `None`: the fields' own points are the witnesses.
    witnesses: Option<Witnesses>,
    refit: Arc<RefitOperator>,
    scale: f64,
    outliers: usize,
}

impl GlobalField {
    /// Fit every point's local field (on all cores) and index the supports.
    ///
    /// `normals` are unit and consistently oriented outward; `knn` lists each point's neighbours
    /// (its `k` is the neighbourhood size; `params.k` is not consulted here).
    pub fn build(
        points: &[DVec3],
        normals: &[DVec3],
        knn: &KnnGraph,
        params: &FitParams,
        progress: &dyn Progress,
    ) -> Result<Self, FieldError> {
        Self::build_with_index(points, normals, knn, None, params, progress)
    }

    /// [`GlobalField::build`] with the caller's k-d tree over `points` (the one `knn` was built
    /// with), which the gap fields' planning queries instead of building a second.
    pub fn build_indexed(
        points: &[DVec3],
        normals: &[DVec3],
        knn: &KnnGraph,
        index: &PointIndex,
        params: &FitParams,
        progress: &dyn Progress,
    ) -> Result<Self, FieldError> {
        if index.len() != points.len() {
            return Err(FieldError::Mismatch {
                points: points.len(),
                normals: normals.len(),
                graph: index.len(),
            });
        }
        Self::build_with_index(points, normals, knn, Some(index), params, progress)
    }

    fn build_with_index(
        points: &[DVec3],
        normals: &[DVec3],
        knn: &KnnGraph,
        index: Option<&PointIndex>,
        params: &FitParams,
        progress: &dyn Progress,
    ) -> Result<Self, FieldError> {
        validate(points, normals, knn, params)?;
        let n = points.len();
        let radii: Vec<f64> = (0..n).map(|i| knn.radius(i)).collect();
        let mut sorted: Vec<f64> = radii.iter().copied().filter(|r| *r > 0.0).collect();
        sorted.sort_by(f64::total_cmp);
        let typical = sorted.get(sorted.len() / 2).copied().unwrap_or(1.0);
        let outlier = flag_outliers(
            points,
            normals,
            knn,
            params.outlier_ratio,
            params.normal_agreement,
            typical,
        );
        // The points that get a local field (all of them unless thinned), in Morton order.
        let centres = thinned_centres(knn, &outlier, params.centre_spacing);
        let centre_points: Vec<DVec3> = centres.iter().map(|&i| points[i as usize]).collect();
        let order: Vec<u32> = morton_order(&centre_points)
            .into_iter()
            .map(|c| centres[c as usize])
            .collect();
        let mut slot = vec![NO_LOCAL; n];
        for (s, &i) in order.iter().enumerate() {
            slot[i as usize] = s as u32;
        }
        let n = order.len();
        let c = params.size.pow(3);
        let mut coeffs = vec![0.0; n * c];
        // Every slot's frame is written by its fit.
        let unfitted = LocalFrame {
            center: DVec3::ZERO,
            axes: [DVec3::X, DVec3::Y, DVec3::Z],
            half: 1.0,
        };
        let mut frames = vec![unfitted; n];
        const BLOCK: usize = 512;
        coeffs
            .par_chunks_mut(c * BLOCK)
            .zip(frames.par_chunks_mut(BLOCK))
            .enumerate()
            .for_each_init(
                || (FitScratch::new(params.size), Vec::new(), Vec::new()),
                |(scratch, hp, hn), (block, (cs, fs))| {
                    for (o, (coef, frame)) in cs.chunks_mut(c).zip(fs.iter_mut()).enumerate() {
                        let i = order[block * BLOCK + o] as usize;
                        hp.clear();
                        hn.clear();
                        for &j in knn.neighbours(i) {
                            if !outlier[j as usize] || j as usize == i {
                                hp.push(points[j as usize]);
                                hn.push(normals[j as usize]);
                            }
                        }
                        let hood = Neighbourhood {
                            center: points[i],
                            normal: normals[i],
                            points: hp,
                            normals: hn,
                            fallback_radius: typical,
                        };
                        *frame = fit_local(&hood, params, scratch, coef);
                    }
                    progress.advance(fs.len());
                },
            );
        // Gap fields follow the points' fields (a static surface's only: thinned).
        let sites = if params.gap_fields > 0.0 && params.centre_spacing > 0.0 {
            let own;
            let index = match index {
                Some(index) => index,
                None => {
                    own = PointIndex::new(points);
                    &own
                }
            };
            let sites = crate::gaps::plan(points, normals, knn, &outlier, &order, index, params);
            let first = frames.len();
            frames.resize(first + sites.len(), unfitted);
            coeffs.resize((first + sites.len()) * c, 0.0);
            fit_gap_fields(
                &sites,
                points,
                normals,
                &outlier,
                index,
                params,
                typical,
                &mut frames[first..],
                &mut coeffs[first * c..],
            );
            sites
        } else {
            Vec::new()
        };
        // Everything below is in slot order.
        let support: Vec<f64> = frames
            .iter()
            .enumerate()
            .map(|(s, f)| {
                if order.get(s).is_some_and(|&i| outlier[i as usize]) {
                    0.0
                } else {
                    params.support * f.half
                }
            })
            .collect();
        let inliers: Vec<u32> = (0..n as u32)
            .filter(|&s| support[s as usize] > 0.0)
            .collect();
        if inliers.is_empty() {
            return Err(FieldError::AllOutliers);
        }
        let inlier_points: Vec<DVec3> =
            inliers.iter().map(|&s| frames[s as usize].center).collect();
        let centers: Vec<DVec3> = frames.iter().map(|f| f.center).collect();
        // The length scale is the points' fields' (gap fields, fitted where points are sparse,
        // have wider supports and would move it, and with it the padding of mesh grids).
        let mut sup_sorted: Vec<f64> = support[..n].iter().copied().filter(|r| *r > 0.0).collect();
        sup_sorted.sort_by(f64::total_cmp);
        let scale = sup_sorted[sup_sorted.len() / 2];
        let grid = SupportGrid::new(&centers, &support, 2.0 * scale);
        let witnesses = (params.centre_spacing > 0.0).then(|| {
            let support: Vec<f64> = (0..points.len())
                .map(|i| {
                    let r = if radii[i] > 0.0 { radii[i] } else { typical };
                    if outlier[i] {
                        0.0
                    } else {
                        params.support * r * (1.0 + params.offset)
                    }
                })
                .collect();
            Witnesses {
                grid: SupportGrid::new(points, &support, 2.0 * scale),
                normals: normals.to_vec(),
                support,
            }
        });
        let refit = RefitOperator::new(params.size, params.size)
            .map_err(|_| FieldError::Param("size must be in 3..=6"))?;
        Ok(Self {
            inner: Arc::new(FieldData {
                params: *params,
                frames,
                support,
                coeffs,
                normals: order
                    .iter()
                    .map(|&i| normals[i as usize])
                    .chain(sites.iter().map(|g| g.normal))
                    .collect(),
                nearest: PointIndex::new(&inlier_points),
                nearest_ids: inliers,
                slot,
                orphans: Vec::new(),
                fitted: n + sites.len(),
                first_gap: n,
                grid,
                witnesses,
                refit: Arc::new(refit),
                scale,
                outliers: outlier.iter().filter(|o| **o).count(),
            }),
        })
    }

    /// `f(x)`.
    #[inline]
    pub fn value(&self, x: DVec3) -> f64 {
        self.value_and_gradient(x).0
    }

    /// `f(x)` and `∇f(x)`. Allocation-free; finite for finite `x`.
    ///
    /// The covering fields are blended in two groups, split by the sign of their normal's dot
    /// product with that of the most central covering support. When the groups face opposite ways (mean normals with a dot
    /// product below `normal_agreement`: the two sides of a thin solid, or of a thin gap, closer
    /// than the supports) averaging them would erase both sheets; instead each group is blended
    /// alone and the two are combined like a CSG of half-spaces: `max` (intersection) when the
    /// groups face away from each other (a thin solid), `min` (union) when they face each other
    /// (a gap). There f has a crease where the sides meet, and it can step where the split
    /// switches on (the groups' mean normals crossing the threshold); elsewhere it is the
    /// papers' C¹ blend.
    pub fn value_and_gradient(&self, x: DVec3) -> (f64, DVec3) {
        self.value_and_gradient_over::<true>(x, &self.inner.grid)
    }

    /// `f(x)` with the supports taken from a list gathered once for a box (see
    /// [`GlobalField::gather_supports`]): equal, bit for bit, to [`GlobalField::value`] for
    /// every `x` in that box, without the per-query index lookups or the gradient's cost.
    /// Block-wise grid sampling uses this.
    pub fn value_near(&self, x: DVec3, supports: &SupportList) -> f64 {
        self.value_and_gradient_over::<false>(x, supports).0
    }

    /// [`GlobalField::value_and_gradient`] with the supports taken from a list gathered for a
    /// box ([`GlobalField::gather_supports`]): equal, bit for bit, for every `x` in that box.
    pub fn value_and_gradient_near(&self, x: DVec3, supports: &SupportList) -> (f64, DVec3) {
        self.value_and_gradient_over::<true>(x, supports)
    }

    /// `f` and, with `GRAD`, `∇f` (else the gradient is meaningless where the blend defines f).
    fn value_and_gradient_over<const GRAD: bool>(
        &self,
        x: DVec3,
        supports: &impl Supports,
    ) -> (f64, DVec3) {
        let [a, b] = self.blend::<GRAD>(x, supports);
        let agreement = self.inner.params.normal_agreement;
        let opposed = a.sw > 0.0
            && b.sw > 0.0
            && a.normal.dot(b.normal) < agreement * a.normal.length() * b.normal.length();
        let result = if opposed {
            let (fa, fb) = (a.value(), b.value());
            let solid = (a.centre / a.sw - b.centre / b.sw).dot(a.normal) > 0.0;
            let pick_a = if solid { fa.0 >= fb.0 } else { fa.0 <= fb.0 };
            Some(if pick_a { fa } else { fb })
        } else {
            let all = Blend {
                sw: a.sw + b.sw,
                swf: a.swf + b.swf,
                gsw: a.gsw + b.gsw,
                gswf: a.gswf + b.gswf,
                ..Blend::default()
            };
            (all.sw > 1e-12).then(|| all.value())
        };
        match result {
            Some((f, g)) if f.is_finite() && g.is_finite() => (f, g),
            _ => self.nearest_signed_distance(x),
        }
    }

    /// Accumulate the blend at `x` over the supports containing it, in two groups split by the
    /// sign of each field's normal against the most central covering field's.
    #[inline]
    fn blend<const GRAD: bool>(&self, x: DVec3, supports: &impl Supports) -> [Blend; 2] {
        let d = &*self.inner;
        let size = d.params.size;
        let c = size * size * size;
        let mut groups = [Blend::default(); 2];
        // The split is relative to the normal of the most central covering support (largest
        // weight; ties to the lower index), so it does not depend on the storage order.
        // One scan finds the supports containing x (keeping up to HITS of them) and the most
        // central one; the blend then visits the kept ones (past HITS it scans again), in the
        // scan's order either way.
        let (mut best, mut n_ref) = ((f64::INFINITY, usize::MAX), DVec3::ZERO);
        let mut hits = [(0u32, 0.0f64); HITS];
        let mut count = 0usize;
        supports.for_each_containing(x, |i, _, dist2| {
            if count < HITS {
                hits[count] = (i as u32, dist2);
            }
            count += 1;
            let key = (dist2 / (d.support[i] * d.support[i]), i);
            if key.0 < best.0 || (key.0 == best.0 && key.1 < best.1) {
                (best, n_ref) = (key, d.frames[i].axes[2]);
            }
        });
        let mut visit = |i: usize, rel: DVec3, dist2: f64| {
            let r = d.support[i];
            let fr = &d.frames[i];
            let normal = fr.axes[2];
            let acc = &mut groups[usize::from(normal.dot(n_ref) < 0.0)];
            let dist = dist2.sqrt();
            let (phi, dphi) = weight(dist / r);
            let [u, v, w] = fr.to_local(x);
            acc.sw += phi;
            acc.centre += fr.center * phi;
            acc.normal += normal * phi;
            if !GRAD {
                acc.swf += phi * eval3_value(size, &d.coeffs[i * c..(i + 1) * c], u, v, w);
                return;
            }
            let gphi = if dist > 0.0 {
                rel * (dphi / (r * dist))
            } else {
                DVec3::ZERO
            };
            let (s, gq) = eval3(size, &d.coeffs[i * c..(i + 1) * c], u, v, w);
            let inv_edge = 0.5 / fr.half;
            let gs = (fr.axes[0] * gq[0] + fr.axes[1] * gq[1] + normal * gq[2]) * inv_edge;
            acc.swf += phi * s;
            acc.gsw += gphi;
            acc.gswf += gphi * s + gs * phi;
        };
        if count <= HITS {
            for &(i, dist2) in &hits[..count] {
                let i = i as usize;
                visit(i, x - d.frames[i].center, dist2);
            }
        } else {
            supports.for_each_containing(x, visit);
        }
        groups
    }

    /// Signed distance to the nearest inlier point, signed by its normal (the fallback where
    /// no support covers `x`).
    pub fn nearest_signed_distance(&self, x: DVec3) -> (f64, DVec3) {
        let d = &*self.inner;
        // The index measures squared distances, which overflow beyond ~1e154: search from x
        // pulled in along its ray instead (as far out, the nearest point is the same).
        // (The index must not see NaN or infinity either.)
        let q = DVec3::from_array(x.to_array().map(|c| {
            if c.is_nan() {
                0.0
            } else {
                c.clamp(-f64::MAX, f64::MAX)
            }
        }));
        let far = q.abs().max_element();
        let q = if far > FAR_QUERY {
            q * (FAR_QUERY / far)
        } else {
            q
        };
        let (item, _) = d.nearest.nearest(q);
        let i = d.nearest_ids[item] as usize;
        let rel = x - d.frames[i].center;
        let n = d.normals[i];
        // Scaled length: finite even where |rel|² overflows.
        let m = rel.abs().max_element();
        let side = if m > 0.0 && m.is_finite() {
            (rel / m).dot(n)
        } else {
            rel.dot(n)
        };
        let sign = if side < 0.0 { -1.0 } else { 1.0 };
        let len = if m > 0.0 && m.is_finite() {
            m * (rel / m).length()
        } else {
            m
        };
        if len > 0.0 && len.is_finite() {
            (sign * len, rel * (sign / len))
        } else if m > 0.0 && !rel.is_nan() {
            // |rel| overflows (x near ±f64::MAX, or infinite): the largest component is a
            // finite lower bound of the distance; 0 would claim that x lies on the surface.
            let dir = (rel / m).try_normalize().map_or(n, |d| d * sign);
            (sign * m.min(f64::MAX), dir)
        } else {
            (0.0, n)
        }
    }

    /// `true` when some local support contains `x` (the blend, not the fallback, defines f).
    pub fn is_covered(&self, x: DVec3) -> bool {
        let d = &*self.inner;
        let mut hit = false;
        d.grid.for_each_containing(x, |_, _, _| hit = true);
        hit
    }

    /// Whether the field is trusted at `x`, the test every consumer of the zero set applies
    /// (meshing, projection, region grids, CSG classification). Three conditions:
    /// - some point *vouches* for `x`: it lies within `trust ×` that point's support radius
    ///   ([`FitParams::trust`]);
    /// - the blending weight there, `Σ φᵢ(x)`, is at least [`FitParams::trust_weight`];
    /// - the vouching points do not disown it: less than three quarters of their weight comes
    ///   from points with `x` more than [`FitParams::trust_plane`] (0.2) support radii off
    ///   their tangent plane.
    ///
    /// Nearer the points the blend interpolates them; farther out the local fits extrapolate,
    /// and a zero set there is not evidence of a surface. Each condition removes one kind of
    /// spurious piece, measured on the benchmark shapes (docs/BENCHMARKS.md): the distance, the
    /// sheets where fits curl past the end of their data (the bunny's ears; 0.7 keeps randomly
    /// sampled shapes whole, 0.5 left gaps in a 20k-point torus, the sheet returns at 0.9);
    /// the weight, the fringe a few rim fields reach alone (a CSG rim's fits continuing over
    /// the carved-away void: three fields, `Σ φ` = 0.17 against ≈ 5 on a surface); the planes,
    /// fins that one-sided fits beside a crease bend into the void (3 mm off the planes of
    /// every point near them). A sampled surface passes all three: it lies within half a
    /// spacing of a sample and near its neighbours' planes. Allocation-free.
    pub fn is_trusted(&self, x: DVec3) -> bool {
        self.trust_at(x).0
    }

    /// [`GlobalField::is_trusted`] with the supports taken from a list gathered for a box
    /// ([`GlobalField::gather_supports`]): the same answer for every `x` in that box.
    pub fn is_trusted_near(&self, x: DVec3, supports: &SupportList) -> bool {
        self.trust_near(x, supports).0
    }

    /// Where `x` is trusted ([`GlobalField::is_trusted_near`]), the way the points vouching
    /// for it face: their normals' mean weighted by blending weight, Σ φᵢ nᵢ / Σ φᵢ, whose
    /// length says how well they agree (1: all alike). Meshing keeps a piece
    /// of zero set only where its outward direction agrees with that: a zero set facing
    /// against its points is the back of a bump or dent one noisy point's fit makes (a point a
    /// fraction of a spacing off its neighbours' surface, as scans have), a small inverted
    /// piece a cell or so beside the surface.
    pub fn trusted_facing_near(&self, x: DVec3, supports: &SupportList) -> Option<DVec3> {
        let (trusted, facing) = self.trust_near(x, supports);
        trusted.then_some(facing)
    }

    /// Whether a zero set whose outward direction is `outward` faces the way `facing` (from
    /// [`GlobalField::trusted_facing_near`]) says its points do; always, with
    /// [`FitParams::trust_facing`] off, and where the points disagree among themselves
    /// (`|facing|` below 0.8: the sides of a part thinner than the supports,
    /// a tail or a horn, whose normals point every way and say nothing about which way the
    /// zero set there should face).
    pub fn faces_its_points(&self, outward: DVec3, facing: DVec3) -> bool {
        !self.inner.params.trust_facing
            || facing.length() < FACING_AGREEMENT
            || outward.dot(facing) > FACING_LIMIT * outward.length() * facing.length()
    }

    /// [`GlobalField::trusted_facing_near`] with the supports from the index.
    pub fn trusted_facing(&self, x: DVec3) -> Option<DVec3> {
        let (trusted, facing) = self.trust_at(x);
        trusted.then_some(facing)
    }

    /// Visit every local field whose support contains `x`, with the supports from a list
    /// gathered for a box holding `x`: its point (a gap field's centre), unit normal, blending
    /// weight at `x` and support radius.
    pub fn for_each_support_near(
        &self,
        x: DVec3,
        supports: &SupportList,
        mut visit: impl FnMut(DVec3, DVec3, f64, f64),
    ) {
        let d = &*self.inner;
        supports.for_each_containing(x, |i, _, dist2| {
            let r = d.support[i];
            visit(
                d.frames[i].center,
                d.normals[i],
                weight(dist2.sqrt() / r).0,
                r,
            );
        });
    }

    /// Whether `x` is trusted, and the vouching points' mean normal weighted by their blending
    /// weights ([`GlobalField::trusted_facing_near`]), with the witnesses from the index.
    fn trust_at(&self, x: DVec3) -> (bool, DVec3) {
        let d = &*self.inner;
        match &d.witnesses {
            None => self.trust_by(x, &d.grid, &d.normals, &d.support),
            Some(w) => self.trust_by(x, &w.grid, &w.normals, &w.support),
        }
    }

    /// [`GlobalField::trust_at`] with the witnesses of a list gathered for a box.
    fn trust_near(&self, x: DVec3, list: &SupportList) -> (bool, DVec3) {
        let d = &*self.inner;
        match &d.witnesses {
            None => self.trust_by(x, list, &d.normals, &d.support),
            Some(w) => self.trust_by(x, &Items(&list.witnesses), &w.normals, &w.support),
        }
    }

    /// The trust test over `supports`, whose ids index `normals` and `support`.
    fn trust_by(
        &self,
        x: DVec3,
        supports: &impl Supports,
        normals: &[DVec3],
        support: &[f64],
    ) -> (bool, DVec3) {
        if !x.is_finite() {
            return (false, DVec3::ZERO);
        }
        let d = &*self.inner;
        let tau2 = d.params.trust * d.params.trust;
        let (mut weight_sum, mut vouching, mut off_plane) = (0.0, 0.0, 0.0);
        let mut facing = DVec3::ZERO;
        supports.for_each_containing(x, |i, rel, dist2| {
            let r2 = support[i] * support[i];
            let phi = weight((dist2 / r2).sqrt()).0;
            weight_sum += phi;
            if dist2 <= tau2 * r2 {
                // A point vouches for x; it disowns x lying far off its tangent plane.
                vouching += phi + f64::MIN_POSITIVE;
                facing += normals[i] * phi;
                if rel.dot(normals[i]).abs() > d.params.trust_plane * support[i] {
                    off_plane += phi + f64::MIN_POSITIVE;
                }
            }
        });
        let trusted = vouching > 0.0
            && weight_sum >= d.params.trust_weight
            && off_plane < OFF_PLANE_SHARE * vouching;
        (trusted, if trusted { facing / vouching } else { facing })
    }

    /// The value a sampled grid and an inside test should use: `f(x)` where it is trusted or
    /// agrees in sign with the nearest oriented point; otherwise the nearest point's signed
    /// distance ([`GlobalField::nearest_signed_distance`]). So the inside of a spurious sheet or
    /// blob beyond the trusted band is outside, while the deep interior of a solid (untrusted
    /// but on the points' inner side) keeps `f`.
    pub fn trusted_value(&self, x: DVec3) -> f64 {
        self.trusted_value_from(x, self.value(x))
    }

    /// [`GlobalField::trusted_value`] given `f = f(x)` already evaluated (e.g. by
    /// [`GlobalField::value_near`]).
    pub fn trusted_value_from(&self, x: DVec3, f: f64) -> f64 {
        if !x.is_finite() || self.is_trusted(x) {
            return f;
        }
        let (nsd, _) = self.nearest_signed_distance(x);
        if (nsd < 0.0) == (f < 0.0) { f } else { nsd }
    }

    /// Collect into `out` every support that reaches into the box `[lo, hi]` (for
    /// [`GlobalField::value_near`] at points of that box).
    pub fn gather_supports(&self, lo: DVec3, hi: DVec3, out: &mut SupportList) {
        let d = &*self.inner;
        d.grid.gather_box(lo, hi, &mut out.items);
        out.witnesses.clear();
        if let Some(w) = &d.witnesses {
            w.grid.gather_box(lo, hi, &mut out.witnesses);
        }
    }

    /// Every inlier's centre (and that of each field added since the fit), for callers that
    /// seed work on the trusted zero set (meshing's walk).
    pub fn centres(&self) -> impl Iterator<Item = DVec3> + '_ {
        let d = &*self.inner;
        d.nearest_ids
            .iter()
            .map(|&s| s as usize)
            .chain(d.fitted..d.frames.len())
            .map(move |s| d.frames[s].center)
    }

    /// The support ball of every inlier: (centre, support radius), gap fields and relocated
    /// fields ([`GlobalField::relocate_point`]) included.
    pub fn support_balls(&self) -> impl Iterator<Item = (DVec3, f64)> + '_ {
        let d = &*self.inner;
        d.nearest_ids
            .iter()
            .map(|&s| s as usize)
            .chain(d.first_gap..d.frames.len())
            .map(move |s| (d.frames[s].center, d.support[s]))
    }

    /// Number of local fields the fit made: one per point (outliers' empty slots included), or
    /// one per centre of a thinned field ([`FitParams::centre_spacing`]), so fewer than the
    /// points there, plus its gap fields ([`GlobalField::gap_field_count`]); relocated fields
    /// are not counted twice.
    pub fn len(&self) -> usize {
        self.inner.fitted
    }

    /// Number of gap fields ([`FitParams::gap_fields`]): local fields centred in the gaps
    /// between the points, not at a point (their slots follow the points' fields).
    pub fn gap_field_count(&self) -> usize {
        self.inner.fitted - self.inner.first_gap
    }

    /// Always `false`: a field has at least one point.
    pub fn is_empty(&self) -> bool {
        self.inner.frames.is_empty()
    }

    /// Points rejected as outliers (no local field, no support).
    pub fn outlier_count(&self) -> usize {
        self.inner.outliers
    }

    /// Median support radius: the field's length scale (tolerances are relative to it).
    pub fn scale(&self) -> f64 {
        self.inner.scale
    }

    /// The parameters the field was fitted with.
    pub fn params(&self) -> &FitParams {
        &self.inner.params
    }

    /// Storage slot of point `i`'s local field; `None` for a point without one.
    pub fn slot_of(&self, i: usize) -> Option<usize> {
        match self.inner.slot.get(i) {
            Some(&s) if s != NO_LOCAL => Some(s as usize),
            _ => None,
        }
    }

    /// Frame of point `i`'s local field (panics if it has none: see
    /// [`GlobalField::support_radius`]).
    pub fn frame(&self, i: usize) -> &LocalFrame {
        self.slot_frame(self.slot_of(i).expect("point has a local field"))
    }

    /// World-unit coefficients of point `i`'s local field (`size³`, flat index
    /// `(a·size+b)·size+c`).
    pub fn coefficients(&self, i: usize) -> &[f64] {
        self.slot_coefficients(self.slot_of(i).expect("point has a local field"))
    }

    /// Support radius of point `i`'s blending weight (0 for an outlier, or a point without a
    /// local field).
    pub fn support_radius(&self, i: usize) -> f64 {
        self.slot_of(i).map_or(0.0, |s| self.inner.support[s])
    }

    /// Frame of the local field in storage slot `s`.
    pub fn slot_frame(&self, s: usize) -> &LocalFrame {
        &self.inner.frames[s]
    }

    /// Coefficients of the local field in storage slot `s`.
    pub fn slot_coefficients(&self, s: usize) -> &[f64] {
        let c = self.inner.params.size.pow(3);
        &self.inner.coeffs[s * c..(s + 1) * c]
    }

    /// Support radius of the local field in storage slot `s`.
    pub fn slot_support(&self, s: usize) -> f64 {
        self.inner.support[s]
    }

    /// Slots of local fields whose points were removed ([`GlobalField::swap_remove_point`]):
    /// they still blend, so whoever refits the fields of a changed area refits these too.
    pub fn orphans(&self) -> &[u32] {
        &self.inner.orphans
    }

    /// The object's point `i` of `n` was removed by swap-remove (point `n − 1` now sits at
    /// `i`): keep the point → local field map in step. The removed point's local field stays in
    /// the blend as an orphan. O(1) unless the field is shared (copy-on-write).
    pub fn swap_remove_point(&mut self, i: usize, n: usize) {
        let data = Arc::make_mut(&mut self.inner);
        if data.slot.len() < n {
            data.slot.resize(n, NO_LOCAL);
        }
        if i >= data.slot.len() {
            return;
        }
        let gone = data.slot.swap_remove(i);
        if gone != NO_LOCAL && data.support[gone as usize] > 0.0 {
            data.orphans.push(gone);
        }
        // Trailing points without a field need no entry.
        while data.slot.last() == Some(&NO_LOCAL) {
            data.slot.pop();
        }
    }

    /// The precomputed refit operator (Eq. 4) for this field's spline size, on a grid of
    /// `size` samples per axis spanning each local domain.
    pub fn refit_operator(&self) -> &Arc<RefitOperator> {
        &self.inner.refit
    }

    /// World positions of local field `i`'s refit grid nodes, in the order
    /// [`RefitOperator::apply`] expects its samples.
    pub fn refit_nodes(&self, i: usize) -> impl Iterator<Item = DVec3> + '_ {
        let op = &self.inner.refit;
        let s = op.samples();
        let frame = self.frame(i);
        (0..s * s * s)
            .map(move |flat| frame.to_world(op.node(flat / (s * s), (flat / s) % s, flat % s)))
    }

    /// Replace local field `i`'s coefficients by the refit of `samples` (values at the refit
    /// grid nodes of its domain, see [`RefitOperator::node`] and [`LocalFrame::to_world`]).
    /// Copy-on-write: other snapshots are unaffected. A point without a field is skipped.
    pub fn refit_local(&mut self, i: usize, samples: &[f64]) {
        if let Some(s) = self.slot_of(i) {
            self.refit_slot(s, samples);
        }
    }

    /// Give point `i` a new local field on `frame` (its domain moved with the point, which a
    /// stroke carried away from where the old one was fitted), fitted to `samples` of the
    /// field wanted there at [`GlobalField::refit_nodes`]' positions for that frame (the
    /// [`RefitOperator`]'s nodes mapped by `frame`). The old field stays in the blend as an
    /// orphan (it still represents the field around where it is); the new one keeps the old
    /// support radius and takes `frame`'s third axis as its normal. Returns the new slot, or
    /// `None` (nothing changed) for a point without a local field, an outlier, or any point of
    /// a thinned field ([`FitParams::centre_spacing`]: a static surface). O(1)
    /// amortised, unless the field is shared (copy-on-write).
    pub fn relocate_point(
        &mut self,
        i: usize,
        frame: LocalFrame,
        samples: &[f64],
    ) -> Option<usize> {
        if self.inner.witnesses.is_some() {
            return None; // a thinned field is static (its witnesses would not follow)
        }
        let old = self.slot_of(i)?;
        let support = self.inner.support[old];
        if support.is_nan() || support <= 0.0 {
            return None;
        }
        let data = Arc::make_mut(&mut self.inner);
        let c = data.params.size.pow(3);
        let s = data.frames.len();
        data.frames.push(frame);
        data.support.push(support);
        data.normals.push(frame.axes[2]);
        data.coeffs.resize((s + 1) * c, 0.0);
        let refit = Arc::clone(&data.refit);
        refit.apply(samples, &mut data.coeffs[s * c..(s + 1) * c]);
        data.orphans.push(old as u32);
        data.slot[i] = s as u32;
        data.grid.insert(frame.center, support, s as u32);
        Some(s)
    }

    /// [`GlobalField::refit_local`] by storage slot.
    pub fn refit_slot(&mut self, s: usize, samples: &[f64]) {
        let data = Arc::make_mut(&mut self.inner);
        let c = data.params.size.pow(3);
        let refit = Arc::clone(&data.refit);
        refit.apply(samples, &mut data.coeffs[s * c..(s + 1) * c]);
    }
}

/// The slot of a point without a local field.
const NO_LOCAL: u32 = u32::MAX;

/// The points the trust tests ([`GlobalField::is_trusted`]) consult when the local fields sit
/// at a thinned subset of them: all inliers, each with its normal and about the support radius
/// its own field would have had (from its k-NN radius), so a thinned field trusts the places a
/// full one does (the thinned centres alone leave holes between them).
#[derive(Debug, Clone)]
struct Witnesses {
    grid: SupportGrid,
    normals: Vec<DVec3>,
    support: Vec<f64>,
}

/// Supports gathered for a box ([`GlobalField::gather_supports`]); reuse one per thread.
#[derive(Debug, Clone, Default)]
pub struct SupportList {
    items: Vec<SupportItem>,
    /// The trust witnesses reaching the box, where the field has them ([`Witnesses`]).
    witnesses: Vec<SupportItem>,
}

impl SupportList {
    /// An empty list.
    pub fn new() -> Self {
        Self::default()
    }

    /// Replace `out` by the supports of this list that reach into the smaller box `[lo, hi]`,
    /// in the same order (so blends over either list give the same bits inside that box).
    pub fn narrow_to(&self, lo: DVec3, hi: DVec3, out: &mut SupportList) {
        out.items.clear();
        out.items
            .extend(self.items.iter().filter(|item| item.reaches_box(lo, hi)));
        out.witnesses.clear();
        out.witnesses.extend(
            self.witnesses
                .iter()
                .filter(|item| item.reaches_box(lo, hi)),
        );
    }
}

/// Where a blend finds the supports containing a point.
pub(crate) trait Supports {
    /// Call `visit(i, x − cᵢ, |x − cᵢ|²)` for every support `i` containing `x` (`|x − cᵢ| < rᵢ`).
    fn for_each_containing(&self, x: DVec3, visit: impl FnMut(usize, DVec3, f64));
}

impl Supports for SupportGrid {
    #[inline]
    fn for_each_containing(&self, x: DVec3, visit: impl FnMut(usize, DVec3, f64)) {
        SupportGrid::for_each_containing(self, x, visit);
    }
}

impl Supports for SupportList {
    #[inline]
    fn for_each_containing(&self, x: DVec3, visit: impl FnMut(usize, DVec3, f64)) {
        Items(&self.items).for_each_containing(x, visit);
    }
}

/// Supports in a slice (a list's blend supports or its witnesses).
struct Items<'a>(&'a [SupportItem]);

impl Supports for Items<'_> {
    #[inline]
    fn for_each_containing(&self, x: DVec3, mut visit: impl FnMut(usize, DVec3, f64)) {
        for item in self.0 {
            let rel = x - item.center;
            let dist2 = rel.length_squared();
            if dist2 < item.radius2 {
                visit(item.id as usize, rel, dist2);
            }
        }
    }
}

/// The zero set is untrusted where points holding this share of the vouching weight disown it.
const OFF_PLANE_SHARE: f64 = 0.75;

/// The least agreement (length of the vouching points' weighted mean normal) at which the
/// facing test applies ([`GlobalField::faces_its_points`]). A smooth surface's points agree
/// to better than 0.95; on a shell thinner than the supports both sides vouch and they do not.
/// Measured on a 0.02-thick ellipsoid (the test
/// `a_shell_thinner_than_the_supports_keeps_its_facing_test_quiet`): applied at any agreement
/// (as it was) the test cut it into many pieces, at 0.5 into two; at 0.8 and 0.9 it is whole,
/// while 0.95 let a piece through on the CSG crease. The Stanford bunny scan's inverted bump
/// (agreement near 1) is left out at all of them.
const FACING_AGREEMENT: f64 = 0.8;

/// Supports a blend keeps from its one scan ([`GlobalField::blend`]); past this many it
/// scans again.
const HITS: usize = 64;

/// Cosine of the largest angle between a meshed zero set's outward direction and the way its
/// vouching points face ([`GlobalField::faces_its_points`]).
const FACING_LIMIT: f64 = -0.5;

/// Beyond this coordinate magnitude the nearest-point search runs from a point pulled in along
/// the query's ray (squared distances overflow past ~1e154).
const FAR_QUERY: f64 = 1e150;

/// The points that get a local field, ascending: every point when `spacing` is 0, else a
/// greedy pass in index order over the k-NN graph that skips a point where a centre already
/// lies within `spacing` × its neighbourhood radius, so every inlier is a centre or lies that
/// near one (outliers are left out: they would get no field anyway).
fn thinned_centres(knn: &KnnGraph, outlier: &[bool], spacing: f64) -> Vec<u32> {
    let n = knn.len();
    if spacing <= 0.0 {
        return (0..n as u32).collect();
    }
    let mut taken = vec![false; n];
    let mut centres = Vec::new();
    for i in 0..n {
        if outlier[i] {
            continue;
        }
        let reach = spacing * knn.radius(i);
        let covered = knn
            .neighbours(i)
            .iter()
            .zip(knn.distances(i))
            .any(|(&j, &d)| taken[j as usize] && d <= reach);
        if !covered {
            taken[i] = true;
            centres.push(i as u32);
        }
    }
    centres
}

/// Fit a local field at each gap site to the site's own `k` nearest inlier points, on all
/// cores, into `frames` and `coeffs` (one frame and `size³` coefficients per site, in order).
#[allow(clippy::too_many_arguments)]
fn fit_gap_fields(
    sites: &[GapSite],
    points: &[DVec3],
    normals: &[DVec3],
    outlier: &[bool],
    index: &PointIndex,
    params: &FitParams,
    typical: f64,
    frames: &mut [LocalFrame],
    coeffs: &mut [f64],
) {
    coeffs
        .par_chunks_mut(params.size.pow(3))
        .zip(frames.par_iter_mut())
        .zip(sites.par_iter())
        .for_each_init(
            || (FitScratch::new(params.size), Vec::new(), Vec::new()),
            |(scratch, hp, hn), ((coef, frame), site)| {
                hp.clear();
                hn.clear();
                for (j, _) in index.nearest_k(site.centre, params.k) {
                    if !outlier[j] {
                        hp.push(points[j]);
                        hn.push(normals[j]);
                    }
                }
                let hood = Neighbourhood {
                    center: site.centre,
                    normal: site.normal,
                    points: hp,
                    normals: hn,
                    fallback_radius: typical,
                };
                *frame = fit_local(&hood, params, scratch, coef);
            },
        );
}

/// Point indices sorted along a Morton (Z-order) curve over the bounding box.
fn morton_order(points: &[DVec3]) -> Vec<u32> {
    let (lo, hi) = crate::pointset::bounds(points).unwrap_or((DVec3::ZERO, DVec3::ONE));
    let scale = ((1u64 << 21) - 1) as f64 / (hi - lo).max_element().max(f64::MIN_POSITIVE);
    let spread = |v: f64| -> u64 {
        let mut x = (v.clamp(0.0, ((1u64 << 21) - 1) as f64)) as u64;
        x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
        x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
        x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
        x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
        (x | (x << 2)) & 0x1249_2492_4924_9249
    };
    let mut keyed: Vec<(u64, u32)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let q = (*p - lo) * scale;
            (
                spread(q.x) | (spread(q.y) << 1) | (spread(q.z) << 2),
                i as u32,
            )
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// Running sums of the blend of one group of fields at one point.
#[derive(Debug, Clone, Copy, Default)]
struct Blend {
    sw: f64,
    swf: f64,
    gsw: DVec3,
    gswf: DVec3,
    /// `Σ φᵢ cᵢ` and `Σ φᵢ nᵢ`: where the group's points are and which way they face.
    centre: DVec3,
    normal: DVec3,
}

impl Blend {
    /// `(f, ∇f)` of this group alone (`sw > 0`).
    fn value(&self) -> (f64, DVec3) {
        let f = self.swf / self.sw;
        (f, (self.gswf - self.gsw * f) / self.sw)
    }
}

impl Clone for FieldData {
    fn clone(&self) -> Self {
        let inlier_points: Vec<DVec3> = self
            .nearest_ids
            .iter()
            .map(|&i| self.frames[i as usize].center)
            .collect();
        Self {
            params: self.params,
            frames: self.frames.clone(),
            support: self.support.clone(),
            coeffs: self.coeffs.clone(),
            normals: self.normals.clone(),
            nearest: PointIndex::new(&inlier_points),
            nearest_ids: self.nearest_ids.clone(),
            slot: self.slot.clone(),
            orphans: self.orphans.clone(),
            fitted: self.fitted,
            first_gap: self.first_gap,
            grid: self.grid.clone(),
            witnesses: self.witnesses.clone(),
            refit: Arc::clone(&self.refit),
            scale: self.scale,
            outliers: self.outliers,
        }
    }
}

/// Blending weight: the centred quadratic B-spline of `1.5·t`, scaled to 1 at `t = 0`, with
/// support `t < 1`; returns `(φ, dφ/dt)`. C¹ and positive inside the support.
#[inline]
fn weight(t: f64) -> (f64, f64) {
    let s = 1.5 * t;
    if s < 0.5 {
        ((0.75 - s * s) / 0.75, -2.0 * s * 1.5 / 0.75)
    } else if s < 1.5 {
        let m = 1.5 - s;
        (0.5 * m * m / 0.75, -m * 1.5 / 0.75)
    } else {
        (0.0, 0.0)
    }
}

fn validate(
    points: &[DVec3],
    normals: &[DVec3],
    knn: &KnnGraph,
    p: &FitParams,
) -> Result<(), FieldError> {
    if points.is_empty() {
        return Err(FieldError::Empty);
    }
    if normals.len() != points.len() || knn.len() != points.len() {
        return Err(FieldError::Mismatch {
            points: points.len(),
            normals: normals.len(),
            graph: knn.len(),
        });
    }
    let checks = [
        (3..=MAX_SIZE).contains(&p.size),
        p.offset > 0.0 && p.offset < 1.0,
        p.weight_width > 0.0 && p.weight_width.is_finite(),
        p.normal_weight > 0.0 && p.normal_weight.is_finite(),
        p.regularization > 0.0 && p.regularization.is_finite(),
        p.support > 0.0 && p.support <= 1.0,
        p.normal_agreement.is_finite(),
        p.outlier_ratio > 1.0,
        p.trust > 0.0 && p.trust.is_finite(),
        p.trust_weight >= 0.0 && p.trust_weight.is_finite(),
        p.trust_plane > 0.0,
        (0.0..=1.0).contains(&p.centre_spacing),
        (0.0..1.0).contains(&p.gap_fields),
    ];
    const WHAT: [&str; 13] = [
        "size must be in 3..=6",
        "offset must be in (0, 1)",
        "weight_width must be positive",
        "normal_weight must be positive and finite",
        "regularization must be positive",
        "support must be in (0, 1]",
        "normal_agreement must be finite",
        "outlier_ratio must exceed 1",
        "trust must be positive and finite",
        "trust_weight must be finite and ≥ 0",
        "trust_plane must be positive (infinite: no plane test)",
        "centre_spacing must be in [0, 1]",
        "gap_fields must be in [0, 1)",
    ];
    match checks.iter().position(|ok| !ok) {
        Some(bad) => Err(FieldError::Param(WHAT[bad])),
        None => Ok(()),
    }
}
