//! Surface samples binned in a uniform grid (counting sort, CSR layout) for probe queries.
//!
//! Storage is sized at construction: [`SampleGrid::update`] re-bins moved samples (a deforming
//! mesh) without allocating, growing the cell size if the samples spread beyond the cell budget.

use glam::DVec3;

use super::{ProbeError, tolerance};

/// A point on the touched surface: where it is, which way is out, how much area it stands for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceSample {
    /// Position, m.
    pub position: DVec3,
    /// Outward unit normal of the sampled surface.
    pub normal: DVec3,
    /// Surface area the sample represents, m² (its spring's share of the contact).
    pub area: f64,
}

impl SurfaceSample {
    fn is_valid(&self) -> bool {
        self.position.is_finite()
            && (self.normal.length() - 1.0).abs() <= tolerance::UNIT_NORMAL
            && self.area.is_finite()
            && self.area >= 0.0
    }
}

/// Surface samples sorted by uniform grid cell, for box queries.
#[derive(Debug, Clone)]
pub struct SampleGrid {
    samples: Vec<SurfaceSample>,
    original: Vec<u32>,
    cell_start: Vec<u32>,
    fill: Vec<u32>,
    origin: DVec3,
    cell: f64,
    dims: [usize; 3],
    requested_cell: f64,
    max_cells: usize,
}

impl SampleGrid {
    /// Bin `samples` in cells of about `cell` m (a probe radius or less is a good choice).
    ///
    /// Allocates once: at most `max(64, 2·len)` cells; if the samples span more, the cell size
    /// grows until they fit.
    pub fn new(samples: &[SurfaceSample], cell: f64) -> Result<Self, ProbeError> {
        if !(cell.is_finite() && cell > 0.0) {
            return Err(ProbeError::BadCellSize(cell));
        }
        if samples.len() >= u32::MAX as usize {
            return Err(ProbeError::BadSample {
                index: u32::MAX as usize,
            });
        }
        let max_cells = (2 * samples.len()).max(64);
        let mut grid = Self {
            samples: Vec::with_capacity(samples.len()),
            original: Vec::with_capacity(samples.len()),
            cell_start: Vec::with_capacity(max_cells + 1),
            fill: Vec::with_capacity(max_cells),
            origin: DVec3::ZERO,
            cell,
            dims: [1; 3],
            requested_cell: cell,
            max_cells,
        };
        grid.rebin(samples)?;
        Ok(grid)
    }

    /// Re-bin after the samples moved; the count must not change. Allocation-free.
    pub fn update(&mut self, samples: &[SurfaceSample]) -> Result<(), ProbeError> {
        if samples.len() != self.samples.len() {
            return Err(ProbeError::SampleCountChanged {
                expected: self.samples.len(),
                got: samples.len(),
            });
        }
        self.rebin(samples)
    }

    fn rebin(&mut self, samples: &[SurfaceSample]) -> Result<(), ProbeError> {
        if let Some(index) = samples.iter().position(|s| !s.is_valid()) {
            return Err(ProbeError::BadSample { index });
        }
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for s in samples {
            lo = lo.min(s.position);
            hi = hi.max(s.position);
        }
        if samples.is_empty() {
            (lo, hi) = (DVec3::ZERO, DVec3::ZERO);
        }
        let extent = hi - lo;
        let mut cell = self.requested_cell;
        let dims = loop {
            let d = (extent / cell).floor() + DVec3::ONE;
            if d.x * d.y * d.z <= self.max_cells as f64 {
                break [d.x as usize, d.y as usize, d.z as usize];
            }
            if !cell.is_finite() {
                // The extent itself overflowed (samples beyond ±f64::MAX/2): one cell.
                break [1, 1, 1];
            }
            cell *= 1.25;
        };
        self.origin = lo;
        self.cell = cell;
        self.dims = dims;
        let cells = dims[0] * dims[1] * dims[2];
        self.cell_start.clear();
        self.cell_start.resize(cells + 1, 0);
        for s in samples {
            let c = self.cell_of(s.position);
            self.cell_start[c + 1] += 1;
        }
        for c in 0..cells {
            self.cell_start[c + 1] += self.cell_start[c];
        }
        self.fill.clear();
        self.fill.extend_from_slice(&self.cell_start[..cells]);
        let placeholder = SurfaceSample {
            position: DVec3::ZERO,
            normal: DVec3::Z,
            area: 0.0,
        };
        self.samples.clear();
        self.samples.resize(samples.len(), placeholder);
        self.original.clear();
        self.original.resize(samples.len(), 0);
        for (i, s) in samples.iter().enumerate() {
            let c = self.cell_of(s.position);
            let slot = self.fill[c] as usize;
            self.fill[c] += 1;
            self.samples[slot] = *s;
            self.original[slot] = i as u32;
        }
        Ok(())
    }

