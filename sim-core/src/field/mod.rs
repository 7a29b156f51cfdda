//! The global implicit field (papers' Eq. 5): local B-spline fields blended by compactly
//! supported weights, `f(x) = Σ sᵢ(x) φᵢ(x) / Σ φᵢ(x)`, with the nearest point's signed distance
//! where no support covers `x` (a field at every point, or at a thinned subset of them for a
//! static surface, [`FitParams::centre_spacing`], whose trust tests still consult every
//! point, plus fields centred in the gaps between them, [`FitParams::gap_fields`], and each
//! static field's weight scaled down by how far its fit misses its own points,
//! [`FitParams::misfit_width`]); where the covering fields come from the two opposite sides of
//! a thin solid or gap, the sides are blended apart and combined by max / min (which one
//! decided by the covering fields' votes, fixed at the fit), a side with a small share of the
//! weight keeping its veto only where its own tangent planes agree (see
//! [`GlobalField::value_and_gradient`]). Sign: `f < 0` inside, `f > 0` outside, `∇f` outward.
//!
//! Contract: a [`GlobalField`] is immutable and cheap to clone (one `Arc`), so a simulation can
//! hand snapshots to other threads. [`GlobalField::value_and_gradient`] costs O(supports at x),
//! allocates nothing and returns finite numbers for every finite `x`.
//!
//! Layout: `build` fits the fields, `blend` evaluates `f` and `∇f`, `trust` decides where the
//! zero set is trusted, `supports` finds the fields covering a point; this file holds the
//! field's data, its accessors and the edits a sculpting scene makes (refits, relocations).

mod blend;
mod build;
mod supports;
mod trust;

use std::sync::Arc;

use glam::DVec3;

use crate::bspline::RefitOperator;
use crate::knn::PointIndex;
use crate::local_fit::{FitParams, LocalFrame};
use crate::spatial::SupportGrid;

pub use supports::SupportList;

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
    /// The k-d tree given to [`GlobalField::build_indexed`] is over other points.
    #[error("{points} points but a k-d tree over {index}")]
    IndexMismatch {
        /// Number of points.
        points: usize,
        /// Points in the tree.
        index: usize,
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
    /// Per slot, whether the field's opposed neighbours make a thin solid (+1) or a thin gap
    /// (−1) with it ([`blend::vote`]); NaN where it has none. A relocated field gets its own
    /// vote; its neighbours' votes are not revisited.
    votes: Vec<f64>,
    /// Per slot, the factor on its blending weight for how well its fit follows its own points
    /// ([`FitParams::misfit_width`]); 1 for every slot without that option, and for relocated
    /// fields (a field with the option is static).
    misfit: Vec<f64>,
    /// Per slot, whether the field is exactly its frame's tangent plane
    /// ([`crate::local_fit::is_tangent_plane`]: a flat face's fit), which the blend evaluates
    /// as a signed distance instead of through the spline (the same value up to rounding).
    planar: Vec<bool>,
    /// Every inlier point as a trust witness, where the local fields are thinned
    /// ([`FitParams::centre_spacing`]); `None`: the fields' own points are the witnesses.
    witnesses: Option<Witnesses>,
    refit: Arc<RefitOperator>,
    scale: f64,
    outliers: usize,
    small_neighbourhoods: usize,
    /// Gap samples that joined the points ([`FitParams::gap_samples`]).
    gap_samples: usize,
}

impl GlobalField {
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

    /// Gap samples that joined the points ([`FitParams::gap_samples`]): they shape the fits and
    /// have fields where the thinning gives them one, but do not vouch for the zero set.
    pub fn gap_sample_count(&self) -> usize {
        self.inner.gap_samples
    }

    /// Points rejected as outliers (no local field, no support).
    pub fn outlier_count(&self) -> usize {
        self.inner.outliers
    }

    /// Points fitted to fewer than `k` neighbours, their nearest surrounding them evenly
    /// ([`FitParams::k_even`]).
    pub fn small_neighbourhood_count(&self) -> usize {
        self.inner.small_neighbourhoods
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
    /// amortised plus one support-grid lookup for its vote, unless the field is shared
    /// (copy-on-write).
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
        data.planar.push(false);
        data.orphans.push(old as u32);
        data.slot[i] = s as u32;
        data.grid.insert(frame.center, support, s as u32);
        let agreement = data.params.normal_agreement;
        let vote = blend::vote(&data.frames, &data.support, &data.grid, agreement, s);
        data.votes.push(vote);
        data.misfit.push(1.0);
        Some(s)
    }

    /// [`GlobalField::refit_local`] by storage slot.
    pub fn refit_slot(&mut self, s: usize, samples: &[f64]) {
        let data = Arc::make_mut(&mut self.inner);
        let c = data.params.size.pow(3);
        let refit = Arc::clone(&data.refit);
        refit.apply(samples, &mut data.coeffs[s * c..(s + 1) * c]);
        data.planar[s] = false;
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
            votes: self.votes.clone(),
            misfit: self.misfit.clone(),
            planar: self.planar.clone(),
            witnesses: self.witnesses.clone(),
            refit: Arc::clone(&self.refit),
            scale: self.scale,
            outliers: self.outliers,
            small_neighbourhoods: self.small_neighbourhoods,
            gap_samples: self.gap_samples,
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
