//! Regular voxel grids: geometry ([`GridSpec`]) and immutable node values ([`ScalarGrid`]).
//!
//! Contract: node `(i, j, k)` sits at `origin + spacing·(i, j, k)`; values are stored x fastest,
//! then y, then z (`index = i + nx·(j + ny·k)`). A [`ScalarGrid`] is an immutable snapshot: the
//! simulation publishes new ones (share via `Arc`), the haptic thread reads them.
//! [`ScalarGrid::sample`] allocates nothing, never panics, and returns `None` outside the grid,
//! for non-finite queries, and for grids too small to interpolate (fewer than 2 nodes on an axis).
//!
//! Interpolation: the value is trilinear in the cell containing `x`; the gradient is the
//! trilinear blend of the central-difference gradients at the cell's 8 corners (one-sided
//! differences on the grid boundary), so it is continuous across cell faces.

use glam::DVec3;
use rayon::prelude::*;

/// Why a grid could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// The number of values does not match the node count of the spec.
    #[error("{got} values for a grid of {expected} nodes")]
    WrongLength {
        /// Node count of the spec.
        expected: usize,
        /// Number of values supplied.
        got: usize,
    },
    /// A node value is NaN or infinite.
    #[error("node {index} has the non-finite value {value}")]
    NonFinite {
        /// Flat index of the first bad node.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// The spacing is not a positive finite number, or the bounds are not finite.
    #[error("invalid grid geometry: {0}")]
    Geometry(&'static str),
}

/// Most nodes a grid may have: node indices are stored as `u32` (the dynamic model's slots).
pub const MAX_NODES: usize = u32::MAX as usize;

/// Axis-aligned regular grid geometry: node (i,j,k) sits at origin + spacing*(i,j,k).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridSpec {
    /// Position of node (0, 0, 0).
    pub origin: DVec3,
    /// Distance between neighbouring nodes (metres), > 0.
    pub spacing: f64,
    /// Node counts along x, y, z.
    pub dims: [usize; 3],
}

impl GridSpec {
    /// The smallest grid with this spacing whose nodes cover the box `[min, max]`
    /// (origin at `min`, at least 2 nodes per axis).
    ///
    /// # Panics
    /// If `spacing` is not positive and finite, the bounds are not finite, or the grid would have
    /// more than [`MAX_NODES`] nodes; see
    /// [`GridSpec::try_covering`] for the fallible form.
    pub fn covering(min: DVec3, max: DVec3, spacing: f64) -> Self {
        match Self::try_covering(min, max, spacing) {
            Ok(spec) => spec,
            Err(e) => panic!("GridSpec::covering: {e}"),
        }
    }

    /// Fallible [`GridSpec::covering`].
    pub fn try_covering(min: DVec3, max: DVec3, spacing: f64) -> Result<Self, GridError> {
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(GridError::Geometry("spacing must be positive and finite"));
        }
        if !(min.is_finite() && max.is_finite()) {
            return Err(GridError::Geometry("bounds must be finite"));
        }
        let extent = (max - min).max(DVec3::ZERO);
        // Tolerate round-off so an exact multiple of the spacing does not add a node.
        let n = |e: f64| (e / spacing - 1e-9).ceil().max(1.0) + 1.0;
        let dims = [n(extent.x), n(extent.y), n(extent.z)];
        // Counted in f64 first: the usize product (and `cells as usize + 1`) would overflow.
        if dims[0] * dims[1] * dims[2] > MAX_NODES as f64 {
            return Err(GridError::Geometry(
                "the box holds more than 2³² − 1 nodes at this spacing",
            ));
        }
        Ok(Self {
            origin: min,
            spacing,
            dims: dims.map(|d| d as usize),
        })
    }

    /// World position of node `(i, j, k)`.
    #[inline]
    pub fn node_position(&self, i: usize, j: usize, k: usize) -> DVec3 {
        self.origin + self.spacing * DVec3::new(i as f64, j as f64, k as f64)
    }

    /// Total number of nodes.
    #[inline]
    pub fn node_count(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Flat index of node `(i, j, k)` (x fastest).
    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// Node coordinates of a flat index.
    #[inline]
    pub fn coords(&self, index: usize) -> [usize; 3] {
        let i = index % self.dims[0];
        let r = index / self.dims[0];
        [i, r % self.dims[1], r / self.dims[1]]
    }

    /// The node coordinates `(first, last)`, inclusive, of the nodes in the box `[lo, hi]`
    /// rounded outward to whole cells and clamped to the grid (a box outside the grid yields
    /// the nearest face's nodes). Tools visit these to touch only what is within their reach.
    pub fn node_range(&self, lo: DVec3, hi: DVec3) -> ([usize; 3], [usize; 3]) {
        let idx = |x: DVec3, up: bool| -> [usize; 3] {
            let g = (x - self.origin) / self.spacing;
            std::array::from_fn(|a| {
                let v = if up { g[a].ceil() } else { g[a].floor() };
                v.clamp(0.0, (self.dims[a] - 1) as f64) as usize
            })
        };
        (idx(lo, false), idx(hi, true))
    }

    /// World position of the last node `(nx-1, ny-1, nz-1)`.
    pub fn max_corner(&self) -> DVec3 {
        self.node_position(
            self.dims[0].saturating_sub(1),
            self.dims[1].saturating_sub(1),
            self.dims[2].saturating_sub(1),
        )
    }

    /// Whether `x` lies in the closed box spanned by the nodes (false for non-finite `x`).
    #[inline]
    pub fn contains(&self, x: DVec3) -> bool {
        let hi = self.max_corner();
        x.cmpge(self.origin).all() && x.cmple(hi).all()
    }

    /// The cell containing `x` and the fractional position inside it, `None` outside or when an
    /// axis has fewer than 2 nodes.
    #[inline]
    pub fn locate(&self, x: DVec3) -> Option<([usize; 3], DVec3)> {
        if !self.contains(x) || self.dims.iter().any(|&n| n < 2) {
            return None;
        }
        let g = (x - self.origin) / self.spacing;
        let mut cell = [0usize; 3];
        let mut t = DVec3::ZERO;
        for a in 0..3 {
            let c = (g[a].floor() as usize).min(self.dims[a] - 2);
            cell[a] = c;
            t[a] = (g[a] - c as f64).clamp(0.0, 1.0);
        }
        Some((cell, t))
    }
}

