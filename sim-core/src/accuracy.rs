//! Error against ground truth, two ways:
//! - [`mesh_error`], the one to judge a surface by: area-uniform samples over the *whole* output
//!   mesh → distance to the reference, and samples on the reference → distance to the output
//!   (coverage), so a spurious sheet far from the data and a hole both count. Each way's max
//!   also takes every vertex (the output's; the reference's when it is a mesh), so a spike
//!   narrower than the samples' spacing is not missed by luck.
//! - [`zero_set_error`], the projected figure: start near the reference surface, project onto
//!   the fitted zero set with Newton, measure each projected point's distance to the reference.
//!   It sees how well the field fits where the data is, but never a zero-set piece away from it.
//!
//! - [`SampledError::by_spacing`] breaks the first down by how far each sample lies from the
//!   nearest input point, in the points' spacings (error at the data against between it).
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
    /// The reference's own vertices, if it has any (a mesh's, those on a triangle): the
    /// coverage max measures each, besides the samples. An analytic shape has none.
    fn vertices(&self) -> Vec<DVec3> {
        Vec::new()
    }
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
    fn vertices(&self) -> Vec<DVec3> {
        self.mesh.used_vertices()
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
    /// Largest: over the samples and, for [`mesh_error`], every vertex of the side measured.
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
    Some(SampledError::new(mesh, reference, samples, seed)?.summary())
}

/// The samples behind [`mesh_error`], each with its distance: to summarise ([`Self::summary`],
/// the same figures as [`mesh_error`]) and to break down by where they lie
/// ([`Self::by_spacing`]).
#[derive(Debug, Clone)]
pub struct SampledError {
    /// Samples on the output and their distances to the reference.
    pub on_output: Vec<(DVec3, f64)>,
    /// Samples on the reference and their distances to the output.
    pub on_reference: Vec<(DVec3, f64)>,
    /// The largest distance of a vertex each way: the output's vertices to the reference, and
    /// the reference's ([`Reference::vertices`]) to the output. Each way's max counts it.
    pub vertex_max: [f64; 2],
    /// See [`Reference::size`].
    pub reference_size: f64,
}

impl SampledError {
    /// Draw and measure the samples of [`mesh_error`] (the same samples for a seed).
    pub fn new(
        mesh: &TriMesh,
        reference: &dyn Reference,
        samples: usize,
        seed: u64,
    ) -> Option<Self> {
        if mesh.area().is_nan() || mesh.area() <= 0.0 {
            return None;
        }
        let output = MeshReference::new(mesh.clone())?;
        let on_output = output
            .sample(samples, seed ^ 0x0a7e_5a3f)
            .into_par_iter()
            .map(|(p, _)| (p, reference.distance(p)))
            .collect();
        let on_reference = reference
            .sample(samples, seed)
            .into_par_iter()
            .map(|(p, _)| (p, output.distance(p)))
            .collect();
        let farthest = |vertices: Vec<DVec3>, to: &dyn Reference| {
            vertices
                .into_par_iter()
                .map(|v| to.distance(v))
                .reduce(|| 0.0, f64::max)
        };
        let vertex_max = [
            farthest(output.vertices(), reference),
            farthest(reference.vertices(), &output),
        ];
        Some(Self {
            on_output,
            on_reference,
            vertex_max,
            reference_size: reference.size(),
        })
    }

    /// RMS and 99th percentile of the samples and the max of the samples and the vertices,
    /// each way, in metres.
    pub fn summary(&self) -> TwoSidedError {
        let distances = |s: &[(DVec3, f64)], vertex_max: f64| {
            let d = Distances::of(s.iter().map(|(_, d)| *d).collect());
            Distances {
                max: d.max.max(vertex_max),
                ..d
            }
        };
        TwoSidedError {
            samples: self.on_output.len(),
            to_reference: distances(&self.on_output, self.vertex_max[0]),
            coverage: distances(&self.on_reference, self.vertex_max[1]),
            reference_size: self.reference_size,
        }
    }

    /// The error broken down by how far each sample lies from the nearest of `points` (the
    /// input the mesh was made from), in units of the points' median nearest-neighbour
    /// spacing: where a method's error grows between the points, not at them, it is the
    /// interpolant, not the fit to the data. `None` for fewer than two distinct points.
    pub fn by_spacing(&self, points: &[DVec3]) -> Option<ErrorBySpacing> {
        if points.len() < 2 {
            return None;
        }
        let index = PointIndex::new(points);
        let spacing = crate::resample::spacing_in(points, &index, usize::MAX)?;
        let bands = |samples: &[(DVec3, f64)]| {
            let gaps: Vec<f64> = samples
                .par_iter()
                .map(|(p, _)| index.nearest(*p).1 / spacing)
                .collect();
            let total: f64 = samples.iter().map(|(_, d)| d * d).sum();
            SPACING_BANDS
                .windows(2)
                .map(|edge| {
                    let (mut count, mut sum) = (0usize, 0.0);
                    for (g, (_, d)) in gaps.iter().zip(samples) {
                        if *g >= edge[0] && *g < edge[1] {
                            count += 1;
                            sum += d * d;
                        }
                    }
                    BandError {
                        samples: count as f64 / samples.len().max(1) as f64,
                        rms: if count > 0 {
                            (sum / count as f64).sqrt() / self.reference_size
                        } else {
                            0.0
                        },
                        squared: if total > 0.0 { sum / total } else { 0.0 },
                    }
                })
                .collect::<Vec<_>>()
        };
        let (out, cov) = (bands(&self.on_output), bands(&self.on_reference));
        Some(ErrorBySpacing {
            spacing,
            bands: SPACING_BANDS
                .windows(2)
                .zip(out.into_iter().zip(cov))
                .map(|(edge, (to_reference, coverage))| SpacingBand {
                    from: edge[0],
                    to: edge[1].is_finite().then_some(edge[1]),
                    to_reference,
                    coverage,
                })
                .collect(),
        })
    }
}

