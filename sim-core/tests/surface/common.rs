//! Shared helpers: fit a point set, and check the field is finite and bounded everywhere.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim_core::accuracy::{ErrorReport, Reference, zero_set_error};
use sim_core::knn::PointIndex;
use sim_core::reconstruct::{IgnoreStages, NormalPolicy, Reconstruction, reconstruct};
use sim_core::{FitParams, GlobalField, NoProgress, PointSet};

pub fn fit(points: &PointSet, params: &FitParams, policy: NormalPolicy) -> Reconstruction {
    reconstruct(points, params, policy, &mut IgnoreStages, &NoProgress).expect("fit")
}

/// `workstation fit`'s defaults for a static surface before its smaller neighbourhoods
/// (`k_even`): thinned centres with gap fields, positions leading normals.
pub fn thinned_with_gaps() -> FitParams {
    FitParams {
        normal_weight: 0.25,
        regularization: 3e-4,
        centre_spacing: 0.35,
        gap_fields: 0.12,
        ..FitParams::default()
    }
}

/// `workstation fit`'s defaults for a static surface: [`thinned_with_gaps`] with smaller
/// neighbourhoods where the nearest 16 surround a point, fits weighed by their misfit, and
/// fewer centres on flat faces.
pub fn fit_defaults() -> FitParams {
    FitParams {
        flat_spacing: 0.5,
        k_even: 16,
        even_lean: 0.2,
        misfit_width: 0.035,
        ..thinned_with_gaps()
    }
}

pub fn error(field: &GlobalField, reference: &dyn Reference, n: usize) -> ErrorReport {
    let e = zero_set_error(field, reference, n, 0.5, 11);
    eprintln!(
        "  rms {:.3e} max {:.3e} (relative), unconverged {}",
        e.rms_relative(),
        e.max_relative(),
        e.unconverged
    );
    e
}

/// Sample the bounding box of `points` grown by `grow`× its diagonal, the band of ±1 field
/// scale (median support radius) around the points, and the narrow band of ±¼ scale, and check:
/// value and gradient finite everywhere; `|f(x)| ≤ 2·(dist(x, nearest point) + max_support)`
/// (never more than twice what one local domain can hold; sparse scans reach ~1.3×);
/// `‖∇f‖ ≤ grad_bound` in the narrow band, where haptic queries and projections live, and
/// `‖∇f‖ ≤ 1000` elsewhere (near the outer edge of the supports the blend of disagreeing local
/// fields can be steep: a known weakness, see docs/BENCHMARKS.md). Returns the narrow-band max.
pub fn assert_bounded(field: &GlobalField, points: &[DVec3], grow: f64, grad_bound: f64) -> f64 {
    let (lo, hi) = sim_core::pointset::bounds(points).unwrap();
    let diag = (hi - lo).length().max(field.scale());
    let (lo, hi) = (
        lo - DVec3::splat(grow * diag),
        hi + DVec3::splat(grow * diag),
    );
    let index = PointIndex::new(points);
    // Over the points, not `field.len()`: a thinned field has fewer fields than points.
    let max_support = (0..points.len())
        .map(|i| field.support_radius(i))
        .fold(0.0, f64::max);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (mut near_grad, mut far_grad): (f64, f64) = (0.0, 0.0);
    for n in 0..6000 {
        let t = DVec3::new(rng.random(), rng.random(), rng.random()) - DVec3::splat(0.5);
        let p = points[rng.random_range(0..points.len())];
        let x = match n % 3 {
            0 => lo + (hi - lo) * (t + DVec3::splat(0.5)),
            1 => p + t * 2.0 * field.scale(),
            _ => p + t * 0.5 * field.scale(),
        };
        let (f, g) = field.value_and_gradient(x);
        assert!(
            f.is_finite() && g.is_finite(),
            "non-finite field at {x}: {f} {g}"
        );
        let (_, d) = index.nearest(x);
        assert!(
            f.abs() <= 2.0 * (d + max_support),
            "|f({x})| = {} > 2·({d} + {max_support})",
            f.abs()
        );
        if n % 3 == 2 {
            near_grad = near_grad.max(g.length());
        } else {
            far_grad = far_grad.max(g.length());
        }
    }
    eprintln!("  max ‖∇f‖: {near_grad:.2} within ¼ scale of the points, {far_grad:.2} elsewhere");
    assert!(
        near_grad <= grad_bound,
        "‖∇f‖ reached {near_grad} > {grad_bound} near the points"
    );
    assert!(
        far_grad <= 1000.0,
        "‖∇f‖ reached {far_grad} away from the points"
    );
    near_grad
}
