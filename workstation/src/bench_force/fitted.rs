//! The whole chain on the benchmark sphere: sampled points → fitted field (DESIGN §2) →
//! resampled grid → field force, against the exact sphere. Separates the grid's error (the
//! analytic rows) from what the fitted field adds.

use serde::Serialize;
use sim_core::grid::{GridSpec, ScalarGrid};
use sim_core::haptic::FieldContactParams;
use sim_core::haptic::fixtures::{AnalyticField, force_errors};
use sim_core::reconstruct::{IgnoreStages, NormalPolicy, reconstruct};
use sim_core::sampling::Shape;
use sim_core::{FitParams, NoProgress};

/// Field-force errors on the fitted sphere.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct FittedErrors {
    /// Points sampled on the sphere.
    pub points: usize,
    /// Largest relative force error at depths 0.1–0.3 R.
    pub deep_rel_error: f64,
    /// Largest direction error at depths 0.1–0.3 R, rad.
    pub deep_direction_rad: f64,
    /// Largest error as a position at depths 0–0.05 R, m.
    pub shallow_position_m: f64,
    /// Largest direction error at depths 0–0.05 R, rad.
    pub shallow_direction_rad: f64,
}

/// Fit `points` samples of `sphere` with the default parameters, resample on a grid of spacing
/// `h` over the test region, and measure the field force against the exact sphere.
pub fn fitted_errors(
    points: usize,
    sphere: &AnalyticField,
    h: f64,
    params: &FieldContactParams,
) -> anyhow::Result<FittedErrors> {
    let radius = sphere.size();
    let samples = Shape::Sphere { radius }.sample(points, 5);
    let fit = reconstruct(
        &samples,
        &FitParams::default(),
        NormalPolicy::Keep,
        &mut IgnoreStages,
        &NoProgress,
    )?;
    let (lo, hi) = sphere.region(3.0 * h);
    let grid = ScalarGrid::from_fn(GridSpec::covering(lo, hi, h), |p| fit.field.value(p));
    let deep = force_errors(sphere, &grid, params, 2000, 1, (0.1, 0.3));
    let shallow = force_errors(sphere, &grid, params, 2000, 2, (0.0, 0.05));
    Ok(FittedErrors {
        points,
        deep_rel_error: deep.rel_vector,
        deep_direction_rad: deep.direction_rad,
        shallow_position_m: shallow.position_m,
        shallow_direction_rad: shallow.direction_rad,
    })
}