/// Band edges of [`SampledError::by_spacing`], in median spacings from the nearest point.
pub const SPACING_BANDS: [f64; 7] = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0, f64::INFINITY];

/// [`SampledError::by_spacing`]'s result.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ErrorBySpacing {
    /// The unit of the bands: the points' median nearest-neighbour spacing, metres.
    pub spacing: f64,
    /// One per band of [`SPACING_BANDS`].
    pub bands: Vec<SpacingBand>,
}

/// The samples lying from `from` to `to` spacings from the nearest point, each way.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SpacingBand {
    /// Lower edge, in spacings (inclusive).
    pub from: f64,
    /// Upper edge, in spacings (exclusive); `None` for the last, open band.
    pub to: Option<f64>,
    /// Samples on the output, distance to the reference.
    pub to_reference: BandError,
    /// Samples on the reference, distance to the output.
    pub coverage: BandError,
}

/// One direction's samples in one band.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BandError {
    /// Share of that direction's samples in the band (0..=1).
    pub samples: f64,
    /// RMS of their distances, relative to the reference size (0 for an empty band).
    pub rms: f64,
    /// Share of that direction's summed squared distance in the band (0..=1).
    pub squared: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Nodes of an `n × n` grid of spacing `s` on z = 0.
    fn grid(n: usize, s: f64) -> Vec<DVec3> {
        (0..n * n)
            .map(|i| DVec3::new((i % n) as f64 * s, (i / n) as f64 * s, 0.0))
            .collect()
    }

    /// Samples over the grid's inner cells (a 40 × 40 lattice per cell), each with the
    /// distance `error(gap)` for its distance `gap` to the nearest node.
    fn sampled(s: f64, error: impl Fn(f64) -> f64) -> SampledError {
        let mut samples = Vec::new();
        for cell in 0..(8 * 8) {
            let origin = DVec3::new((2 + cell % 8) as f64 * s, (2 + cell / 8) as f64 * s, 0.0);
            for k in 0..40 * 40 {
                let p = origin
                    + DVec3::new((k % 40) as f64 + 0.5, (k / 40) as f64 + 0.5, 0.0) * (s / 40.0);
                let gap = (p / s - (p / s).round()).length() * s;
                samples.push((p, error(gap)));
            }
        }
        SampledError {
            on_output: samples.clone(),
            on_reference: samples,
            vertex_max: [0.0; 2],
            reference_size: 1.0,
        }
    }

    #[test]
    fn bands_are_in_the_spacing_of_distinct_points() {
        let mut points = grid(12, 0.1);
        points.extend(grid(12, 0.1)); // every point twice, as a mesh file's seams repeat them
        let by = sampled(0.1, |_| 1e-3).by_spacing(&points).unwrap();
        assert!((by.spacing - 0.1).abs() < 1e-12, "{}", by.spacing);
        assert_eq!(sampled(0.1, |_| 1e-3).by_spacing(&[DVec3::ONE; 2]), None);
    }

    #[test]
    fn bands_see_error_that_grows_between_the_points_and_error_that_does_not() {
        let s = 0.1;
        let points = grid(12, s);
        // A sag between the points (zero at them) against a uniform offset.
        let sag = sampled(s, |gap| 1e-3 * (gap / s).powi(2))
            .by_spacing(&points)
            .unwrap();
        let offset = sampled(s, |_| 1e-3).by_spacing(&points).unwrap();
        assert!((sag.spacing - s).abs() < 1e-12);
        for by in [&sag, &offset] {
            assert_eq!(by.bands.len(), SPACING_BANDS.len() - 1);
            for side in [
                |b: &SpacingBand| b.to_reference,
                |b: &SpacingBand| b.coverage,
            ] {
                let samples: f64 = by.bands.iter().map(|b| side(b).samples).sum();
                let squared: f64 = by.bands.iter().map(|b| side(b).squared).sum();
                assert!((samples - 1.0).abs() < 1e-12 && (squared - 1.0).abs() < 1e-12);
            }
        }
        // On a grid every sample lies within √2/2 spacing of a node: two bands hold them.
        let (near, mid) = (sag.bands[0].to_reference, sag.bands[1].to_reference);
        assert!((near.samples + mid.samples - 1.0).abs() < 1e-12, "{sag:?}");
        assert!(near.samples > 0.7 && mid.samples > 0.1, "{sag:?}");
        assert!(sag.bands[2..].iter().all(|b| b.to_reference.rms == 0.0));
        // The sag's RMS grows from the near band to the far one; the offset's does not.
        assert!(mid.rms > 2.0 * near.rms, "{sag:?}");
        let (a, b) = (offset.bands[0].coverage.rms, offset.bands[1].coverage.rms);
        assert!(
            (a - 1e-3).abs() < 1e-12 && (b - 1e-3).abs() < 1e-12,
            "{offset:?}"
        );
        // The far band's share of the squared error outweighs its share of samples.
        assert!(mid.squared > mid.samples, "{sag:?}");
        assert_eq!(sag.bands[5].to, None);
        assert_eq!(sag.bands[0].to, Some(0.5));
    }
}
