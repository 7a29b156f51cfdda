//! Dynamic sampling (DESIGN §3): up-sampling by the largest empty Voronoi circle on the tangent
//! plane, down-sampling by merging points closer than a fraction of the spacing.
//!
//! Up-sampling, per point `p` with normal `n`: its `k` nearest neighbours are projected onto the
//! tangent plane; for every pair `a, b` the circumcentre `c` of `(p, a, b)` is a vertex of `p`'s
//! Voronoi cell if its circle holds no other neighbour (a Delaunay triangle), O(k³) per point. If the largest such circle's radius exceeds
//! `max_gap`, a point is inserted at `c`, lifted to 3-D and projected onto the field's zero set
//! (normal from the gradient). Candidates within `max_gap / 2` of an earlier insertion are
//! skipped, so one hole gets one point per pass.
//!
//! Contract: deterministic (points in index order, neighbour lists sorted), finite output;
//! inserted points are appended, existing ones never move. Down-sampling returns a new point set
//! whose merged points are the cluster means projected onto the zero set.

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use crate::field::GlobalField;
use crate::knn::PointIndex;
use crate::linalg::tangent_frame;
use crate::pointset::PointSet;

/// Settings of [`upsample`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpsampleOptions {
    /// Insert where the largest empty circle's radius exceeds this (m).
    pub max_gap: f64,
    /// Neighbours considered per point.
    pub k: usize,
}

/// A point to insert: position on the zero set, unit normal, and the index of the point whose
/// Voronoi cell it came from (to inherit colour).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Insertion {
    /// Position.
    pub position: DVec3,
    /// Unit outward normal.
    pub normal: DVec3,
    /// The point it was found next to.
    pub parent: usize,
}

/// The largest empty circle of point `p`'s tangent-plane Voronoi cell among `neighbours`:
/// `(centre in 3-D, radius)`, or `None` when the cell is unbounded everywhere. Only circles whose
/// emptiness the neighbours can prove are considered: every point inside a circle through `p` of
/// radius `r` is within `2r` of `p`, so `2r` must not exceed the farthest neighbour's distance
/// (the neighbours must be the nearest ones).
pub fn largest_empty_circle(p: DVec3, n: DVec3, neighbours: &[DVec3]) -> Option<(DVec3, f64)> {
    let (t1, t2) = tangent_frame(n);
    let q: Vec<DVec2> = neighbours
        .iter()
        .map(|x| DVec2::new((*x - p).dot(t1), (*x - p).dot(t2)))
        .filter(|v| v.length_squared() > 0.0)
        .collect();
    if q.len() < 3 {
        return None;
    }
    let reach = q.iter().map(|v| v.length()).fold(0.0, f64::max);
    let mut best: Option<(DVec2, f64)> = None;
    // Every Delaunay triangle (p, a, b) has an empty circumcircle whose centre is a vertex of
    // p's Voronoi cell: try all counter-clockwise pairs, keep the empty ones.
    for (ia, &a) in q.iter().enumerate() {
        for &b in &q[ia + 1..] {
            let (a, b) = if a.perp_dot(b) >= 0.0 { (a, b) } else { (b, a) };
            let cross = a.perp_dot(b);
            if cross <= 1e-12 * a.length() * b.length() {
                continue; // collinear with p: no finite circle
            }
            let c = DVec2::new(
                b.y * a.length_squared() - a.y * b.length_squared(),
                a.x * b.length_squared() - b.x * a.length_squared(),
            ) / (2.0 * cross);
            let r = c.length();
            if !(r.is_finite() && 2.0 * r <= reach) || best.is_some_and(|(_, rb)| r <= rb) {
                continue;
            }
            if q.iter().all(|x| x.distance(c) >= r * (1.0 - 1e-9)) {
                best = Some((c, r));
            }
        }
    }
    best.map(|(c, r)| (p + t1 * c.x + t2 * c.y, r))
}

/// Find up-sampling insertions for `points` (with unit `normals`) on `field`'s zero set.
pub fn upsample(
    points: &[DVec3],
    normals: &[DVec3],
    field: &GlobalField,
    opts: &UpsampleOptions,
) -> Vec<Insertion> {
    let all: Vec<usize> = (0..points.len()).collect();
    upsample_at(points, normals, field, opts, &all)
}

