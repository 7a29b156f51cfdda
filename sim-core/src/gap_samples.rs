//! Gap samples: points added to a static surface's points where they leave a gap that the
//! points' own fits would only extrapolate across
//! ([`FitParams::gap_samples`](crate::local_fit::FitParams::gap_samples)).
//!
//! A local fit follows its neighbours; across a gap among them (the wide triangles of a CAD
//! mesh's faces, a scan's sparse band) it carries their curvature on, and where the fits of the
//! gap's sides meet, the blend sags or bulges. A query-centred fit (APSS, MLS) fits afresh at
//! every place, the gap included, so it does not. A gap sample brings that answer into the
//! gap: a position on the algebraic sphere fitted there the way APSS fits (Guennebaud & Gross
//! 2007: per-point radii `hⱼ`, weights `(1 − d²/hⱼ²)⁴`), with the sphere's normal. The samples
//! then join the points (the field's build, [`crate::field::GlobalField::build`]): they take
//! part in the k-NN rows, so the fits around a gap reach across it with their own
//! neighbourhood radius, and get a field where the thinning gives them one. They do not vouch
//! for the zero set: the field trusts where the points alone would, with the points' own trust
//! radii. (As extra fit rows only, with no k-NN row or field of their own, seven of the bench's
//! 42 figures stayed behind APSS's; as trust witnesses too, with the radii the samples shrink,
//! they opened holes in closed shapes: docs/BENCHMARKS.md, "Gap samples".)
//!
//! Where: the midpoint of each point and each of its [`NEIGHBOURS`] nearest that lies at least
//! `clearance` of its nearest point's radius `rⱼ` (the distance to that point's
//! [`NEIGHBOURS`]-th nearest) from every point; sites are then kept `clearance · r` apart, the
//! sparsest first. Each site takes [`PROJECTIONS`] steps onto the sphere fitted there to the
//! points within `hⱼ = REACH · rⱼ` of it. A sample is dropped when it moved more than
//! [`MOVE`] of its site's radius (no sphere explains the gap), when the sphere is convex and
//! tighter than [`MIN_SPHERE_RADIUS`] site radii (a tip or a thin tube the points do not pin
//! down; a tight concave one, a groove or the inner side of a crease, is bounded by the points
//! around it and keeps its samples), when a
//! neighbour faces more than acos([`FACING`]) away from the sphere's normal (the far side of a
//! thin part), or when its neighbours' weighted mean leans off it along the tangent plane by
//! more than [`LEAN`] of their RMS distance (a rim or a hole's edge: the points do not
//! surround it).
//!
//! Contract: [`place`] is deterministic, runs at build time on all cores and allocates; its
//! inputs are the field build's, validated finite. Every sample returned is finite with a unit
//! normal that faces the way its neighbours' do.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::DVec3;
use rayon::prelude::*;

use crate::knn::KnnGraph;
use crate::spatial::{MulHasher, SupportGrid, cell_of, key};

/// Neighbours per point that give the gap sites and the radius `rⱼ`.
pub const NEIGHBOURS: usize = 16;

/// Projection steps onto the fitted sphere.
pub const PROJECTIONS: usize = 3;

/// The sphere at a site is fitted to the points within `REACH · rⱼ` of it.
pub const REACH: f64 = 0.9;

/// The most a sample may move from its site, in the site's radii.
pub const MOVE: f64 = 0.25;

/// The least cosine between a neighbour's normal and the sphere's normal (107°).
pub const FACING: f64 = -0.3;

/// The most the neighbours' weighted mean may lean along the tangent plane, in their RMS
/// distance from the sample.
pub const LEAN: f64 = 0.5;

/// The least radius of a convex fitted sphere, in the site's radii: a tighter one (the tip of
/// a thin tail, a tube the points sample a few times round) is one the points do not pin down,
/// and a sample on it can make the fits around it close off a blob of their own (the cow's tail
/// tip did, 12 triangles apart from the mesh, with no such test or at 0.75). 1.0 and 1.25 keep
/// it whole too, with other figures behind APSS's (docs/BENCHMARKS.md, "Gap samples"). A
/// concave sphere is not tested: samples in grooves and inner creases are bounded by the points
/// on either side (homer's mouth gets them, and its max goes 1.12 → 0.78× APSS's).
pub const MIN_SPHERE_RADIUS: f64 = 1.5;

