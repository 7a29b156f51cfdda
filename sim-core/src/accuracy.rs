//! Error against ground truth, two ways:
//! - [`mesh_error`], the one to judge a surface by: area-uniform samples over the *whole* output
//!   mesh → distance to the reference, and samples on the reference → distance to the output
//!   (coverage), so a spurious sheet far from the data and a hole both count.
//! - [`zero_set_error`], the projected figure: start near the reference surface, project onto
//!   the fitted zero set with Newton, measure each projected point's distance to the reference.
//!   It sees how well the field fits where the data is, but never a zero-set piece away from it.
//!
//! Contract: deterministic for a seed; distances are exact for analytic shapes and exact
//! point-to-triangle distances for meshes.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::field::GlobalField;
use crate::knn::PointIndex;
use crate::mesh::{TriMesh, closest_on_triangle};
use crate::sampling::Shape;

/// A surface to measure against.
pub trait Reference: Sync {
    /// Unsigned distance from `p` to the reference surface.
    fn distance(&self, p: DVec3) -> f64;
    /// `n` points on the reference with unit normals, seeded.
    fn sample(&self, n: usize, seed: u64) -> Vec<(DVec3, DVec3)>;
    /// The length errors are made relative to (sphere radius, else bounding-box diagonal).
    fn size(&self) -> f64;
}

impl Reference for Shape {
    fn distance(&self, p: DVec3) -> f64 {
        self.signed_distance(p).abs()
    }
    fn sample(&self, n: usize, seed: u64) -> Vec<(DVec3, DVec3)> {
        let s = Shape::sample(self, n, seed);
        s.positions
            .into_iter()
            .zip(s.normals.unwrap_or_default())
            .collect()
    }
    fn size(&self) -> f64 {
        self.reference_size()
    }
}

/// A triangle mesh as a reference, with a centroid k-d tree for exact distance queries.
#[derive(Debug)]
pub struct MeshReference {
    mesh: TriMesh,
    centroids: PointIndex,
    max_radius: f64,
}

impl MeshReference {
    /// Index `mesh`; `None` if it has no triangles.
    pub fn new(mesh: TriMesh) -> Option<Self> {
        if mesh.triangles.is_empty() {
            return None;
        }
        let mut max_radius: f64 = 0.0;
        let centroids: Vec<DVec3> = mesh
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
                let g = (a + b + c) / 3.0;
                max_radius = max_radius
                    .max((a - g).length())
                    .max((b - g).length())
                    .max((c - g).length());
                g
            })
            .collect();
        Some(Self {
            centroids: PointIndex::new(&centroids),
            mesh,
            max_radius,
        })
    }

    fn triangle_distance(&self, t: usize, p: DVec3) -> f64 {
        let [a, b, c] = self.mesh.triangles[t].map(|i| self.mesh.vertices[i as usize]);
        (closest_on_triangle(p, a, b, c) - p).length()
    }
}

impl Reference for MeshReference {
    fn distance(&self, p: DVec3) -> f64 {
        let (t0, _) = self.centroids.nearest(p);
        let ub = self.triangle_distance(t0, p);
        self.centroids
            .within(p, ub + self.max_radius)
            .into_iter()
            .map(|(t, _)| self.triangle_distance(t, p))
            .fold(ub, f64::min)
    }
    fn sample(&self, n: usize, seed: u64) -> Vec<(DVec3, DVec3)> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let tris = &self.mesh.triangles;
        let mut cumulative = Vec::with_capacity(tris.len());
        let mut total = 0.0;
        for t in tris {
            let [a, b, c] = t.map(|i| self.mesh.vertices[i as usize]);
            total += 0.5 * (b - a).cross(c - a).length();
            cumulative.push(total);
        }
        (0..n)
            .map(|_| {
                let pick = rng.random::<f64>() * total;
                let t = cumulative
                    .partition_point(|&c| c < pick)
                    .min(tris.len() - 1);
                let [a, b, c] = tris[t].map(|i| self.mesh.vertices[i as usize]);
                let (mut u, mut v) = (rng.random::<f64>(), rng.random::<f64>());
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                let n = (b - a).cross(c - a).try_normalize().unwrap_or(DVec3::Z);
                (a + (b - a) * u + (c - a) * v, n)
            })
            .collect()
    }
    fn size(&self) -> f64 {
        crate::pointset::bounds(&self.mesh.vertices).map_or(1.0, |(lo, hi)| (hi - lo).length())
    }
}

/// Zero-set error statistics.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ErrorReport {
    /// Points projected.
    pub samples: usize,
    /// Projections that did not reach the tolerance (still counted in the statistics).
    pub unconverged: usize,
    /// Root-mean-square distance to the reference, metres.
    pub rms: f64,
    /// Largest distance, metres.
    pub max: f64,
    /// The reference length used for relative errors.
    pub reference_size: f64,
}

