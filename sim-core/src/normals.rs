//! Normals for points that have none: PCA over the k-NN, then a consistent orientation by
//! propagation over a minimum spanning tree of the k-NN graph (Hoppe et al. 1992).
//!
//! Contract: every returned normal is a finite unit vector. A neighbourhood without a defined
//! plane (all duplicates) gets `+Z` before orientation. Given normals are never re-estimated;
//! [`orient_consistently`] only flips signs, and [`orient_if_unoriented`] only where the given
//! signs are noise (some scanners write unoriented normals).

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use crate::knn::{KnnGraph, PointIndex};
use crate::linalg::sym3_eigen;

/// The PCA normal (least-variance axis) of each point's k-NN, unoriented. Runs on all cores.
pub fn estimate_pca(points: &[DVec3], knn: &KnnGraph) -> Vec<DVec3> {
    (0..points.len())
        .into_par_iter()
        .map(|i| pca_normal(points, knn.neighbours(i)))
        .collect()
}

/// Fill in only the zero (unknown) entries of `normals` by PCA.
pub fn fill_missing(points: &[DVec3], knn: &KnnGraph, normals: &mut [DVec3]) {
    normals
        .par_iter_mut()
        .enumerate()
        .filter(|(_, n)| **n == DVec3::ZERO)
        .for_each(|(i, n)| {
            *n = pca_normal(points, knn.neighbours(i));
        });
}

fn pca_normal(points: &[DVec3], nb: &[u32]) -> DVec3 {
    let centroid = nb.iter().map(|&j| points[j as usize]).sum::<DVec3>() / nb.len() as f64;
    let mut cov = DMat3::ZERO;
    for &j in nb {
        let d = points[j as usize] - centroid;
        cov += DMat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    match sym3_eigen(cov) {
        Some((vals, vecs)) if vals[2] > 0.0 && vecs[0].is_normalized() => vecs[0],
        _ => DVec3::Z,
    }
}

/// Flip normals so neighbours agree, propagating along a minimum spanning tree of the
/// (symmetrised) graph of each point's [`ORIENT_NEIGHBOURS`] nearest neighbours with edge cost `1 − |nᵢ·nⱼ|`. In each connected component the
/// point with the largest `z` is made to face `+z` (for a closed surface it lies on the hull,
/// where `+z` is outward). Returns the number of normals flipped.
pub fn orient_consistently(points: &[DVec3], knn: &KnnGraph, normals: &mut [DVec3]) -> usize {
    let n = points.len();
    // Symmetric adjacency in CSR form.
    let mut degree = vec![0u32; n + 1];
    for i in 0..n {
        for &j in orientation_edges(knn, i) {
            degree[i + 1] += 1;
            degree[j as usize + 1] += 1;
        }
    }
    for i in 0..n {
        degree[i + 1] += degree[i];
    }
    let mut fill = degree.clone();
    let mut adj = vec![0u32; degree[n] as usize];
    for i in 0..n {
        for &j in orientation_edges(knn, i) {
            adj[fill[i] as usize] = j;
            fill[i] += 1;
            adj[fill[j as usize] as usize] = i as u32;
            fill[j as usize] += 1;
        }
    }
    // Seeds: components visited in order of decreasing z, so each component's seed is its top.
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| points[b].z.total_cmp(&points[a].z));
    let mut done = vec![false; n];
    let mut flips = 0;
    let mut heap = BinaryHeap::new();
    for &seed in &order {
        if done[seed] {
            continue;
        }
        if normals[seed].z < 0.0 {
            normals[seed] = -normals[seed];
            flips += 1;
        }
        heap.push((Reverse(Cost(0.0)), seed as u32, seed as u32));
        while let Some((_, node, parent)) = heap.pop() {
            let node = node as usize;
            if done[node] {
                continue;
            }
            done[node] = true;
            if node != parent as usize && normals[node].dot(normals[parent as usize]) < 0.0 {
                normals[node] = -normals[node];
                flips += 1;
            }
            for &m in &adj[degree[node] as usize..degree[node + 1] as usize] {
                if !done[m as usize] {
                    let cost = 1.0 - normals[node].dot(normals[m as usize]).abs();
                    heap.push((Reverse(Cost(cost)), m, node as u32));
                }
            }
        }
    }
    flips
}

/// Neighbours used as orientation edges: the nearest [`ORIENT_NEIGHBOURS`] (the MST needs a
/// connected graph along the surface, not the whole k-NN; fewer edges keep Prim's heap small).
fn orientation_edges(knn: &KnnGraph, i: usize) -> &[u32] {
    let nb = knn.neighbours(i);
    &nb[1..nb.len().min(ORIENT_NEIGHBOURS + 1)]
}

/// Out-edges per point in the orientation graph.
pub const ORIENT_NEIGHBOURS: usize = 10;

/// After [`orient_consistently`] on a copy of given normals, keep the global sign the majority of
/// the given normals agree with: flips all of `oriented` if most disagree with `given`.
pub fn match_majority(given: &[DVec3], oriented: &mut [DVec3]) {
    let agree = given
        .iter()
        .zip(oriented.iter())
        .filter(|(g, o)| g.dot(**o) >= 0.0)
        .count();
    if 2 * agree < given.len() {
        oriented.iter_mut().for_each(|o| *o = -*o);
    }
}