/// A sample in a gap: a position on the sphere fitted there, and its outward unit normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GapSample {
    /// Position.
    pub position: DVec3,
    /// Outward unit normal.
    pub normal: DVec3,
}

/// The gap samples among `points` (unit outward `normals`), from their k-NN graph `knn` (rows
/// of at least two; the first [`NEIGHBOURS`] others of each row are used) and leaving out the
/// `outlier` points. `clearance` (in `(0, 1)`) is the least distance of a site from every point
/// and between sites, in radii `rⱼ`. See the module docs.
pub fn place(
    points: &[DVec3],
    normals: &[DVec3],
    knn: &KnnGraph,
    outlier: &[bool],
    clearance: f64,
) -> Vec<GapSample> {
    let used = NEIGHBOURS.min(knn.k().saturating_sub(1));
    if used == 0 || !positive(clearance) {
        return Vec::new();
    }
    let radius = |i: usize| knn.distances(i).get(used).copied().unwrap_or(0.0);
    let radii: Vec<f64> = (0..points.len())
        .map(|i| if outlier[i] { 0.0 } else { radius(i) })
        .collect();
    let sites = sites(points, knn, &radii, used, clearance);
    let reach: Vec<f64> = radii.iter().map(|r| REACH * r).collect();
    let mut typical: Vec<f64> = radii.iter().copied().filter(|r| *r > 0.0).collect();
    if typical.is_empty() {
        return Vec::new();
    }
    let mid = typical.len() / 2;
    let typical = *typical.select_nth_unstable_by(mid, f64::total_cmp).1;
    let grid = SupportGrid::new(points, &reach, 2.0 * REACH * typical);
    sites
        .par_iter()
        .filter_map(|&(site, r)| {
            let sample = project(site, r, normals, &reach, &grid)?;
            (sample.position.distance(site) <= MOVE * r).then_some(sample)
        })
        .collect()
}

/// The gap sites, each with its nearest point's radius: midpoints of point–neighbour pairs clear
/// of every point by `clearance · rⱼ`, then thinned to `clearance · r` apart, widest first.
fn sites(
    points: &[DVec3],
    knn: &KnnGraph,
    radii: &[f64],
    used: usize,
    clearance: f64,
) -> Vec<(DVec3, f64)> {
    let mut found: Vec<(DVec3, f64, u64)> = (0..points.len())
        .into_par_iter()
        .filter(|&i| radii[i] > 0.0)
        .flat_map_iter(|i| {
            let row = knn.neighbours(i);
            row[1..=used.min(row.len() - 1)]
                .iter()
                .enumerate()
                .filter(move |&(_, &j)| (j as usize) > i && radii[j as usize] > 0.0)
                .filter_map(move |(m, &j)| {
                    let mid = 0.5 * (points[i] + points[j as usize]);
                    // Every point within |pᵢ − pⱼ| of pᵢ is in its row, so the midpoint's
                    // nearest point is too.
                    let (near, gap) = row
                        .iter()
                        .map(|&o| (o as usize, points[o as usize].distance(mid)))
                        .filter(|&(o, _)| radii[o] > 0.0)
                        .min_by(|a, b| a.1.total_cmp(&b.1))?;
                    let r = radii[near];
                    (gap >= clearance * r).then_some((mid, r, (i as u64) << 8 | m as u64))
                })
        })
        .collect();
    // Widest first; ties in the order they were found (deterministic).
    found.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.2.cmp(&b.2)));
    let Some(&(_, widest, _)) = found.first() else {
        return Vec::new();
    };
    // Cells twice the widest clearance: a site's clearance ball then spans two cells along
    // each axis at most, its own and the one on the nearer side, so 8 lookups find every kept
    // site it must clear (27 lookups in cells one clearance wide took the airplane's 30k
    // candidates 15–24 ms, these 6–8 ms: the lookups, not the distance checks, are the cost).
    let cell = 2.0 * clearance * widest;
    // Keys wrap far out (cells then share one): a query sees a superset, and checks distances.
    let mut grid: HashMap<u64, Vec<u32>, BuildHasherDefault<MulHasher>> = HashMap::default();
    let mut kept: Vec<(DVec3, f64)> = Vec::new();
    for &(x, r, _) in &found {
        let c = cell_of(x, cell);
        let side = (x / cell)
            .to_array()
            .map(|t| if t - t.floor() < 0.5 { -1 } else { 1 });
        let reach2 = (clearance * r).powi(2);
        let near = [0, side[2]].into_iter().any(|dz| {
            [0, side[1]].into_iter().any(|dy| {
                [0, side[0]].into_iter().any(|dx| {
                    grid.get(&key([c[0] + dx, c[1] + dy, c[2] + dz]))
                        .is_some_and(|list| {
                            list.iter()
                                .any(|&o| kept[o as usize].0.distance_squared(x) < reach2)
                        })
                })
            })
        });
        if !near {
            grid.entry(key(c)).or_default().push(kept.len() as u32);
            kept.push((x, r));
        }
    }
    kept
}

