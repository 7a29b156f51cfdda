//! Per-point data derived from each point's nearest neighbours (the elliptical splat, from the
//! [`K`] nearest: [`NeighbourShape`]), kept up to date incrementally as points move, turn,
//! appear and disappear.
//!
//! [`NeighbourCache::rebuild`] computes every point's [`NeighbourShape`] with the k-d tree (in
//! parallel) and indexes the points twice: in a hash grid of cells two typical radii wide (for
//! neighbour searches) and by reach, on levels of cells that double in size (for "whose ball
//! holds this place"); [`NeighbourCache::update`] then applies [`Edits`] in O(changed points ·
//! neighbours): a point's shape depends only on its own normal and the positions and normals
//! of the points inside its ball of radius `reach` (the distance to the farthest of the
//! [`SEARCH`] nearest, by position), so only points whose ball a changed point left, entered or
//! turned in, and the changed points themselves, are recomputed, by a ring search of the grid.
//! The k-d tree is never rebuilt on this path.
//!
//! The shape is the one place that reads the neighbours ([`NeighbourShape::from_nearest`]): its
//! ball is the one its search reached, so the incremental rule above holds for it.
//!
//! Contract: after any sequence of updates the shapes equal a [`NeighbourCache::rebuild`] of
//! the same positions and normals (the tests compare bit for bit). Large edits (over a quarter
//! of the points) fall back to a rebuild.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::DVec3;
use rayon::prelude::*;
use sim_core::knn::PointIndex;

/// Neighbours a shape is derived from (the point itself not counted): within the 10–16
/// [`render::splat_shape`] asks for, so the neighbours across the sparse direction of an
/// anisotropic sampling (a scan's rows) are among them.
pub const K: usize = 12;

/// Nearest points a shape's search asks for, the point itself included: one more than the
/// shape uses ([`NeighbourShape::from_nearest`]).
pub const SEARCH: usize = K + 2;

/// Radius of every point when there are at most [`K`] points (no K-th neighbour), m.
pub const LONE_RADIUS: f32 = 1e-3;

/// Recomputations above this many run on the worker pool.
const PARALLEL_FROM: usize = 20_000;

/// Rings a k-NN search scans before it falls back to checking every point.
const MAX_RINGS: i32 = 32;

/// What a splat takes from its point's neighbours: an ellipse in the tangent plane
/// ([`render::splat_shape`]), sized by the local spacing and stretched where the sampling is
/// anisotropic.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NeighbourShape {
    /// Major semi-axis (m), at least 1 µm.
    pub radius: f32,
    /// Minor semi-axis (m, ≤ `radius`).
    pub minor_radius: f32,
    /// Major axis, a unit tangent; zero for a disk of `radius`.
    pub axis: [f32; 3],
    /// Normal curvatures in the frame `(axis, plane_normal × axis)`, 1/m, positive where the
    /// surface bends away from `plane_normal` ([`render::Splat::curvature`]).
    pub curvature: [f32; 3],
    /// The neighbours' own plane normal the shape was computed in (its sign is arbitrary: the
    /// curvature's sign is relative to it).
    pub plane_normal: [f32; 3],
    /// Growth to the Voronoi cell's corners ([`render::Splat::cell_growth`]).
    pub cell_growth: f32,
}

impl NeighbourShape {
    /// A disk of `radius` m.
    pub fn disk(radius: f32) -> Self {
        Self {
            radius,
            minor_radius: radius,
            axis: [0.0; 3],
            curvature: [0.0; 3],
            plane_normal: [0.0; 3],
            cell_growth: 1.0,
        }
    }

    /// The curvature relative to a point's unit `normal`, in the renderer's frame
    /// `(axis, normal × axis)`. When the neighbours' plane normal points the other way the form
    /// changes sign and so does the frame's second axis: `k_aa` and `k_bb` flip, `k_ab` stays.
    pub fn curvature_along(&self, normal: DVec3) -> [f32; 3] {
        let [aa, ab, bb] = self.curvature;
        if normal.dot(DVec3::from(self.plane_normal.map(f64::from))) < 0.0 {
            [-aa, ab, -bb]
        } else {
            self.curvature
        }
    }

