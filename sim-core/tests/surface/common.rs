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

/// Sample `n` points in the bounding box of `points` grown by `grow`× its diagonal and check:
/// value and gradient finite; `|f(x)| ≤ dist(x, nearest point) + max_support` (the field never
/// exceeds what one local domain can hold); `‖∇f‖ ≤ grad_bound`. Returns the largest `‖∇f‖`.
pub fn assert_bounded(field: &GlobalField, points: &[DVec3], grow: f64, grad_bound: f64) -> f64 {
    let (lo, hi) = sim_core::pointset::bounds(points).unwrap();
    let diag = (hi - lo).length().max(field.scale());
    let (lo, hi) = (
        lo - DVec3::splat(grow * diag),
        hi + DVec3::splat(grow * diag),
    );
    let index = PointIndex::new(points);
    let max_support = (0..field.len())
        .map(|i| field.support_radius(i))
        .fold(0.0, f64::max);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut worst_grad: f64 = 0.0;
    for _ in 0..4000 {
        let t = DVec3::new(rng.random(), rng.random(), rng.random());
        // Half the samples near the points, where the local fields act.
        let x = if rng.random::<bool>() {
            lo + (hi - lo) * t
        } else {
            let p = points[rng.random_range(0..points.len())];
            p + (t - DVec3::splat(0.5)) * 2.0 * field.scale()
        };
        let (f, g) = field.value_and_gradient(x);
        assert!(
            f.is_finite() && g.is_finite(),
            "non-finite field at {x}: {f} {g}"
        );
        let (_, d) = index.nearest(x);
        assert!(
            f.abs() <= d + max_support,
            "|f({x})| = {} > {d} + {max_support}",
            f.abs()
        );
        worst_grad = worst_grad.max(g.length());
    }
    assert!(
        worst_grad <= grad_bound,
        "‖∇f‖ reached {worst_grad} > {grad_bound}"
    );
    worst_grad
}