/// [`PROJECTIONS`] steps from `site` (whose nearest point's radius is `r`) onto the weighted
/// algebraic sphere of the points whose reach (`grid`, radii `reach`) holds it; the sample, or
/// `None` where it fails a test of the module docs (the move is the caller's).
fn project(
    site: DVec3,
    r: f64,
    normals: &[DVec3],
    reach: &[f64],
    grid: &SupportGrid,
) -> Option<GapSample> {
    let mut x = site;
    let mut last = None;
    for _ in 0..PROJECTIONS {
        if !x.is_finite() {
            return None;
        }
        let sphere = Sphere::fit(x, normals, reach, grid)?;
        let step = sphere.step()?;
        last = Some((x, sphere, step));
        x += step;
    }
    let (from, sphere, step) = last?;
    // `a > 0`: the neighbours' normals spread apart, a convex sphere (see `MIN_SPHERE_RADIUS`).
    if sphere.a > 0.0 && sphere.radius() < MIN_SPHERE_RADIUS * r {
        return None;
    }
    let mut g = (sphere.u + 2.0 * sphere.a * step).try_normalize()?;
    if g.dot(sphere.mean_normal) < 0.0 {
        g = -g;
    }
    // The tests, on the last fit's neighbours as seen from the sample.
    let (mut sum_w, mut mean, mut sum_rr, mut facing) = (0.0, DVec3::ZERO, 0.0, true);
    grid.for_each_containing(from, |j, rel, d2| {
        let w = weight(d2, reach[j]);
        let r = -rel - step;
        sum_w += w;
        mean += w * r;
        sum_rr += w * r.length_squared();
        facing &= normals[j].dot(g) >= FACING;
    });
    if !facing || !positive(sum_w) {
        return None;
    }
    mean /= sum_w;
    let lean = (mean - g * mean.dot(g)).length();
    (lean <= LEAN * (sum_rr / sum_w).sqrt() && x.is_finite()).then_some(GapSample {
        position: x,
        normal: g,
    })
}

/// `x > 0` (false for NaN).
fn positive(x: f64) -> bool {
    x > 0.0
}

/// APSS's weight `(1 − d²/h²)⁴` of a point at squared distance `d2` with reach `h`.
fn weight(d2: f64, h: f64) -> f64 {
    let t = 1.0 - d2 / (h * h);
    let t2 = t * t;
    t2 * t2
}

/// The algebraic sphere `u₀ + u·y + a·|y|²` (in `y = p − x`, from the query `x`) fitted to the
/// points and normals around `x` (Guennebaud & Gross 2007, Eq. 4–6), with its neighbours'
/// weighted mean normal.
#[derive(Debug, Clone, Copy)]
struct Sphere {
    constant: f64,
    u: DVec3,
    a: f64,
    mean_normal: DVec3,
    /// Weighted mean of `|y|²`, to judge whether `a` is a plane's.
    mean_d2: f64,
}

