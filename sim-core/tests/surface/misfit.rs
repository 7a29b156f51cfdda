//! Fits weighed by their misfit (`FitParams::misfit_width`): a local field whose fit cannot
//! follow its own points gives way in the blend to its neighbours' better fits.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim_core::reconstruct::NormalPolicy;
use sim_core::{FitParams, GlobalField, PointSet};

use crate::common::{fit, thinned_with_gaps};

const SPACING: f64 = 0.01;
const N: usize = 41;

/// A planar grid (z = 0, facing +z) whose points with x below the middle are scattered off
/// the plane by up to `noise` spacings (a noisy patch of a scan beside a clean one).
fn half_noisy_plane(noise: f64) -> PointSet {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut positions = Vec::new();
    for i in 0..N {
        for j in 0..N {
            let z = if i < N / 2 {
                noise * SPACING * (2.0 * rng.random::<f64>() - 1.0)
            } else {
                0.0
            };
            positions.push(DVec3::new(i as f64 * SPACING, j as f64 * SPACING, z));
        }
    }
    PointSet {
        normals: Some(vec![DVec3::Z; positions.len()]),
        positions,
        colors: None,
    }
}

fn height(field: &GlobalField, x: f64, y: f64) -> f64 {
    let at = |z: f64| field.value(DVec3::new(x, y, z));
    let (mut lo, mut hi) = (-SPACING, SPACING);
    assert!(at(lo) < 0.0 && at(hi) > 0.0, "no crossing at ({x}, {y})");
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if at(mid) < 0.0 { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

/// The worst height of the zero set over the clean half, in spacings, in bands one spacing
/// wide from the noisy patch's edge outward.
fn clean_side_heights(field: &GlobalField) -> [f64; 4] {
    let edge = (N / 2) as f64 * SPACING;
    let mut worst = [0.0f64; 4];
    for (band, w) in worst.iter_mut().enumerate() {
        for j in 10..N - 10 {
            for s in 0..4 {
                let x = edge + (band as f64 + s as f64 * 0.25) * SPACING;
                let y = (j as f64 + 0.5) * SPACING;
                *w = w.max(height(field, x, y).abs() / SPACING);
            }
        }
    }
    worst
}

/// Beside a noisy patch, the fits reaching over it miss their points and the clean side's fits
/// do not, so with `misfit_width` the clean side is pulled off its plane less. Measured (0.4
/// spacing noise; worst height in spacings, 0–1 / 1–2 / 2–3 spacings from the patch):
/// 0.054 / 0.0080 / 0.0030 weighing all fits the same, 0.041 / 0.0053 / 0.0015 at 0.01; at
/// `fit`'s 0.035, 0.051 / 0.0077 / 0.0027. And a field at every point (a sculpting scene's,
/// which is refitted as it changes) is not weighed at all.
#[test]
fn a_noisy_patch_bends_its_clean_neighbour_less_when_fits_weigh_their_misfit() {
    let pts = half_noisy_plane(0.4);
    let heights = |misfit_width: f64, centre_spacing: f64| {
        let params = FitParams {
            misfit_width,
            centre_spacing,
            ..thinned_with_gaps()
        };
        let field = fit(&pts, &params, NormalPolicy::Keep).field;
        let h = clean_side_heights(&field);
        eprintln!("misfit width {misfit_width}, centre spacing {centre_spacing}: {h:.4?}");
        h
    };
    let (same, weighed) = (heights(0.0, 0.35), heights(0.01, 0.35));
    for band in 0..3 {
        assert!(
            weighed[band] < 0.85 * same[band],
            "{} spacings from the patch: {:.4} weighed against {:.4}",
            band,
            weighed[band],
            same[band]
        );
    }
    // A field at every point (centre spacing 0) is never weighed: the width changes nothing.
    assert_eq!(heights(0.01, 0.0), heights(0.0, 0.0));
}
