//! Per-point data derived from each point's nearest neighbours (the elliptical splat, from the
//! [`K`] nearest: [`NeighbourShape`]), kept up to date incrementally as points move, appear and
//! disappear.
//!
//! [`NeighbourCache::rebuild`] computes every point's [`NeighbourShape`] with the k-d tree (in
//! parallel) and indexes the points twice: in a hash grid of cells two typical radii wide (for
//! neighbour searches) and by reach, on levels of cells that double in size (for "whose ball
//! holds this place"); [`NeighbourCache::update`] then applies [`Edits`] in O(changed points · neighbours): a
//! point's shape depends only on the points inside its ball of radius `reach` (its K-th
//! neighbour distance), so only points whose ball a changed point left or entered, and the
//! changed points themselves, are recomputed, by a ring search of the grid. The k-d tree is
//! never rebuilt on this path.
//!
//! The shape is the one place that reads the neighbours ([`NeighbourShape::from_nearest`]): its
//! ball is the K-th neighbour's, so the incremental rule above holds for it.
//!
//! Contract: after any sequence of updates the shapes equal a [`NeighbourCache::rebuild`] of
//! the same positions (the tests compare bit for bit). Large edits (over a quarter of the
//! points) fall back to a rebuild.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::DVec3;
use rayon::prelude::*;
use sim_core::knn::PointIndex;

/// Neighbours a shape is derived from (the point itself not counted): within the 10–16
/// [`render::splat_shape`] asks for, so the neighbours across the sparse direction of an
/// anisotropic sampling (a scan's rows) are among them.
pub const K: usize = 12;

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

    /// The shape of a point from its `K + 1` nearest points (itself included), nearest first,
    /// as `(index, distance)`; `positions` are all points. The tangent plane is the
    /// neighbours' own (the least principal axis of their spread about the point), so the
    /// shape depends on positions only and the cache's incremental rule holds; the renderer
    /// lays the axis into the plane of the point's actual normal. Degenerate neighbourhoods
    /// (collinear, coincident) fall back to a disk through the K-th neighbour.
    pub fn from_nearest(p: DVec3, nearest: &[(u32, f64)], positions: &[DVec3]) -> Self {
        let disk = Self::disk(
            nearest
                .last()
                .map_or(f64::from(LONE_RADIUS), |x| x.1.max(1e-6)) as f32,
        );
        let mut neighbours = [[0.0f32; 3]; K];
        let mut count = 0;
        let mut cov = glam::DMat3::ZERO;
        for &(j, _) in nearest.iter().filter(|x| x.1 > 0.0).take(K) {
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
            Some(s) if s.radius.is_finite() && s.radius > 0.0 => Self {
                radius: s.radius.max(1e-6),
                minor_radius: s.minor_radius.clamp(1e-6, s.radius.max(1e-6)),
                axis: s.axis,
                curvature: s.curvature,
                plane_normal,
                cell_growth: s.cell_growth,
            },
            _ => disk,
        }
    }
}

/// Every point's shape and reach (its K-th neighbour's distance) from scratch, with a k-d tree
/// on all cores; at most [`K`] points: lone disks of unbounded reach.
pub fn shapes_and_reach(positions: &[DVec3]) -> (Vec<NeighbourShape>, Vec<f64>) {
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
        .map(|&p| {
            let near: Vec<(u32, f64)> = tree
                .nearest_k(p, K + 1)
                .into_iter()
                .map(|(j, d)| (j as u32, d))
                .collect();
            let reach = near.last().map_or(0.0, |x| x.1);
            (NeighbourShape::from_nearest(p, &near, positions), reach)
        })
        .unzip()
}

/// Changes to apply: the new point count and the new positions of the points that changed.
/// Points at or beyond `len` are removed; every index in `old len..len` must be in `set`.
#[derive(Debug, Clone, Default)]
pub struct Edits {
    /// New number of points.
    pub len: usize,
    /// `(index, new position)` of moved or appended points (indices below `len`).
    pub set: Vec<(u32, DVec3)>,
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
    shapes: Vec<NeighbourShape>,
    /// Distance to the K-th neighbour (the ball the shape depends on); `inf` with ≤ K points.
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