/// Value and gradient at a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldSample {
    /// Interpolated field value.
    pub value: f64,
    /// Interpolated gradient (outward for our sign convention).
    pub gradient: DVec3,
}

/// Node values on a GridSpec; immutable snapshots of it are what the haptic thread reads (share via Arc).
#[derive(Debug, Clone)]
pub struct ScalarGrid {
    spec: GridSpec,
    values: Vec<f64>,
}

impl ScalarGrid {
    /// Evaluate `f` at every node (in parallel).
    pub fn from_fn(spec: GridSpec, f: impl Fn(DVec3) -> f64 + Sync) -> Self {
        let values = (0..spec.node_count())
            .into_par_iter()
            .map(|idx| {
                let [i, j, k] = spec.coords(idx);
                f(spec.node_position(i, j, k))
            })
            .collect();
        Self { spec, values }
    }

    /// Wrap node values (x fastest); rejects a wrong length and non-finite values.
    pub fn from_values(spec: GridSpec, values: Vec<f64>) -> Result<Self, GridError> {
        if values.len() != spec.node_count() {
            return Err(GridError::WrongLength {
                expected: spec.node_count(),
                got: values.len(),
            });
        }
        if let Some((index, &value)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(GridError::NonFinite { index, value });
        }
        Ok(Self { spec, values })
    }

    /// The grid geometry.
    #[inline]
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// Node values, x fastest.
    #[inline]
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// Mutable node values, for in-crate publishers that keep them finite.
    pub(crate) fn values_mut(&mut self) -> &mut [f64] {
        &mut self.values
    }

    /// Value at node `(i, j, k)`. Panics when out of range.
    #[inline]
    pub fn node(&self, i: usize, j: usize, k: usize) -> f64 {
        self.values[self.spec.index(i, j, k)]
    }

    /// Overwrite these node values with `src` (same length), reusing the allocation; for
    /// publishers that recycle snapshots. Non-finite values are rejected and nothing changes.
    pub fn copy_from(&mut self, src: &[f64]) -> Result<(), GridError> {
        if src.len() != self.values.len() {
            return Err(GridError::WrongLength {
                expected: self.values.len(),
                got: src.len(),
            });
        }
        if let Some((index, &value)) = src.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(GridError::NonFinite { index, value });
        }
        self.values.copy_from_slice(src);
        Ok(())
    }

    /// Trilinear value; gradient = trilinear blend of the central-difference gradients at the 8 corners of the cell containing x. None outside the grid. No allocation.
    pub fn sample(&self, x: DVec3) -> Option<FieldSample> {
        sample_slice(&self.spec, &self.values, x)
    }
}

/// [`ScalarGrid::sample`] over any value slice laid out by `spec` (the dynamic model uses it on
/// its live buffers). `None` outside, for non-finite `x`, or if `values` is too short.
pub fn sample_slice(spec: &GridSpec, values: &[f64], x: DVec3) -> Option<FieldSample> {
    if values.len() < spec.node_count() {
        return None;
    }
    let ([ci, cj, ck], t) = spec.locate(x)?;
    let mut value = 0.0;
    let mut gradient = DVec3::ZERO;
    for c in 0..8 {
        let (di, dj, dk) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
        let w = weight(t.x, di) * weight(t.y, dj) * weight(t.z, dk);
        let (i, j, k) = (ci + di, cj + dj, ck + dk);
        value += w * values[spec.index(i, j, k)];
        gradient += w * node_gradient(spec, values, i, j, k);
    }
    Some(FieldSample { value, gradient })
}