    /// The shape of point `p` with normal `n` from its [`SEARCH`] nearest points (itself
    /// included), nearest first, as `(index, distance)`; `positions` and `normals` are all
    /// points'. It uses the neighbours strictly nearer than the last one given, at most [`K`]:
    /// the same set whichever of several equally far points a search returned last (two
    /// coincident points facing apart, a sheet of no thickness, would otherwise give a shape
    /// that depends on the search's order).
    ///
    /// Only neighbours on the point's own sheet count: one whose normal faces away from `n`
    /// (the other side of a part thinner than the spacing, an ear or a blade) would tilt the
    /// plane across the part and read its thickness as curvature, and the splat would stand
    /// out of the surface as a petal ([`on_own_sheet`]). The tangent plane is the kept
    /// neighbours' own (the least principal axis of their spread about the point); the
    /// renderer lays the axis into the plane of the point's actual normal. The ellipse is
    /// scaled down, if need be, to reach no farther than the nearest neighbour across a bend
    /// ([`ACROSS_A_BEND`]; the renderer's growth to the cell's corners, at most
    /// [`render::MAX_CELL_GROWTH`] where the splat faces the eye, comes on top). Degenerate
    /// neighbourhoods (collinear, coincident, all facing away) fall back to a disk through the
    /// farthest neighbour used.
    pub fn from_nearest(
        p: DVec3,
        n: DVec3,
        nearest: &[(u32, f64)],
        positions: &[DVec3],
        normals: &[DVec3],
    ) -> Self {
        let bound = match nearest.last() {
            Some(&(_, d)) if nearest.len() >= SEARCH => d,
            _ => f64::INFINITY,
        };
        let used = || nearest.iter().filter(|x| x.1 > 0.0 && x.1 < bound).take(K);
        let far = used().map(|x| x.1).fold(0.0, f64::max);
        let disk = Self::disk(if far > 0.0 {
            far
        } else {
            f64::from(LONE_RADIUS)
        } as f32);
        let mut neighbours = [[0.0f32; 3]; K];
        let mut count = 0;
        let mut cov = glam::DMat3::ZERO;
        // The nearest neighbour across a bend: how far the tangent plane holds.
        let mut bend = f64::INFINITY;
        for &(j, distance) in used() {
            let m = normals[j as usize];
            if !on_own_sheet(n, m) {
                continue;
            }
            if n.dot(m) < ACROSS_A_BEND * n.length() * m.length() {
                bend = bend.min(distance);
            }
            let d = positions[j as usize] - p;
            cov += glam::DMat3::from_cols(d * d.x, d * d.y, d * d.z);
            neighbours[count] = positions[j as usize].as_vec3().to_array();
            count += 1;
        }
        let Some((_, vectors)) = sim_core::linalg::sym3_eigen(cov) else {
            return disk;
        };
        let plane_normal = vectors[0].as_vec3().to_array();
        match render::splat_shape(p.as_vec3().to_array(), plane_normal, &neighbours[..count]) {
            Some(s) if s.radius.is_finite() && s.radius > 0.0 => {
                let f = (bend / f64::from(s.radius)).min(1.0) as f32;
                let (radius, minor_radius) = (s.radius * f, s.minor_radius * f);
                Self {
                    radius: radius.max(1e-6),
                    minor_radius: minor_radius.clamp(1e-6, radius.max(1e-6)),
                    axis: s.axis,
                    curvature: s.curvature,
                    plane_normal,
                    cell_growth: s.cell_growth,
                }
            }
            _ => disk,
        }
    }
}

/// A neighbour whose normal is further than this (cosine, about 37°) from a point's lies across
/// a bend: a crease, or a curve sharper than the spacing resolves. The point's splat, flat or
/// curved in its own tangent plane, stands for the surface only up to there, so it reaches no
/// farther than the nearest such neighbour (beyond, it stood out of the surface as a lobe along
/// every sharp edge and past every thin rim). The tolerance is the one the splat already allows
/// a normal against its neighbours' plane ([`crate::live::frames::NORMAL_AGREES`]).
pub const ACROSS_A_BEND: f64 = super::frames::NORMAL_AGREES;

/// Whether a neighbour with normal `m` is on the sheet of a point with normal `n`: it does not
/// face away (`n·m ≥ 0`; a zero or non-finite normal faces nowhere and keeps every neighbour).
/// Two sides of a part thinner than the spacing face apart; a rim between them is 90° from both
/// and still belongs to each.
pub fn on_own_sheet(n: DVec3, m: DVec3) -> bool {
    n.dot(m) >= 0.0 || !n.dot(m).is_finite()
}

/// Every point's shape and reach (the farthest of its [`SEARCH`] nearest) from scratch, with a
/// k-d tree on all cores; at most [`K`] points: lone disks of unbounded reach.
pub fn shapes_and_reach(positions: &[DVec3], normals: &[DVec3]) -> (Vec<NeighbourShape>, Vec<f64>) {
    if positions.len() <= K {
        return (
            vec![NeighbourShape::disk(LONE_RADIUS); positions.len()],
            vec![f64::INFINITY; positions.len()],
        );
    }
    let tree = PointIndex::new(positions);
    positions
        .par_iter()
        .with_min_len(1024)
        .zip(normals)
        .map(|(&p, &n)| {
            let near: Vec<(u32, f64)> = tree
                .nearest_k(p, SEARCH)
                .into_iter()
                .map(|(j, d)| (j as u32, d))
                .collect();
            let reach = near.last().map_or(0.0, |x| x.1);
            (
                NeighbourShape::from_nearest(p, n, &near, positions, normals),
                reach,
            )
        })
        .unzip()
}