impl Sphere {
    /// The fit at `x`; `None` with fewer than four neighbours.
    fn fit(x: DVec3, normals: &[DVec3], reach: &[f64], grid: &SupportGrid) -> Option<Self> {
        let (mut sw, mut sp, mut sn, mut spn, mut spp) = (0.0, DVec3::ZERO, DVec3::ZERO, 0.0, 0.0);
        let mut count = 0;
        grid.for_each_containing(x, |j, rel, d2| {
            let (q, n, w) = (-rel, normals[j], weight(d2, reach[j]));
            sw += w;
            sp += w * q;
            sn += w * n;
            spn += w * q.dot(n);
            spp += w * d2;
            count += 1;
        });
        if count < 4 || !positive(sw) {
            return None;
        }
        let (mp, mn, mpn, mpp) = (sp / sw, sn / sw, spn / sw, spp / sw);
        let spread = mpp - mp.dot(mp);
        let a = if spread > 0.0 {
            0.5 * (mpn - mp.dot(mn)) / spread
        } else {
            0.0
        };
        let u = mn - 2.0 * a * mp;
        Some(Self {
            constant: -u.dot(mp) - a * mpp,
            u,
            a,
            mean_normal: mn,
            mean_d2: mpp,
        })
    }

    /// The sphere's centre and squared radius (relative to the query), or `None` for a plane.
    fn centre(&self) -> Option<(DVec3, f64)> {
        let (u, a, c) = (self.u, self.a, self.constant);
        if a.abs() * self.mean_d2.sqrt() < 1e-9 * u.length() {
            return None;
        }
        let centre = -u / (2.0 * a);
        Some((centre, centre.length_squared() - c / a))
    }

    /// The sphere's radius (infinite for a plane, 0 for an imaginary sphere).
    fn radius(&self) -> f64 {
        self.centre()
            .map_or(f64::INFINITY, |(_, rho2)| rho2.max(0.0).sqrt())
    }