impl ErrorReport {
    /// `rms / reference_size`.
    pub fn rms_relative(&self) -> f64 {
        self.rms / self.reference_size
    }
    /// `max / reference_size`.
    pub fn max_relative(&self) -> f64 {
        self.max / self.reference_size
    }
}

/// Project `samples` starting points onto the field's zero set and measure their distance to
/// `reference`. Starts are reference samples displaced along their normal by up to
/// `jitter × field.scale()` (uniform in ±); runs on all cores.
pub fn zero_set_error(
    field: &GlobalField,
    reference: &dyn Reference,
    samples: usize,
    jitter: f64,
    seed: u64,
) -> ErrorReport {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x005e_ed0f_e440);
    let starts: Vec<DVec3> = reference
        .sample(samples, seed)
        .into_iter()
        .map(|(p, n)| p + n * ((rng.random::<f64>() * 2.0 - 1.0) * jitter * field.scale()))
        .collect();
    let results: Vec<(f64, bool)> = starts
        .par_iter()
        .map(|&x| {
            let pr = field.project_to_zero_set(x);
            (reference.distance(pr.point), pr.converged)
        })
        .collect();
    let n = results.len().max(1);
    let sum2: f64 = results.iter().map(|(d, _)| d * d).sum();
    ErrorReport {
        samples: results.len(),
        unconverged: results.iter().filter(|(_, ok)| !ok).count(),
        rms: (sum2 / n as f64).sqrt(),
        max: results.iter().map(|(d, _)| *d).fold(0.0, f64::max),
        reference_size: reference.size(),
    }
}

/// Distance statistics of one direction of [`mesh_error`], in metres.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Distances {
    /// Root mean square.
    pub rms: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest.
    pub max: f64,
}

impl Distances {
    fn of(mut d: Vec<f64>) -> Self {
        if d.is_empty() {
            return Self {
                rms: 0.0,
                p99: 0.0,
                max: 0.0,
            };
        }
        d.par_sort_unstable_by(f64::total_cmp);
        let n = d.len();
        let rms = (d.iter().map(|x| x * x).sum::<f64>() / n as f64).sqrt();
        let p99 = d[((n as f64 * 0.99).ceil() as usize).clamp(1, n) - 1];
        Self {
            rms,
            p99,
            max: d[n - 1],
        }
    }

    /// Each figure divided by `size`.
    pub fn relative(&self, size: f64) -> Self {
        Self {
            rms: self.rms / size,
            p99: self.p99 / size,
            max: self.max / size,
        }
    }
}

/// Both ways between an output mesh and a reference surface: every spurious piece of the
/// output raises `to_reference`, every hole raises `coverage`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct TwoSidedError {
    /// Samples drawn on each side.
    pub samples: usize,
    /// Area-uniform samples on the output → distance to the reference surface.
    pub to_reference: Distances,
    /// Samples on the reference → distance to the output mesh (exact point–triangle).
    pub coverage: Distances,
    /// The reference length for relative figures (see [`Reference::size`]).
    pub reference_size: f64,
}

impl TwoSidedError {
    /// Both directions divided by [`TwoSidedError::reference_size`].
    pub fn relative(&self) -> (Distances, Distances) {
        (
            self.to_reference.relative(self.reference_size),
            self.coverage.relative(self.reference_size),
        )
    }
}

/// The two-sided distance between `mesh` and `reference`: `samples` area-uniform points on the
/// whole mesh measured against the reference, and `samples` points on the reference measured
/// against the mesh. `None` when the mesh has no triangle of positive area (nothing covers the
/// reference). Deterministic for a seed; runs on all cores.
pub fn mesh_error(
    mesh: &TriMesh,
    reference: &dyn Reference,
    samples: usize,
    seed: u64,
) -> Option<TwoSidedError> {
    if mesh.area().is_nan() || mesh.area() <= 0.0 {
        return None;
    }
    let output = MeshReference::new(mesh.clone())?;
    let on_output = output.sample(samples, seed ^ 0x0a7e_5a3f);
    let to_reference: Vec<f64> = on_output
        .par_iter()
        .map(|(p, _)| reference.distance(*p))
        .collect();
    let on_reference = reference.sample(samples, seed);
    let coverage: Vec<f64> = on_reference
        .par_iter()
        .map(|(p, _)| output.distance(*p))
        .collect();
    Some(TwoSidedError {
        samples,
        to_reference: Distances::of(to_reference),
        coverage: Distances::of(coverage),
        reference_size: reference.size(),
    })
}