/// Neighbours of each sampled point that [`unoriented_share`] pairs it with.
const SHARE_NEIGHBOURS: usize = 8;
/// Points [`unoriented_share`] samples at most (evenly by index).
const SHARE_SAMPLES: usize = 4_000;
/// A neighbour within this sine (about 15°) of a point's tangent plane lies beside it, on its
/// sheet; the far side of a thin part lies off the plane by the part's thickness.
const BESIDE: f64 = 0.25;

/// Given normals whose [`unoriented_share`] exceeds this are noise in sign: oriented scans and
/// meshes measure 0–0.004 (the bench's six models), a 3 mm leaf sampled every 4 mm 0.08,
/// random signs 0.41–0.46.
pub const UNORIENTED_SHARE: f64 = 0.2;

/// The share of near pairs (each sampled point with its 8 nearest) whose
/// normals face apart although the neighbour lies beside the point, in its tangent plane: the
/// signature of unoriented normals. On one oriented sheet neighbours beside each other agree;
/// the two sides of a thin part face apart but lie off each other's planes. Zero normals
/// (unknown) are skipped; 0 when there are no pairs.
pub fn unoriented_share(points: &[DVec3], index: &PointIndex, normals: &[DVec3]) -> f64 {
    share_apart(points, normals, |i| {
        index
            .nearest_k(points[i], SHARE_NEIGHBOURS + 1)
            .into_iter()
            .map(|(j, _)| j)
            .filter(move |&j| j != i)
    })
}

/// [`unoriented_share`] with each sampled point's nearest others read from a k-NN graph (its
/// rows are the point, then the nearest others) instead of searched in a tree: the same pairs
/// but where distances tie.
pub fn unoriented_share_in(points: &[DVec3], knn: &KnnGraph, normals: &[DVec3]) -> f64 {
    share_apart(points, normals, |i| {
        let row = knn.neighbours(i);
        row[1.min(row.len())..row.len().min(SHARE_NEIGHBOURS + 1)]
            .iter()
            .map(|&j| j as usize)
    })
}

/// The share behind [`unoriented_share`], over each sampled point's `near` others (on all
/// cores; integer counts, so the result does not depend on the split).
fn share_apart<I: Iterator<Item = usize>>(
    points: &[DVec3],
    normals: &[DVec3],
    near: impl Fn(usize) -> I + Sync,
) -> f64 {
    let step = (points.len() / SHARE_SAMPLES).max(1);
    let (apart, pairs) = (0..points.len().div_ceil(step))
        .into_par_iter()
        .map(|s| {
            let i = s * step;
            let n = normals[i];
            let (mut apart, mut pairs) = (0usize, 0usize);
            if n == DVec3::ZERO || !n.is_finite() {
                return (0, 0);
            }
            for j in near(i) {
                let (m, d) = (normals[j], points[j] - points[i]);
                let len = d.length();
                if j == i || m == DVec3::ZERO || !m.is_finite() || len == 0.0 {
                    continue;
                }
                pairs += 1;
                let beside = n.dot(d).abs() <= BESIDE * len * n.length();
                if beside && n.dot(m) < 0.0 {
                    apart += 1;
                }
            }
            (apart, pairs)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    if pairs == 0 {
        0.0
    } else {
        apart as f64 / pairs as f64
    }
}

/// Make the signs of given `normals` consistent ([`orient_consistently`]: each connected part's
/// top point facing `+z`) when they look unoriented ([`unoriented_share`] above
/// [`UNORIENTED_SHARE`]); otherwise leave them as they are. Returns the share when it
/// reoriented. A field fitted to unoriented normals has no consistent inside: its surface breaks
/// up (a 36k-point scan with random signs: coverage 32× worse, 41 % of projections
/// unconverged). Costs a k-d tree and at most 4,000 searches when nothing is wrong.
pub fn orient_if_unoriented(points: &[DVec3], normals: &mut [DVec3]) -> Option<f64> {
    if points.len() < 2 || points.len() != normals.len() {
        return None;
    }
    let index = PointIndex::new(points);
    let share = unoriented_share(points, &index, normals);
    if share <= UNORIENTED_SHARE {
        return None;
    }
    let knn = KnnGraph::build(points, &index, ORIENT_NEIGHBOURS + 1);
    orient_consistently(points, &knn, normals);
    Some(share)
}

/// [`orient_if_unoriented`] over a k-NN graph of the points (at least
/// [`ORIENT_NEIGHBOURS`] + 1 per row for the same orientation), which the caller has anyway:
/// no k-d tree of its own and no searches.
pub fn orient_if_unoriented_in(
    points: &[DVec3],
    knn: &KnnGraph,
    normals: &mut [DVec3],
) -> Option<f64> {
    if points.len() < 2 || points.len() != normals.len() || knn.len() != points.len() {
        return None;
    }
    let share = unoriented_share_in(points, knn, normals);
    if share <= UNORIENTED_SHARE {
        return None;
    }
    orient_consistently(points, knn, normals);
    Some(share)
}

/// A totally ordered edge cost for the heap.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Cost(f64);
impl Eq for Cost {}
impl PartialOrd for Cost {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Cost {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}