/// Changes to apply: the new point count and the new positions and normals of the points that
/// changed. Points at or beyond `len` are removed; every index in `old len..len` must be in
/// `set`.
#[derive(Debug, Clone, Default)]
pub struct Edits {
    /// New number of points.
    pub len: usize,
    /// `(index, new position, new normal)` of moved, turned or appended points (indices below
    /// `len`).
    pub set: Vec<(u32, DVec3, DVec3)>,
}

#[derive(Default)]
struct CellHasher(u64);

impl Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
    fn write_i32(&mut self, v: i32) {
        self.0 = (self.0.rotate_left(21) ^ (v as u32 as u64)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }
}

type Cells = HashMap<[i32; 3], Vec<u32>, BuildHasherDefault<CellHasher>>;

/// Points binned in cubic cells, updated point by point.
#[derive(Debug, Clone, Default)]
struct CellIndex {
    cell: f64,
    cells: Cells,
}

impl CellIndex {
    fn new(cell: f64, positions: &[DVec3]) -> Self {
        let mut s = Self {
            cell,
            cells: Cells::default(),
        };
        for (i, &p) in positions.iter().enumerate() {
            s.insert(i as u32, p);
        }
        s
    }

    fn key(&self, p: DVec3) -> [i32; 3] {
        let k = (p / self.cell).floor();
        [k.x, k.y, k.z].map(|v| v.clamp(-1e9, 1e9) as i32)
    }

    fn insert(&mut self, i: u32, p: DVec3) {
        self.cells.entry(self.key(p)).or_default().push(i);
    }

    fn remove(&mut self, i: u32, p: DVec3) {
        let key = self.key(p);
        if let Some(v) = self.cells.get_mut(&key) {
            if let Some(at) = v.iter().position(|&x| x == i) {
                v.swap_remove(at);
            }
            if v.is_empty() {
                self.cells.remove(&key);
            }
        }
    }

    /// Visit every point in the cells at Chebyshev ring `r` around `c`.
    fn ring(&self, c: [i32; 3], r: i32, mut visit: impl FnMut(u32)) {
        for dz in -r..=r {
            for dy in -r..=r {
                let edge = dz.abs() == r || dy.abs() == r;
                let step = if edge { 1 } else { (2 * r).max(1) };
                let mut dx = -r;
                while dx <= r {
                    if let Some(v) = self.cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                        v.iter().for_each(|&i| visit(i));
                    }
                    dx += step;
                }
            }
        }
    }

    /// The `k` nearest of `positions` to `p` (`(index, distance)`, nearest first) into `out`.
    fn nearest(&self, p: DVec3, k: usize, positions: &[DVec3], out: &mut Vec<(u32, f64)>) {
        out.clear();
        let c = self.key(p);
        // `out` holds squared distances while searching, sorted ascending.
        let offer = |out: &mut Vec<(u32, f64)>, i: u32| {
            let d2 = (positions[i as usize] - p).length_squared();
            if out.len() == k && d2 >= out[k - 1].1 {
                return;
            }
            let at = out.partition_point(|x| x.1 <= d2);
            if out.len() == k {
                out.pop();
            }
            out.insert(at, (i, d2));
        };
        let mut r = 0;
        loop {
            self.ring(c, r, |i| offer(out, i));
            // Unseen points are farther than r cells.
            let bound = (r as f64 * self.cell) * (1.0 - 1e-9);
            if out.len() == k && out[k - 1].1 <= bound * bound {
                break;
            }
            r += 1;
            if r > MAX_RINGS {
                out.clear();
                for i in 0..positions.len() as u32 {
                    offer(out, i);
                }
                break;
            }
        }
        for x in out.iter_mut() {
            x.1 = x.1.max(0.0).sqrt();
        }
    }
}

/// Points binned by how far their shape reaches: a point of reach `r` sits on the lowest level
/// whose cells (edge `base·2ˡ`) are at least `r` wide, in the cell holding it. Every point whose
/// ball contains `x` is then in the 3×3×3 cells around `x` on some level.
#[derive(Debug, Clone, Default)]
struct ReachIndex {
    base: f64,
    levels: Vec<Cells>,
}

impl ReachIndex {
    const MAX_LEVELS: usize = 24;

    fn level_of(&self, reach: f64) -> Option<usize> {
        if !reach.is_finite() {
            return None;
        }
        let l = (reach / self.base).max(1.0).log2().ceil() as usize;
        Some(l.min(Self::MAX_LEVELS - 1))
    }