/// Central-difference gradient at node `(i, j, k)`, one-sided on the boundary.
#[inline]
pub fn node_gradient(spec: &GridSpec, values: &[f64], i: usize, j: usize, k: usize) -> DVec3 {
    let at = |i: usize, j: usize, k: usize| values[spec.index(i, j, k)];
    let diff = |lo: f64, hi: f64, steps: usize| (hi - lo) / (steps as f64 * spec.spacing);
    let axis = |n: usize, c: usize, get: &dyn Fn(usize) -> f64| -> f64 {
        let lo = c.saturating_sub(1);
        let hi = (c + 1).min(n - 1);
        if hi == lo {
            0.0
        } else {
            diff(get(lo), get(hi), hi - lo)
        }
    };
    let [nx, ny, nz] = spec.dims;
    DVec3::new(
        axis(nx, i, &|a| at(a, j, k)),
        axis(ny, j, &|a| at(i, a, k)),
        axis(nz, k, &|a| at(i, j, a)),
    )
}

#[inline]
fn weight(t: f64, d: usize) -> f64 {
    if d == 0 { 1.0 - t } else { t }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> GridSpec {
        GridSpec::covering(DVec3::splat(-1.0), DVec3::splat(1.0), 0.1)
    }

    #[test]
    fn covering_spans_the_box() {
        let s = spec();
        assert_eq!(s.dims, [21, 21, 21]);
        assert!((s.max_corner() - DVec3::ONE).abs().max_element() < 1e-12);
        assert!(s.contains(DVec3::ZERO) && s.contains(DVec3::ONE));
        assert!(!s.contains(DVec3::new(1.01, 0.0, 0.0)) && !s.contains(DVec3::NAN));
        assert!(GridSpec::try_covering(DVec3::ZERO, DVec3::ONE, 0.0).is_err());
        let thin = GridSpec::covering(DVec3::ZERO, DVec3::new(1.0, 0.0, 0.0), 0.5);
        assert_eq!(thin.dims, [3, 2, 2]);
    }

    #[test]
    fn index_round_trips() {
        let s = GridSpec {
            origin: DVec3::ZERO,
            spacing: 1.0,
            dims: [3, 4, 5],
        };
        for idx in 0..s.node_count() {
            let [i, j, k] = s.coords(idx);
            assert_eq!(s.index(i, j, k), idx);
        }
    }

    #[test]
    fn linear_fields_are_reproduced_exactly() {
        // Trilinear interpolation and central differences are exact for affine functions,
        // including one-sided differences on the boundary: tolerance is round-off only.
        let a = DVec3::new(0.3, -1.7, 2.2);
        let g = ScalarGrid::from_fn(spec(), |x| a.dot(x) + 0.5);
        for x in [
            DVec3::ZERO,
            DVec3::new(0.93, -0.41, 0.07),
            DVec3::splat(-1.0),
            DVec3::ONE,
        ] {
            let s = g.sample(x).unwrap();
            assert!((s.value - (a.dot(x) + 0.5)).abs() < 1e-12, "{x}");
            assert!((s.gradient - a).length() < 1e-10, "{x}");
        }
        assert!(g.sample(DVec3::splat(1.5)).is_none());
    }

    #[test]
    fn sphere_distance_is_close() {
        // h = 0.1; trilinear error of |x|-r is O(h²/r) away from the centre: allow h²/2/r.
        let g = ScalarGrid::from_fn(spec(), |x| x.length() - 0.5);
        let x = DVec3::new(0.31, 0.22, -0.3);
        let s = g.sample(x).unwrap();
        assert!((s.value - (x.length() - 0.5)).abs() < 0.01 / 0.5 / 2.0 * 1.01);
        assert!(s.gradient.normalize().dot(x.normalize()) > 0.99);
    }

    #[test]
    fn from_values_validates() {
        let s = GridSpec {
            origin: DVec3::ZERO,
            spacing: 1.0,
            dims: [2, 2, 2],
        };
        assert!(matches!(
            ScalarGrid::from_values(s, vec![0.0; 7]),
            Err(GridError::WrongLength {
                expected: 8,
                got: 7
            })
        ));
        let mut v = vec![0.0; 8];
        v[3] = f64::NAN;
        assert!(matches!(
            ScalarGrid::from_values(s, v),
            Err(GridError::NonFinite { index: 3, .. })
        ));
        let g = ScalarGrid::from_values(s, (0..8).map(f64::from).collect()).unwrap();
        assert_eq!(g.node(1, 1, 1), 7.0);
    }
}