/// [`upsample`] around the points listed in `which` only (all points still count as
/// neighbours): the cost is O(|which|·k³), not O(N·k³).
pub fn upsample_at(
    points: &[DVec3],
    normals: &[DVec3],
    field: &GlobalField,
    opts: &UpsampleOptions,
    which: &[usize],
) -> Vec<Insertion> {
    let mut out: Vec<Insertion> = Vec::new();
    if points.len() < 4 || opts.max_gap.is_nan() || opts.max_gap <= 0.0 {
        return out;
    }
    let index = PointIndex::new(points);
    let mut hood = Vec::with_capacity(opts.k);
    for &i in which {
        let (p, n) = (points[i], normals[i]);
        hood.clear();
        hood.extend(
            index
                .nearest_k(p, opts.k + 1)
                .into_iter()
                .filter(|&(j, _)| j != i)
                .map(|(j, _)| points[j]),
        );
        let Some((c, r)) = largest_empty_circle(p, n, &hood) else {
            continue;
        };
        if r <= opts.max_gap {
            continue;
        }
        let proj = field.project_to_zero_set(c);
        let (_, g) = field.value_and_gradient(proj.point);
        let (Some(normal), true) = (g.try_normalize(), proj.point.is_finite()) else {
            continue;
        };
        let close = |x: &Insertion| x.position.distance(proj.point) < 0.5 * opts.max_gap;
        if !(proj.converged && proj.trusted) || out.iter().rev().take(64).any(close) {
            continue;
        }
        out.push(Insertion {
            position: proj.point,
            normal,
            parent: i,
        });
    }
    out
}

/// Merge points closer than `min_distance`: greedily in index order, each surviving point
/// absorbs the not-yet-merged points within `min_distance` whose normal agrees with its own
/// (within [`MERGE_MAX_ANGLE_COS`]); the cluster's mean position is projected onto `field`'s
/// zero set, normals and colours are averaged. Points on the two sides of a crease are never
/// merged: one point with their bisecting normal would fit a plane at 45° across the crease
/// and stand out of it as a fin (the ragged rim of a CSG difference).
pub fn downsample(points: &PointSet, field: &GlobalField, min_distance: f64) -> PointSet {
    let pos = &points.positions;
    if pos.is_empty() || min_distance.is_nan() || min_distance <= 0.0 {
        return points.clone();
    }
    let index = PointIndex::new(pos);
    let mut taken = vec![false; pos.len()];
    let mut out = PointSet {
        positions: Vec::new(),
        normals: points.normals.as_ref().map(|_| Vec::new()),
        colors: points.colors.as_ref().map(|_| Vec::new()),
    };
    for i in 0..pos.len() {
        if taken[i] {
            continue;
        }
        let mut cluster: Vec<usize> = index
            .within(pos[i], min_distance)
            .into_iter()
            .map(|(j, _)| j)
            .filter(|&j| !taken[j])
            .filter(|&j| {
                points
                    .normals
                    .as_ref()
                    .is_none_or(|n| n[j].dot(n[i]) >= MERGE_MAX_ANGLE_COS)
            })
            .collect();
        cluster.sort_unstable();
        if !cluster.contains(&i) {
            cluster.insert(0, i);
        }
        let mut mean = DVec3::ZERO;
        let (mut nsum, mut csum) = (DVec3::ZERO, [0u32; 3]);
        for &j in &cluster {
            taken[j] = true;
            mean += pos[j];
            if let Some(ns) = &points.normals {
                nsum += ns[j];
            }
            if let Some(cs) = &points.colors {
                for (s, c) in csum.iter_mut().zip(cs[j]) {
                    *s += u32::from(c);
                }
            }
        }
        let k = cluster.len();
        mean /= k as f64;
        let p = if k > 1 {
            let proj = field.project_to_zero_set(mean);
            if proj.converged && proj.trusted {
                proj.point
            } else {
                pos[i]
            }
        } else {
            pos[i]
        };
        out.positions.push(p);
        if let Some(ns) = out.normals.as_mut() {
            let given = points.normals.as_ref().map_or(DVec3::Z, |n| n[i]);
            ns.push(nsum.try_normalize().unwrap_or(given));
        }
        if let Some(cs) = out.colors.as_mut() {
            cs.push(csum.map(|s| ((s as f64 / k as f64).round()) as u8));
        }
    }
    out
}