    fn key(&self, l: usize, p: DVec3) -> [i32; 3] {
        let k = (p / (self.base * (1u64 << l) as f64)).floor();
        [k.x, k.y, k.z].map(|v| v.clamp(-1e9, 1e9) as i32)
    }

    fn insert(&mut self, i: u32, p: DVec3, reach: f64) {
        if let Some(l) = self.level_of(reach) {
            if self.levels.len() <= l {
                self.levels.resize(l + 1, Cells::default());
            }
            let key = self.key(l, p);
            self.levels[l].entry(key).or_default().push(i);
        }
    }

    fn remove(&mut self, i: u32, p: DVec3, reach: f64) {
        let Some(l) = self.level_of(reach) else {
            return;
        };
        let key = self.key(l, p);
        if let Some(v) = self.levels.get_mut(l).and_then(|c| c.get_mut(&key)) {
            if let Some(at) = v.iter().position(|&x| x == i) {
                v.swap_remove(at);
            }
            if v.is_empty() {
                self.levels[l].remove(&key);
            }
        }
    }

    /// Visit every point whose cell is next to `x`'s on its level (a superset of the points
    /// whose ball holds `x`).
    fn around(&self, x: DVec3, mut visit: impl FnMut(u32)) {
        for (l, cells) in self.levels.iter().enumerate() {
            if cells.is_empty() {
                continue;
            }
            let c = self.key(l, x);
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        if let Some(v) = cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                            v.iter().for_each(|&i| visit(i));
                        }
                    }
                }
            }
        }
    }
}

/// Neighbour-derived shapes of a point set, updated incrementally; see the module doc.
#[derive(Debug, Default)]
pub struct NeighbourCache {
    positions: Vec<DVec3>,
    /// Normals, which pick the neighbours on each point's own sheet.
    normals: Vec<DVec3>,
    shapes: Vec<NeighbourShape>,
    /// Distance to the farthest of the [`SEARCH`] nearest (the ball the shape depends on);
    /// `inf` with ≤ K points.
    reach: Vec<f64>,
    /// Positions by place, for neighbour searches.
    index: CellIndex,
    /// Positions by reach, for "whose ball holds this place".
    balls: ReachIndex,
    /// Scratch: per point, the update that last marked it.
    marked: Vec<u32>,
    epoch: u32,
    affected: Vec<u32>,
    rebuilds: u64,
}

impl NeighbourCache {
    /// Positions the shapes are for.
    pub fn positions(&self) -> &[DVec3] {
        &self.positions
    }

    /// Normals the shapes are for.
    pub fn normals(&self) -> &[DVec3] {
        &self.normals
    }

    /// Shapes, one per point.
    pub fn shapes(&self) -> &[NeighbourShape] {
        &self.shapes
    }

    /// The points the last update recomputed (sorted).
    pub fn affected(&self) -> &[u32] {
        &self.affected
    }

    /// Full rebuilds so far (the first one included).
    pub fn rebuilds(&self) -> u64 {
        self.rebuilds
    }

    /// Recompute every shape for `positions` and `normals` (k-d tree, all cores) and re-index.
    pub fn rebuild(&mut self, positions: Vec<DVec3>, normals: Vec<DVec3>) {
        assert_eq!(positions.len(), normals.len(), "a normal per position");
        self.rebuilds += 1;
        let n = positions.len();
        self.positions = positions;
        self.normals = normals;
        self.marked = vec![0; n];
        self.epoch = 0;
        (self.shapes, self.reach) = shapes_and_reach(&self.positions, &self.normals);
        if n <= K {
            self.index = CellIndex::default();
            self.balls = ReachIndex::default();
            return;
        }
        let mut sorted: Vec<f64> = self.reach.iter().copied().filter(|r| *r > 0.0).collect();
        let typical = if sorted.is_empty() {
            1e-3
        } else {
            let mid = sorted.len() / 2;
            *sorted.select_nth_unstable_by(mid, f64::total_cmp).1
        };
        // Search cells twice the typical reach: one ring around a point usually holds its K.
        self.index = CellIndex::new(2.0 * typical, &self.positions);
        self.balls = ReachIndex {
            base: typical,
            levels: Vec::new(),
        };
        for i in 0..n {
            self.balls
                .insert(i as u32, self.positions[i], self.reach[i]);
        }
    }