    #[inline]
    fn coord(&self, x: f64, axis: usize) -> usize {
        let o = [self.origin.x, self.origin.y, self.origin.z][axis];
        let c = ((x - o) / self.cell).floor();
        if c.is_nan() || c < 0.0 {
            0
        } else {
            (c as usize).min(self.dims[axis] - 1)
        }
    }

    #[inline]
    fn cell_of(&self, p: DVec3) -> usize {
        let (i, j, k) = (self.coord(p.x, 0), self.coord(p.y, 1), self.coord(p.z, 2));
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// No samples at all.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// Cell edge in use, m (≥ the requested size).
    pub fn cell_size(&self) -> f64 {
        self.cell
    }

    /// Visit every sample whose cell overlaps the box `[min, max]` (a superset of the samples
    /// inside it), as `(index in the construction order, sample)`, in storage order.
    #[inline]
    pub fn for_each_in_box(&self, min: DVec3, max: DVec3, visit: impl FnMut(u32, &SurfaceSample)) {
        self.for_each_near(min, max, DVec3::ZERO, f64::INFINITY, visit);
    }

    /// As [`SampleGrid::for_each_in_box`], skipping cells outside the ball of `radius` about
    /// `center` too: each row of cells is clipped to the ball's chord through it.
    #[inline]
    pub fn for_each_near(
        &self,
        min: DVec3,
        max: DVec3,
        center: DVec3,
        radius: f64,
        mut visit: impl FnMut(u32, &SurfaceSample),
    ) {
        if self.samples.is_empty() || !min.is_finite() || !max.is_finite() || radius.is_nan() {
            return;
        }
        let dims = DVec3::new(
            self.dims[0] as f64,
            self.dims[1] as f64,
            self.dims[2] as f64,
        );
        let top = self.origin + self.cell * dims;
        if max.cmplt(self.origin).any() || min.cmpgt(top).any() {
            return;
        }
        let (j0, k0) = (self.coord(min.y, 1), self.coord(min.z, 2));
        let (j1, k1) = (self.coord(max.y, 1), self.coord(max.z, 2));
        // Distance from `c` to the interval of cell `i` along an axis.
        let gap = |c: f64, o: f64, i: usize| {
            let lo = o + self.cell * i as f64;
            (lo - c).max(c - (lo + self.cell)).max(0.0)
        };
        let r2 = radius * radius;
        for k in k0..=k1 {
            let dz = gap(center.z, self.origin.z, k);
            for j in j0..=j1 {
                let dy = gap(center.y, self.origin.y, j);
                let rest = r2 - dy * dy - dz * dz;
                if rest < 0.0 {
                    continue;
                }
                let half = rest.sqrt();
                let (x0, x1) = (min.x.max(center.x - half), max.x.min(center.x + half));
                if x0 > x1 {
                    continue;
                }
                let (i0, i1) = (self.coord(x0, 0), self.coord(x1, 0));
                let row = self.dims[0] * (j + self.dims[1] * k);
                let (a, b) = (
                    self.cell_start[row + i0] as usize,
                    self.cell_start[row + i1 + 1] as usize,
                );
                for slot in a..b {
                    visit(self.original[slot], &self.samples[slot]);
                }
            }
        }
    }
}