/// Points [`downsample`] merges have normals within this cosine (about 25°).
pub const MERGE_MAX_ANGLE_COS: f64 = 0.9;

/// How many nearest points a spacing query looks through for one at a positive distance. A
/// mesh file repeats a vertex where its normals or texture split (two or three copies); a point
/// repeated more often than this counts no spacing.
pub const SPACING_NEIGHBOURS: usize = 8;

/// The set's spacing: the median distance from each point to its nearest *distinct* point.
/// Duplicates are skipped: with a mesh file's repeated seam vertices counted, the median could be
/// 0, and every length set from it (resampling, paint's rim points) with it. 0 when no two
/// points differ.
pub fn spacing(points: &[DVec3]) -> f64 {
    spacing_sampled(points, usize::MAX)
}

/// [`spacing`] estimated from at most `max_queries` evenly strided points (each against all
/// points): a big scan's spacing without a query per point.
pub fn spacing_sampled(points: &[DVec3], max_queries: usize) -> f64 {
    if points.len() < 2 || max_queries == 0 {
        return 0.0;
    }
    spacing_in(points, &PointIndex::new(points), max_queries).unwrap_or(0.0)
}

/// [`spacing_sampled`] over an index already built on `points`; `None` when no queried point
/// has a distinct point among its [`SPACING_NEIGHBOURS`] nearest.
pub fn spacing_in(points: &[DVec3], index: &PointIndex, max_queries: usize) -> Option<f64> {
    let stride = points.len().div_ceil(max_queries.max(1)).max(1);
    let mut nearest: Vec<f64> = points
        .par_chunks(stride)
        .filter_map(|chunk| {
            index
                .nearest_k(chunk[0], SPACING_NEIGHBOURS)
                .into_iter()
                .map(|(_, d)| d)
                .find(|d| *d > 0.0)
        })
        .collect();
    if nearest.is_empty() {
        return None;
    }
    nearest.par_sort_unstable_by(f64::total_cmp);
    Some(nearest[nearest.len() / 2])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spacing_skips_duplicates_and_needs_two_distinct_points() {
        let grid: Vec<DVec3> = (0..36)
            .map(|i| DVec3::new((i % 6) as f64, (i / 6) as f64, 0.0) * 0.25)
            .collect();
        assert_eq!(spacing(&grid), 0.25);
        // Every point twice (a mesh file repeats its seam vertices): counted, the duplicates
        // made the median 0.
        let doubled: Vec<DVec3> = grid.iter().chain(&grid).copied().collect();
        assert_eq!(spacing(&doubled), 0.25);
        assert_eq!(spacing_sampled(&doubled, 10), 0.25);
        assert_eq!(spacing(&[DVec3::ONE]), 0.0);
        assert_eq!(spacing(&[DVec3::ONE; 2]), 0.0);
        assert_eq!(spacing(&[DVec3::ONE; 3 * SPACING_NEIGHBOURS]), 0.0);
    }

    #[test]
    fn hexagon_cell_has_its_vertices_as_largest_circles() {
        // Unit hexagon of neighbours around the origin: the Voronoi vertices sit at distance
        // 1/√3 (circumradius of the equilateral triangles), on every pair.
        let ring: Vec<DVec3> = (0..6)
            .map(|k| {
                let a = k as f64 * std::f64::consts::FRAC_PI_3;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .chain((0..6).map(|k| {
                let a = (k as f64 + 0.5) * std::f64::consts::FRAC_PI_3;
                DVec3::new(a.cos(), a.sin(), 0.0) * 3f64.sqrt()
            }))
            .collect();
        let (c, r) = largest_empty_circle(DVec3::ZERO, DVec3::Z, &ring).unwrap();
        assert!((r - 1.0 / 3f64.sqrt()).abs() < 1e-12, "{r}");
        assert!(c.z.abs() < 1e-12);
    }
}
