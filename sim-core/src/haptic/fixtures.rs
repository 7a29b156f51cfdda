//! Analytic fields with exact forces, for tests, benches and the accuracy report.
//!
//! For an exact signed distance `φ`, the ray from an interior point `x` along `∇φ` meets the
//! surface after exactly `−φ(x)`, so the reference force of [`super::FieldForce`] is
//! `F_ref = k·(−φ(x))·∇φ(x)`. Points are seeded ([`rand_chacha`]), so every report is
//! reproducible.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{FieldContactParams, FieldForce};
use crate::grid::{GridSpec, ScalarGrid};

/// An analytic shape; `size` is the feature size `R` the grid spacing is quoted against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AnalyticField {
    /// Sphere of radius `size` at the origin; test points in the positive octant.
    Sphere {
        /// Radius, m.
        size: f64,
    },
    /// The plane `z = 0`; test points over `[−size, size]²`.
    Plane {
        /// Half width of the tested patch, m.
        size: f64,
    },
    /// Torus around `z`, major radius `3·size`, tube radius `size`; test points within
    /// ±0.3 rad of `+x`.
    Torus {
        /// Tube radius, m.
        size: f64,
    },
}

impl AnalyticField {
    /// The feature size `R`, m.
    pub fn size(&self) -> f64 {
        match *self {
            Self::Sphere { size } | Self::Plane { size } | Self::Torus { size } => size,
        }
    }

    /// Short name for reports.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Sphere { .. } => "sphere",
            Self::Plane { .. } => "plane",
            Self::Torus { .. } => "torus",
        }
    }

    /// Exact signed distance (negative inside), m.
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        let r = self.size();
        match self {
            Self::Sphere { .. } => p.length() - r,
            Self::Plane { .. } => p.z,
            Self::Torus { .. } => DVec3::new(p.x.hypot(p.y) - 3.0 * r, 0.0, p.z).length() - r,
        }
    }

    /// A seeded interior point at `depth` m below the surface and its exact outward normal.
    pub fn interior_point(&self, rng: &mut ChaCha8Rng, depth: f64) -> (DVec3, DVec3) {
        let r = self.size();
        match self {
            Self::Sphere { .. } => {
                let u = DVec3::new(
                    rng.random_range(0.1..1.0),
                    rng.random_range(0.1..1.0),
                    rng.random_range(0.1..1.0),
                )
                .normalize();
                ((r - depth) * u, u)
            }
            Self::Plane { .. } => {
                let p = DVec3::new(rng.random_range(-r..r), rng.random_range(-r..r), -depth);
                (p, DVec3::Z)
            }
            Self::Torus { .. } => {
                let phi: f64 = rng.random_range(-0.3..0.3);
                let theta: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                let radial = DVec3::new(phi.cos(), phi.sin(), 0.0);
                let u = theta.cos() * radial + theta.sin() * DVec3::Z;
                (3.0 * r * radial + (r - depth) * u, u)
            }
        }
    }

    /// The box holding every test point (depth ≤ `R`), grown by `margin`.
    pub fn region(&self, margin: f64) -> (DVec3, DVec3) {
        let r = self.size();
        let (lo, hi) = match self {
            Self::Sphere { .. } => (DVec3::ZERO, DVec3::splat(r)),
            Self::Plane { .. } => (DVec3::new(-r, -r, -r), DVec3::new(r, r, 0.0)),
            Self::Torus { .. } => {
                let s = 0.3f64.sin() * 4.0 * r;
                (
                    DVec3::new(3.0 * r * 0.3f64.cos() - r, -s, -r),
                    DVec3::new(4.0 * r, s, r),
                )
            }
        };
        (lo - DVec3::splat(margin), hi + DVec3::splat(margin))
    }

    /// The field sampled at `spacing` over the test region plus three cells (so no test point
    /// sees a one-sided boundary gradient).
    pub fn grid(&self, spacing: f64) -> ScalarGrid {
        let (lo, hi) = self.region(3.0 * spacing);
        let this = *self;
        ScalarGrid::from_fn(GridSpec::covering(lo, hi, spacing), move |p| {
            this.signed_distance(p)
        })
    }
}

/// Force errors of [`FieldForce`] against the analytic reference.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ForceErrors {
    /// Largest `|F − F_ref| / |F_ref|`.
    pub rel_vector: f64,
    /// Largest `| |F| − |F_ref| | / |F_ref|`.
    pub rel_magnitude: f64,
    /// Largest angle between `F` and `F_ref`, rad.
    pub direction_rad: f64,
    /// Largest `|F − F_ref| / k`: the error as a position, m.
    pub position_m: f64,
}

/// Query `n` seeded interior points at depths uniform in `depths` (fractions of `R`),
/// frictionless and at rest, and return the worst errors.
pub fn force_errors(
    field: &AnalyticField,
    grid: &ScalarGrid,
    params: &FieldContactParams,
    n: usize,
    seed: u64,
    depths: (f64, f64),
) -> ForceErrors {
    let p = FieldContactParams {
        friction: 0.0,
        ..*params
    };
    let Ok(mut ff) = FieldForce::new(p) else {
        return ForceErrors::default();
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut e = ForceErrors::default();
    for _ in 0..n {
        let d = field.size() * rng.random_range(depths.0..depths.1);
        let (x, u) = field.interior_point(&mut rng, d);
        ff.reset();
        let f = ff.query(grid, x, DVec3::ZERO).output.force;
        let reference = p.stiffness * d * u;
        let angle = f.angle_between(reference);
        e.rel_vector = e
            .rel_vector
            .max((f - reference).length() / reference.length());
        e.rel_magnitude = e
            .rel_magnitude
            .max((f.length() / reference.length() - 1.0).abs());
        e.direction_rad = e
            .direction_rad
            .max(if angle.is_finite() { angle } else { 0.0 });
        e.position_m = e.position_m.max((f - reference).length() / p.stiffness);
    }
    e
}

/// `n` seeded interior points at depths uniform in `depths` (fractions of `R`), with their
/// exact depth (m) and outward normal: `(x, depth, normal)`.
pub fn contact_points(
    field: &AnalyticField,
    n: usize,
    seed: u64,
    depths: (f64, f64),
) -> Vec<(DVec3, f64, DVec3)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let d = field.size() * rng.random_range(depths.0..depths.1);
            let (x, u) = field.interior_point(&mut rng, d);
            (x, d, u)
        })
        .collect()
}
