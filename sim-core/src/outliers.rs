//! Rejection of points that should not get a local field: isolated outliers (k-NN density),
//! points a few spacings off the surface their neighbours agree on, and points whose normal
//! opposes most of their neighbours' (a flipped normal).
//!
//! Contract: pure functions of the k-NN graph, positions and normals; run on all cores; a
//! flagged point keeps its index (it is skipped by the fits, the blend and the fallback).

use glam::DVec3;
use rayon::prelude::*;

use crate::knn::KnnGraph;

/// All three tests: `ratio` is [`crate::FitParams::outlier_ratio`], `agreement` is
/// [`crate::FitParams::normal_agreement`], `typical` the median k-NN radius of the set.
pub fn flag_outliers(
    points: &[DVec3],
    normals: &[DVec3],
    knn: &KnnGraph,
    ratio: f64,
    agreement: f64,
    typical: f64,
) -> Vec<bool> {
    let radii: Vec<f64> = (0..points.len()).map(|i| knn.radius(i)).collect();
    let mut outlier = flag_sparse(knn, &radii, ratio, typical);
    flag_off_surface(points, normals, knn, &mut outlier);
    flag_inconsistent(knn, normals, &mut outlier, agreement);
    outlier
}

/// A point is an outlier when its k-NN radius exceeds `ratio` × the median radius of its
/// neighbours (an isolated point far from a dense surface), or `3·ratio` × the median radius of
/// all points (a cluster of outliers, whose members are each other's neighbours).
fn flag_sparse(knn: &KnnGraph, radii: &[f64], ratio: f64, global_median: f64) -> Vec<bool> {
    (0..radii.len())
        .into_par_iter()
        .map_init(Vec::new, |buf, i| {
            buf.clear();
            buf.extend(knn.neighbours(i)[1..].iter().map(|&j| radii[j as usize]));
            if buf.is_empty() {
                return false;
            }
            let mid = buf.len() / 2;
            let (_, median, _) = buf.select_nth_unstable_by(mid, f64::total_cmp);
            (radii[i] > ratio * *median && *median > 0.0) || radii[i] > 3.0 * ratio * global_median
        })
        .collect()
}

/// Flag points lying off the surface their neighbours agree on: farther from the plane through
/// the neighbours' centroid (normal: their mean normal) than 0.3 × the median neighbour distance
/// and than 3 × the neighbours' own RMS distance to that plane (curvature and noise).
/// Catches outliers a few spacings off the surface, which the density test cannot. Skipped where
/// the neighbours' normals cancel (a thin shell) or there are fewer than four neighbours.
fn flag_off_surface(points: &[DVec3], normals: &[DVec3], knn: &KnnGraph, outlier: &mut [bool]) {
    let flags: Vec<bool> = (0..points.len())
        .into_par_iter()
        .map(|i| {
            let (mut count, mut centroid, mut mean_n) = (0usize, DVec3::ZERO, DVec3::ZERO);
            for &j in &knn.neighbours(i)[1..] {
                if !outlier[j as usize] {
                    count += 1;
                    centroid += points[j as usize];
                    mean_n += normals[j as usize];
                }
            }
            if count < 4 || mean_n.length() < 0.5 * count as f64 {
                return false;
            }
            let (centroid, axis) = (centroid / count as f64, mean_n.normalize());
            let offset = (points[i] - centroid).dot(axis).abs();
            // The neighbours' own spread about that plane (curvature, noise) sets the tolerance.
            let spread2 = knn.neighbours(i)[1..]
                .iter()
                .filter(|&&j| !outlier[j as usize])
                .map(|&j| (points[j as usize] - centroid).dot(axis).powi(2))
                .sum::<f64>()
                / count as f64;
            let d = knn.distances(i);
            offset > 0.3 * d[d.len() / 2] && offset > 3.0 * spread2.sqrt()
        })
        .collect();
    for (o, f) in outlier.iter_mut().zip(flags) {
        *o |= f;
    }
}

/// Flag points whose normal disagrees (dot below `agreement`) with at least three quarters of
/// their inlier neighbours: a flipped normal amid consistent ones. Its local field would be the
/// reverse of its neighbours' and the blend's gradient would blow up where they meet. A thin
/// shell, whose neighbourhoods are about half one sheet and half the other, is not affected.
fn flag_inconsistent(knn: &KnnGraph, normals: &[DVec3], outlier: &mut [bool], agreement: f64) {
    let flags: Vec<bool> = (0..normals.len())
        .into_par_iter()
        .map(|i| {
            let (mut total, mut against) = (0usize, 0usize);
            for &j in &knn.neighbours(i)[1..] {
                if !outlier[j as usize] {
                    total += 1;
                    against += usize::from(normals[j as usize].dot(normals[i]) < agreement);
                }
            }
            total >= 4 && 4 * against >= 3 * total
        })
        .collect();
    for (o, f) in outlier.iter_mut().zip(flags) {
        *o |= f;
    }
}