    /// From the query (the origin of `y`) to the nearest point of the sphere (or plane);
    /// `None` where the sphere is imaginary.
    fn step(&self) -> Option<DVec3> {
        let Some((centre, rho2)) = self.centre() else {
            let (u, c) = (self.u, self.constant);
            let uu = u.length_squared();
            return (uu > 0.0).then(|| -u * (c / uu));
        };
        if !positive(rho2) {
            return None;
        }
        Some(centre - centre.try_normalize()? * rho2.sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::knn::PointIndex;

    /// Gap samples of `points` with the fit's k-NN graph (k = 20) and no outliers.
    fn samples(points: &[DVec3], normals: &[DVec3]) -> Vec<GapSample> {
        let knn = KnnGraph::build(points, &PointIndex::new(points), 20);
        place(points, normals, &knn, &vec![false; points.len()], 0.3)
    }

    /// `n` points sampled at random on a sphere of `radius` (uneven: gaps of every width),
    /// with their outward normals.
    fn sphere(n: usize, radius: f64) -> (Vec<DVec3>, Vec<DVec3>) {
        let set = crate::sampling::Shape::Sphere { radius }.sample(n, 7);
        let normals = set.normals.expect("a sampled shape has normals");
        (set.positions, normals)
    }

    /// A square grid in the plane z = `z`, spacing 1, `half` cells either side of the origin,
    /// facing `normal`.
    fn grid(half: i32, z: f64, normal: DVec3) -> (Vec<DVec3>, Vec<DVec3>) {
        let points: Vec<DVec3> = (-half..=half)
            .flat_map(|i| (-half..=half).map(move |j| DVec3::new(i as f64, j as f64, z)))
            .collect();
        let normals = vec![normal; points.len()];
        (points, normals)
    }

    #[test]
    fn samples_on_a_sphere_lie_on_it_facing_out() {
        let (points, normals) = sphere(2000, 10.0);
        let found = samples(&points, &normals);
        assert!(found.len() > 100, "{} samples", found.len());
        for s in &found {
            // APSS's sphere through points on a sphere is that sphere.
            assert!(
                (s.position.length() - 10.0).abs() < 1e-6,
                "{:?}",
                s.position
            );
            assert!(s.normal.dot(s.position.normalize()) > 1.0 - 1e-9);
            assert!((s.normal.length() - 1.0).abs() < 1e-12);
        }
        // Each sits in a gap: clear of every point by 0.3 of its radius (more than 0.3 × the
        // spacing), and the sites were kept apart.
        let index = PointIndex::new(&points);
        for s in &found {
            assert!(index.nearest(s.position).1 > 0.3, "{:?}", s.position);
        }
        assert_eq!(found, samples(&points, &normals), "deterministic");
    }

    #[test]
    fn sites_are_the_greedy_pass_over_every_pair() {
        // Uneven gaps (random points, radii varying over 1.5×, checked): the grid's 8 cells
        // must find every kept site a brute-force pass over all of them finds.
        let (points, _) = sphere(3000, 10.0);
        let knn = KnnGraph::build(&points, &PointIndex::new(&points), 20);
        let radii: Vec<f64> = (0..points.len())
            .map(|i| knn.distances(i)[NEIGHBOURS])
            .collect();
        let spread = radii.iter().copied().fold(0.0, f64::max)
            / radii.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(spread > 1.5, "radii vary {spread:.2}×");
        let kept = sites(&points, &knn, &radii, NEIGHBOURS, 0.3);
        // The same candidates, widest first, each kept unless a kept one lies within its
        // clearance.
        let mut brute: Vec<(DVec3, f64)> = Vec::new();
        let all = sites(&points, &knn, &radii, NEIGHBOURS, 1e-9);
        assert!(all.len() > kept.len() * 2, "{} candidates", all.len());
        let index = PointIndex::new(&points);
        for &(x, r) in &all {
            let clear = index.nearest(x).1 >= 0.3 * r;
            if clear && brute.iter().all(|o| o.0.distance(x) >= 0.3 * r) {
                brute.push((x, r));
            }
        }
        assert_eq!(kept, brute);
    }

    #[test]
    fn a_plane_gets_samples_on_it_inside_its_rim() {
        let (points, normals) = grid(8, 0.0, DVec3::Z);
        let found = samples(&points, &normals);
        // The cell centres are 0.71 from their corners, a gap of 0.3 × the radius (2.2).
        assert!(found.len() > 50, "{} samples", found.len());
        for s in &found {
            assert!(s.position.z.abs() < 1e-9 && s.normal.dot(DVec3::Z) > 1.0 - 1e-12);
            // Between the points, never past the rim.
            assert!(
                s.position.x.abs() < 8.0 && s.position.y.abs() < 8.0,
                "{:?}",
                s.position
            );
        }
    }

    #[test]
    fn no_sample_between_the_two_sheets_of_a_thin_part() {
        // Two sheets 0.8 apart facing away from each other: a midpoint between them is clear of
        // both, and the sphere fitted there sees normals facing both ways.
        let (mut points, mut normals) = grid(6, 0.4, DVec3::Z);
        let (lower, lower_normals) = grid(6, -0.4, -DVec3::Z);
        points.extend(lower);
        normals.extend(lower_normals);
        for s in samples(&points, &normals) {
            assert!((s.position.z.abs() - 0.4).abs() < 1e-9, "{:?}", s.position);
            assert!(s.normal.dot(DVec3::Z * s.position.z.signum()) > 1.0 - 1e-12);
        }
    }

    #[test]
    fn no_sample_on_a_convex_sphere_tighter_than_its_gaps() {
        // 60 points round a sphere of radius 1: each point's 16th neighbour lies about 1.1 away,
        // so the sphere is tighter than 1.5 radii (a tail's tip, a tube a few points round).
        let (points, normals) = sphere(60, 1.0);
        assert!(samples(&points, &normals).is_empty());
        // Seen from inside (a cavity: the normals point at the centre) the sphere is concave,
        // which the points bound: it keeps its samples, on it and facing in.
        let inward: Vec<DVec3> = normals.iter().map(|n| -*n).collect();
        let found = samples(&points, &inward);
        assert!(!found.is_empty());
        for s in &found {
            assert!((s.position.length() - 1.0).abs() < 1e-6, "{:?}", s.position);
            assert!(s.normal.dot(-s.position.normalize()) > 1.0 - 1e-9);
        }
        // The same sphere sampled finely enough for its gaps gets samples.
        let (points, normals) = sphere(2000, 1.0);
        assert!(!samples(&points, &normals).is_empty());
    }

    #[test]
    fn off_gives_nothing() {
        let (points, normals) = sphere(500, 1.0);
        let knn = KnnGraph::build(&points, &PointIndex::new(&points), 20);
        assert!(place(&points, &normals, &knn, &vec![false; 500], 0.0).is_empty());
        // A graph too small to hold a neighbour.
        let one = KnnGraph::build(&points, &PointIndex::new(&points), 1);
        assert!(place(&points, &normals, &one, &vec![false; 500], 0.3).is_empty());
        // Every point an outlier.
        assert!(place(&points, &normals, &knn, &vec![true; 500], 0.3).is_empty());
    }
}