    /// Apply `edits`; returns the points whose shape was recomputed (sorted; after a rebuild,
    /// every point).
    pub fn update(&mut self, edits: &Edits) -> &[u32] {
        let (old, new) = (self.positions.len(), edits.len);
        let removed = old.saturating_sub(new);
        let big = 4 * (edits.set.len() + removed) > new.max(old);
        if old <= K || new <= K || big || self.rebuilds == 0 {
            let mut p = std::mem::take(&mut self.positions);
            let mut n = std::mem::take(&mut self.normals);
            p.resize(new, DVec3::NAN);
            n.resize(new, DVec3::NAN);
            for &(i, x, m) in &edits.set {
                p[i as usize] = x;
                n[i as usize] = m;
            }
            self.rebuild(p, n);
            self.affected = (0..new as u32).collect();
            return &self.affected;
        }
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            self.marked.fill(0);
            self.epoch = 1;
        }
        // Positions that left a ball (old places) and entered one (new places).
        let mut places: Vec<DVec3> = Vec::with_capacity(2 * edits.set.len() + removed);
        for i in new..old {
            let p = self.positions[i];
            self.index.remove(i as u32, p);
            self.balls.remove(i as u32, p, self.reach[i]);
            places.push(p);
        }
        self.positions.truncate(new);
        self.normals.truncate(new);
        self.shapes.truncate(new);
        self.reach.truncate(new);
        self.positions.resize(new, DVec3::NAN);
        self.normals.resize(new, DVec3::NAN);
        self.shapes.resize(new, NeighbourShape::default());
        self.reach.resize(new, f64::INFINITY);
        self.marked.resize(new, 0);
        self.affected.clear();
        for &(i, x, m) in &edits.set {
            let iu = i as usize;
            self.normals[iu] = m;
            if iu < old {
                let was = self.positions[iu];
                self.index.remove(i, was);
                self.balls.remove(i, was, self.reach[iu]);
                places.push(was);
            }
            self.positions[iu] = x;
            self.index.insert(i, x);
            places.push(x);
            if self.marked[iu] != self.epoch {
                self.marked[iu] = self.epoch;
                self.affected.push(i);
            }
        }
        // Every point whose ball held a place now or before.
        for &x in &places {
            let (reach, marked, epoch, pos) =
                (&self.reach, &mut self.marked, self.epoch, &self.positions);
            let affected = &mut self.affected;
            self.balls.around(x, |q| {
                let qu = q as usize;
                if marked[qu] != epoch && pos[qu].distance(x) <= reach[qu] {
                    marked[qu] = epoch;
                    affected.push(q);
                }
            });
        }
        debug_assert!(
            self.positions.iter().all(|p| !p.is_nan()),
            "an appended index was not set"
        );
        // Recompute the affected shapes against the updated index.
        // On this thread unless the work is large: the shared worker pool is busy with the
        // simulation's points, and waiting for it costs more than a few thousand searches.
        let (index, pos, normals) = (&self.index, &self.positions, &self.normals);
        let one = |near: &mut Vec<(u32, f64)>, q: u32| {
            let (p, n) = (pos[q as usize], normals[q as usize]);
            index.nearest(p, SEARCH, pos, near);
            let reach = near.last().map_or(0.0, |x| x.1);
            (
                NeighbourShape::from_nearest(p, n, near, pos, normals),
                reach,
            )
        };
        let fresh: Vec<(NeighbourShape, f64)> = if self.affected.len() < PARALLEL_FROM {
            let mut near = Vec::with_capacity(SEARCH);
            self.affected.iter().map(|&q| one(&mut near, q)).collect()
        } else {
            self.affected
                .par_iter()
                .with_min_len(1024)
                .map_init(Vec::new, |near, &q| one(near, q))
                .collect()
        };
        for (k, (shape, reach)) in fresh.into_iter().enumerate() {
            let q = self.affected[k] as usize;
            let p = self.positions[q];
            // A moved point's entry went with its old place above; this finds nothing then.
            self.balls.remove(q as u32, p, self.reach[q]);
            self.shapes[q] = shape;
            self.reach[q] = reach;
            self.balls.insert(q as u32, p, reach);
        }
        self.affected.sort_unstable();
        &self.affected
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SplitMix64: seeded test inputs without a dependency.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^ (z >> 31)
        }
        fn unit(&mut self) -> f64 {
            (self.next() >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.unit()
        }
        fn below(&mut self, n: usize) -> usize {
            (self.next() % n as u64) as usize
        }
    }

    fn sphere(n: usize, seed: u64) -> Vec<DVec3> {
        let mut rng = Rng(seed);
        (0..n)
            .map(|_| {
                let v = DVec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                );
                v.normalize_or(DVec3::Z) * 0.05
            })
            .collect()
    }

    /// The outward normals of points on a sphere about the origin.
    fn outward(p: &[DVec3]) -> Vec<DVec3> {
        p.iter().map(|x| x.normalize_or(DVec3::Z)).collect()
    }

    fn full(p: &[DVec3], n: &[DVec3]) -> Vec<NeighbourShape> {
        let mut c = NeighbourCache::default();
        c.rebuild(p.to_vec(), n.to_vec());
        c.shapes().to_vec()
    }

    fn apply(p: &mut Vec<DVec3>, n: &mut Vec<DVec3>, e: &Edits) {
        p.resize(e.len, DVec3::NAN);
        n.resize(e.len, DVec3::NAN);
        for &(i, x, m) in &e.set {
            p[i as usize] = x;
            n[i as usize] = m;
        }
    }

    #[test]
    fn incremental_shapes_equal_a_full_recompute_after_moves_turns_insertions_and_deletions() {
        let mut p = sphere(5000, 1);
        let mut n = outward(&p);
        let mut c = NeighbourCache::default();
        c.rebuild(p.clone(), n.clone());
        assert_eq!(c.shapes(), full(&p, &n));
        let mut rng = Rng(7);
        for round in 0..15 {
            let len = p.len();
            let mut e = Edits {
                len,
                set: Vec::new(),
            };
            match round % 5 {
                // A bump: points near the pole pushed out along the normal.
                0 => {
                    for (i, x) in p.iter().enumerate() {
                        let d = x.distance(DVec3::new(0.0, 0.0, 0.05));
                        if d < 0.015 {
                            let y = *x * (1.0 + 0.2 * (1.0 - d / 0.015));
                            e.set.push((i as u32, y, y.normalize()));
                        }
                    }
                }
                // Insertions near random points (a duplicate, and some facing inward: the
                // other side of a sheet, which their neighbours must leave out).
                1 => {
                    for k in 0..50 {
                        let j = rng.below(len);
                        let off = DVec3::new(rng.range(-1e-3, 1e-3), 0.0, 1e-4);
                        let x = if k == 0 { p[j] } else { p[j] + off };
                        let m = if k % 3 == 0 { -n[j] } else { n[j] };
                        e.set.push(((len + k) as u32, x, m));
                    }
                    e.len = len + 50;
                }
                // Deletions: swap-remove style (the last points move into the holes), then
                // the tail is cut.
                2 => {
                    for k in 0..40 {
                        let hole = rng.below(len - 40);
                        e.set.push((hole as u32, p[len - 1 - k], n[len - 1 - k]));
                    }
                    e.set.sort_by_key(|x| x.0);
                    e.set.dedup_by_key(|x| x.0);
                    e.len = len - 40;
                }
                // Turns without moves: normals flipped or tilted in place.
                3 => {
                    for k in 0..60 {
                        let j = rng.below(len);
                        let m = if k % 2 == 0 {
                            -n[j]
                        } else {
                            (n[j] + DVec3::new(0.3, -0.2, 0.1)).normalize()
                        };
                        e.set.push((j as u32, p[j], m));
                    }
                    e.set.sort_by_key(|x| x.0);
                    e.set.dedup_by_key(|x| x.0);
                }
                // Random jitter of scattered points (far-apart changes).
                _ => {
                    for _ in 0..100 {
                        let j = rng.below(len);
                        e.set.push((j as u32, p[j] * rng.range(0.98, 1.02), n[j]));
                    }
                    e.set.sort_by_key(|x| x.0);
                    e.set.dedup_by_key(|x| x.0);
                }
            }
            apply(&mut p, &mut n, &e);
            let affected = c.update(&e).len();
            // Each place a point left or entered lies in about SEARCH balls (as many as a ball
            // holds points), so the work is O(changed points · neighbours), not O(points).
            let places = 2 * e.set.len() + len.saturating_sub(e.len);
            assert!(
                affected <= 2 * SEARCH * places && affected < p.len() / 3,
                "round {round}: {affected} recomputed for {places} places"
            );
            assert_eq!(c.positions(), &p[..]);
            assert_eq!(c.shapes(), full(&p, &n), "round {round}");
        }
        assert_eq!(c.rebuilds(), 1, "no fallback to a rebuild");
    }

    /// A thin oblate ellipsoid (a leaf: semi-axes 40 × 25 × 1.5 mm) sampled by `n` points
    /// from a fixed golden-ratio spiral, with its outward normals.
    fn leaf(n: usize) -> (Vec<DVec3>, Vec<DVec3>) {
        let axes = DVec3::new(0.04, 0.025, 0.0015);
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let a = i as f64 * 0.618_033_988_75 * std::f64::consts::TAU;
                let r = (1.0 - z * z).sqrt();
                let u = DVec3::new(r * a.cos(), r * a.sin(), z);
                (u * axes, (u / axes).normalize())
            })
            .unzip()
    }

    /// Where a part is thinner than the spacing of its points (a 3 mm leaf sampled every
    /// 3–5 mm, like the coarse bunny's ears), the points of the far side are among each point's
    /// nearest. Taken in, they tilted the plane across the part (the splat then stood on edge,
    /// a petal) and their height read as a curvature of hundreds per metre (lumpy shading).
    #[test]
    fn a_splat_on_a_part_thinner_than_the_spacing_is_shaped_by_its_own_side() {
        let (p, n) = leaf(600);
        let mut c = NeighbourCache::default();
        c.rebuild(p.clone(), n.clone());
        let (mut inner, mut far_side_near) = (0, 0);
        for ((x, m), s) in p.iter().zip(&n).zip(c.shapes()) {
            // The flat middle of either face, where the leaf bends by less than 3/m.
            if (x.x / 0.04).powi(2) + (x.y / 0.025).powi(2) > 0.5 {
                continue;
            }
            inner += 1;
            let mut near = vec![];
            for (j, y) in p.iter().enumerate() {
                if y != x && y.distance(*x) <= f64::from(s.radius) && n[j].dot(*m) < 0.0 {
                    near.push(j);
                }
            }
            far_side_near += usize::from(!near.is_empty());
            let plane = DVec3::from(s.plane_normal.map(f64::from));
            assert!(
                plane.dot(*m).abs() > 0.99,
                "{x}: plane {plane} across the leaf"
            );
            let k = s.curvature.iter().fold(0f32, |a, k| a.max(k.abs()));
            assert!(k < 30.0, "{x}: curvature {k}/m on a face bending by < 3/m");
        }
        assert!(inner > 100, "{inner} points in the middle");
        assert!(
            far_side_near > inner / 2,
            "the far side is within the splats' reach: {far_side_near} of {inner}"
        );
    }

    /// How far the splat of shape `s` at `p` (normal `n`) reaches out of the solid
    /// `x ≤ 0, z ≤ 0`: the largest `x` or `z` on its ellipse (m).
    fn protrusion(p: DVec3, n: DVec3, s: &NeighbourShape) -> f64 {
        let a = DVec3::from(s.axis.map(f64::from));
        let b = n.cross(a);
        let (r1, r2) = (f64::from(s.radius), f64::from(s.minor_radius));
        let reach = |e: DVec3| (r1 * a.dot(e)).hypot(r2 * b.dot(e));
        (p.x + reach(DVec3::X)).max(p.z + reach(DVec3::Z))
    }

    /// A box edge sampled like a mesh's vertices: the top face (z = 0, x ≤ 0) and the side
    /// (x = 0, z ≤ 0) on a 2 mm grid, the edge's own points with the two faces' mean normal.
    /// A splat there used to reach as far as its farthest ring neighbour on either face and
    /// stand out of the edge as a lobe; it now stops at the nearest neighbour across the bend.
    #[test]
    fn splats_along_a_sharp_edge_do_not_stand_out_of_it() {
        let h = 0.002;
        let (mut p, mut n) = (vec![], vec![]);
        for j in -10..=10 {
            let y = f64::from(j) * h + f64::from(j * j % 7) * 1e-6;
            p.push(DVec3::new(0.0, y, 0.0));
            n.push(DVec3::new(1.0, 0.0, 1.0).normalize());
            for i in 1..=8 {
                let t = f64::from(i) * h;
                p.push(DVec3::new(-t, y, 0.0));
                n.push(DVec3::Z);
                p.push(DVec3::new(0.0, y, -t));
                n.push(DVec3::X);
            }
        }
        let mut c = NeighbourCache::default();
        c.rebuild(p.clone(), n.clone());
        let (mut worst_edge, mut worst_face) = (0f64, 0f64);
        for ((x, m), s) in p.iter().zip(&n).zip(c.shapes()) {
            // Away from the grid's own ends.
            if x.y.abs() > 6.0 * h || x.x.min(x.z) < -5.0 * h {
                continue;
            }
            let out = protrusion(*x, *m, s);
            if x.x == 0.0 && x.z == 0.0 {
                worst_edge = worst_edge.max(out);
            } else {
                worst_face = worst_face.max(out);
            }
        }
        // Without the stop: 0.71 h and 0.46 h; with it 0.50 h and 0.25 h.
        assert!(
            worst_edge < 0.6 * h,
            "edge splats stand out by {worst_edge} m"
        );
        assert!(
            worst_face < 0.35 * h,
            "face splats stand out by {worst_face} m"
        );
    }

    #[test]
    fn few_points_get_the_lone_radius_and_growing_past_k_computes_radii() {
        let mut c = NeighbourCache::default();
        let p = sphere(4, 3);
        c.rebuild(p.clone(), outward(&p));
        assert!(c.shapes().iter().all(|s| s.radius == LONE_RADIUS));
        let more = sphere(20, 4);
        let e = Edits {
            len: 20,
            set: more
                .iter()
                .enumerate()
                .map(|(i, &x)| (i as u32, x, x.normalize()))
                .collect(),
        };
        c.update(&e);
        assert_eq!(c.shapes(), full(&more, &outward(&more)));
        assert!(c.shapes().iter().all(|s| s.radius != LONE_RADIUS));
    }

    #[test]
    fn the_curvature_is_the_surfaces_whichever_way_the_normals_point() {
        // The cylinder z = −½·κ·(x cos 30° + y sin 30°)², κ = 20/m, bending away from +z along
        // a direction that is neither axis of the sampling grid (1 mm × 1.5 mm): the normal
        // curvature along a tangent w is κ (w·d)² for d that direction, relative to +z.
        let d = DVec3::new(30f64.to_radians().cos(), 30f64.to_radians().sin(), 0.0);
        let kappa = 20.0;
        let pts: Vec<DVec3> = (-6..=6)
            .flat_map(|i| (-6..=6).map(move |j| (i, j)))
            .map(|(i, j)| {
                let (x, y) = (i as f64 * 0.001, j as f64 * 0.0015);
                let s = x * d.x + y * d.y;
                DVec3::new(x, y, -0.5 * kappa * s * s)
            })
            .collect();
        let mut c = NeighbourCache::default();
        let up = vec![DVec3::Z; pts.len()];
        c.rebuild(pts, up);
        let shape = c.shapes()[6 * 13 + 6];
        let a = DVec3::from(shape.axis.map(f64::from));
        for n in [DVec3::Z, -DVec3::Z] {
            let [kaa, kab, kbb] = shape.curvature_along(n).map(f64::from);
            let b = n.cross(a);
            let form = |w: DVec3| {
                let (x, y) = (w.dot(a), w.dot(b));
                kaa * x * x + 2.0 * kab * x * y + kbb * y * y
            };
            // Relative to n: +κ(w·d)² for +z, −κ(w·d)² for −z.
            let sign = n.z;
            for w in [
                d,
                DVec3::X,
                DVec3::Y,
                DVec3::new(1.0, -1.0, 0.0).normalize(),
            ] {
                let want = sign * kappa * w.dot(d).powi(2);
                assert!(
                    (form(w) - want).abs() < 0.5,
                    "{n} {w}: {} vs {want}",
                    form(w)
                );
            }
        }
    }

    #[test]
    fn rows_of_a_scan_give_ellipses_across_the_rows_and_an_even_sampling_gives_disks() {
        // A tilted plane sampled like a range scan: 1 mm along the rows, 3 mm between them.
        let (t1, t2) = (DVec3::new(1.0, 0.0, 0.3).normalize(), DVec3::Y);
        let n = t1.cross(t2);
        let grid = |h1: f64, h2: f64| -> Vec<DVec3> {
            (0..40)
                .flat_map(|i| (0..40).map(move |j| (i, j)))
                .map(|(i, j)| {
                    // A little jitter, so no two distances tie.
                    let w = ((i * 40 + j) as f64 * 0.618_034).fract() * 1e-5;
                    t1 * (i as f64 * h1 + w) + t2 * (j as f64 * h2 - w)
                })
                .collect()
        };
        let mut c = NeighbourCache::default();
        c.rebuild(grid(0.001, 0.003), vec![n; 1600]);
        let s = c.shapes()[20 * 40 + 20];
        let axis = DVec3::from(s.axis.map(f64::from));
        assert!(
            axis.dot(t2).abs() > 0.95,
            "major axis across the rows: {s:?}"
        );
        assert!(axis.dot(n).abs() < 1e-3, "axis in the tangent plane: {s:?}");
        assert!(s.minor_radius < 0.8 * s.radius, "{s:?}");
        // Reaches across the 3 mm to the next row and the 1 mm to the next sample; the minor
        // axis also covers the six nearest (up to 3 mm along the row, `splat_shape`), at the
        // flattest aspect it allows.
        assert!((0.003..0.0055).contains(&f64::from(s.radius)), "{s:?}");
        assert!(
            (0.001..0.0035).contains(&f64::from(s.minor_radius)),
            "{s:?}"
        );
        // Even sampling (a hexagonal lattice, 2 mm): round.
        let hex: Vec<DVec3> = (0..40)
            .flat_map(|i| (0..40).map(move |j| (i, j)))
            .map(|(i, j)| {
                let w = ((i * 40 + j) as f64 * 0.618_034).fract() * 1e-6;
                let x = (i as f64 + 0.5 * (j % 2) as f64) * 0.002 + w;
                t1 * x + t2 * (j as f64 * 0.002 * 0.75f64.sqrt())
            })
            .collect();
        c.rebuild(hex, vec![n; 1600]);
        let s = c.shapes()[20 * 40 + 20];
        assert!(s.minor_radius >= 0.95 * s.radius, "{s:?}");
        assert!((0.0019..0.0025).contains(&f64::from(s.radius)), "{s:?}");
    }
}