    /// Recompute every shape for `positions` (k-d tree, all cores) and re-index.
    pub fn rebuild(&mut self, positions: Vec<DVec3>) {
        self.rebuilds += 1;
        let n = positions.len();
        self.positions = positions;
        self.marked = vec![0; n];
        self.epoch = 0;
        (self.shapes, self.reach) = shapes_and_reach(&self.positions);
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
            p.resize(new, DVec3::NAN);
            for &(i, x) in &edits.set {
                p[i as usize] = x;
            }
            self.rebuild(p);
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
        self.shapes.truncate(new);
        self.reach.truncate(new);
        self.positions.resize(new, DVec3::NAN);
        self.shapes.resize(new, NeighbourShape::default());
        self.reach.resize(new, f64::INFINITY);
        self.marked.resize(new, 0);
        self.affected.clear();
        for &(i, x) in &edits.set {
            let iu = i as usize;
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
        let (index, pos) = (&self.index, &self.positions);
        let one = |near: &mut Vec<(u32, f64)>, q: u32| {
            let p = pos[q as usize];
            index.nearest(p, K + 1, pos, near);
            let reach = near.last().map_or(0.0, |x| x.1);
            (NeighbourShape::from_nearest(p, near, pos), reach)
        };
        let fresh: Vec<(NeighbourShape, f64)> = if self.affected.len() < PARALLEL_FROM {
            let mut near = Vec::with_capacity(K + 1);
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

    fn full(p: &[DVec3]) -> Vec<NeighbourShape> {
        let mut c = NeighbourCache::default();
        c.rebuild(p.to_vec());
        c.shapes().to_vec()
    }

    fn apply(p: &mut Vec<DVec3>, e: &Edits) {
        p.resize(e.len, DVec3::NAN);
        for &(i, x) in &e.set {
            p[i as usize] = x;
        }
    }

    #[test]
    fn incremental_shapes_equal_a_full_recompute_after_moves_insertions_and_deletions() {
        let mut p = sphere(5000, 1);
        let mut c = NeighbourCache::default();
        c.rebuild(p.clone());
        assert_eq!(c.shapes(), full(&p));
        let mut rng = Rng(7);
        for round in 0..12 {
            let n = p.len();
            let mut e = Edits {
                len: n,
                set: Vec::new(),
            };
            match round % 4 {
                // A bump: points near the pole pushed out along the normal.
                0 => {
                    for (i, x) in p.iter().enumerate() {
                        let d = x.distance(DVec3::new(0.0, 0.0, 0.05));
                        if d < 0.015 {
                            e.set.push((i as u32, *x * (1.0 + 0.2 * (1.0 - d / 0.015))));
                        }
                    }
                }
                // Insertions near random points (and a duplicate).
                1 => {
                    for k in 0..50 {
                        let j = rng.below(n);
                        let off = DVec3::new(rng.range(-1e-3, 1e-3), 0.0, 1e-4);
                        let x = if k == 0 { p[j] } else { p[j] + off };
                        e.set.push(((n + k) as u32, x));
                    }
                    e.len = n + 50;
                }
                // Deletions: swap-remove style (the last points move into the holes), then
                // the tail is cut.
                2 => {
                    for k in 0..40 {
                        let hole = rng.below(n - 40);
                        e.set.push((hole as u32, p[n - 1 - k]));
                    }
                    e.set.sort_by_key(|x| x.0);
                    e.set.dedup_by_key(|x| x.0);
                    e.len = n - 40;
                }
                // Random jitter of scattered points (far-apart changes).
                _ => {
                    for _ in 0..100 {
                        let j = rng.below(n);
                        e.set.push((j as u32, p[j] * rng.range(0.98, 1.02)));
                    }
                    e.set.sort_by_key(|x| x.0);
                    e.set.dedup_by_key(|x| x.0);
                }
            }
            apply(&mut p, &e);
            let affected = c.update(&e).len();
            assert!(
                affected < p.len() / 4,
                "round {round}: {affected} recomputed"
            );
            assert_eq!(c.positions(), &p[..]);
            assert_eq!(c.shapes(), full(&p), "round {round}");
        }
        assert_eq!(c.rebuilds(), 1, "no fallback to a rebuild");
    }

    #[test]
    fn few_points_get_the_lone_radius_and_growing_past_k_computes_radii() {
        let mut c = NeighbourCache::default();
        let p = sphere(4, 3);
        c.rebuild(p.clone());
        assert!(c.shapes().iter().all(|s| s.radius == LONE_RADIUS));
        let more = sphere(20, 4);
        let e = Edits {
            len: 20,
            set: more
                .iter()
                .enumerate()
                .map(|(i, &x)| (i as u32, x))
                .collect(),
        };
        c.update(&e);
        assert_eq!(c.shapes(), full(&more));
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
        c.rebuild(pts);
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
        c.rebuild(grid(0.001, 0.003));
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
        c.rebuild(hex);
        let s = c.shapes()[20 * 40 + 20];
        assert!(s.minor_radius >= 0.95 * s.radius, "{s:?}");
        assert!((0.0019..0.0025).contains(&f64::from(s.radius)), "{s:?}");
    }
}
