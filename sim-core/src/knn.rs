//! Nearest-neighbour queries over a fixed point set: a k-d tree (`kiddo`'s immutable tree, which
//! tolerates duplicate and coplanar points) and the k-NN graph used by normals and fits (found
//! in a uniform grid of cells, with the tree where a cell's block cannot prove a row).
//!
//! Contract: built once (a graph may then be shrunk per point, [`KnnGraph::shrink`], before
//! use), then immutable, `Send + Sync`; [`PointIndex::nearest`] does not allocate.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;
use std::sync::Arc;

use glam::DVec3;
use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use rayon::prelude::*;

use crate::spatial::{KEY_BITS, MulHasher, cell_of, key};

/// A k-d tree over positions, returning indices into the original slice.
pub struct PointIndex {
    tree: ImmutableKdTree<f64, u32, 3, 32>,
    len: usize,
}

impl std::fmt::Debug for PointIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PointIndex")
            .field("len", &self.len)
            .finish_non_exhaustive()
    }
}

impl PointIndex {
    /// Build the tree. `points` must be non-empty and finite (see `PointSet::validate`).
    pub fn new(points: &[DVec3]) -> Self {
        assert!(!points.is_empty(), "PointIndex needs at least one point");
        assert!(points.len() < u32::MAX as usize, "at most 2³²−1 points");
        let coords: Vec<[f64; 3]> = points.iter().map(|p| p.to_array()).collect();
        Self {
            tree: ImmutableKdTree::new_from_slice(&coords),
            len: points.len(),
        }
    }

    /// Number of indexed points.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Always `false`: an index holds at least one point.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Index of and distance to the nearest point. Allocation-free.
    pub fn nearest(&self, x: DVec3) -> (usize, f64) {
        let nn = self.tree.nearest_one::<SquaredEuclidean>(&x.to_array());
        (nn.item as usize, nn.distance.max(0.0).sqrt())
    }

    /// All points within `radius` of `x` as `(index, distance)`, in no particular order.
    pub fn within(&self, x: DVec3, radius: f64) -> Vec<(usize, f64)> {
        self.tree
            .within_unsorted::<SquaredEuclidean>(&x.to_array(), radius * radius)
            .into_iter()
            .map(|nn| (nn.item as usize, nn.distance.max(0.0).sqrt()))
            .collect()
    }

    /// The `k` nearest points to `x` as `(index, distance)`, nearest first.
    pub fn nearest_k(&self, x: DVec3, k: usize) -> Vec<(usize, f64)> {
        self.nearest_k_within_squared(x, k, f64::INFINITY)
    }

    /// [`PointIndex::nearest_k`] among the points at most `√radius2` from `x`: the same
    /// answer where at least `k` lie there, found sooner the tighter the bound.
    fn nearest_k_within_squared(&self, x: DVec3, k: usize, radius2: f64) -> Vec<(usize, f64)> {
        let Some(k) = std::num::NonZero::new(k.min(self.len)) else {
            return Vec::new();
        };
        self.tree
            .nearest_n_within::<SquaredEuclidean>(&x.to_array(), radius2, k, true)
            .into_iter()
            .map(|nn| (nn.item as usize, nn.distance.max(0.0).sqrt()))
            .collect()
    }
}

/// For every point, its `k` nearest points (itself first), stored row by row.
#[derive(Debug, Clone, PartialEq)]
pub struct KnnGraph {
    k: usize,
    /// Each point's `k` rows, shared by clones (a shrunk copy only adds `counts`).
    rows: Arc<Rows>,
    /// How many of each point's `k` listed neighbours are in use (empty: all of them); see
    /// [`KnnGraph::shrink`].
    counts: Vec<u32>,
}

impl KnnGraph {
    /// The `k` nearest of every point (k is capped at the point count, ≥ 1): the point itself,
    /// then its `k − 1` nearest others by distance. Runs on all cores.
    ///
    /// Points are bucketed in a uniform grid whose cells are about a typical neighbourhood
    /// radius wide (measured with `index`); each cell gathers the points of its 3 × 3 × 3 block
    /// once and every point in it picks its nearest from those. That answer is exact when the
    /// farthest one picked lies nearer than the block's walls; a point where it does not (a
    /// sparse region) asks `index`, only as far out as that farthest one (its row lies within).
    /// Where distances tie, a row from the grid takes the lower index first, one from the tree
    /// the tree's order.
    pub fn build(points: &[DVec3], index: &PointIndex, k: usize) -> Self {
        let k = k.clamp(1, points.len());
        match CellGrid::new(points, index, k) {
            Some(grid) => Self::from_grid(points, index, k, &grid),
            None => Self::from_tree(points, index, k),
        }
    }

    /// [`KnnGraph::build`] by one k-d tree search per point.
    fn from_tree(points: &[DVec3], index: &PointIndex, k: usize) -> Self {
        let mut neighbours = vec![0u32; points.len() * k];
        let mut distances = vec![0.0; points.len() * k];
        neighbours
            .par_chunks_mut(k)
            .zip(distances.par_chunks_mut(k))
            .enumerate()
            .for_each(|(i, (nb, ds))| tree_row(points, index, i, f64::INFINITY, nb, ds));
        Self {
            k,
            rows: Arc::new(Rows {
                neighbours,
                distances,
            }),
            counts: Vec::new(),
        }
    }

    /// [`KnnGraph::build`] over the cells of `grid`: rows are found in cell order (a cell's
    /// points share its block's candidates) and then moved to point order.
    fn from_grid(points: &[DVec3], index: &PointIndex, k: usize, grid: &CellGrid) -> Self {
        let n = points.len();
        let mut sorted_nb = vec![0u32; n * k];
        let mut sorted_ds = vec![0.0; n * k];
        const CHUNK: usize = 256;
        sorted_nb
            .par_chunks_mut(k * CHUNK)
            .zip(sorted_ds.par_chunks_mut(k * CHUNK))
            .enumerate()
            .for_each_init(
                || (Vec::new(), Vec::new(), (u64::MAX, [0i64; 3])),
                |(candidates, near, cell), (chunk, (nbs, dss))| {
                    for (o, (nb, ds)) in nbs.chunks_mut(k).zip(dss.chunks_mut(k)).enumerate() {
                        let (key, i) = grid.order[chunk * CHUNK + o];
                        if key != cell.0 {
                            *cell = (key, grid.cell_of(points[i as usize]));
                            grid.gather_block(cell.1, points, candidates);
                        }
                        if let Err(bound) =
                            grid_row(points, grid, cell.1, i as usize, candidates, near, nb, ds)
                        {
                            tree_row(points, index, i as usize, bound, nb, ds);
                        }
                    }
                },
            );
        let mut neighbours = vec![0u32; n * k];
        let mut distances = vec![0.0; n * k];
        let mut at = vec![0u32; n];
        for (s, &(_, i)) in grid.order.iter().enumerate() {
            at[i as usize] = s as u32;
        }
        neighbours
            .par_chunks_mut(k)
            .zip(distances.par_chunks_mut(k))
            .zip(&at)
            .for_each(|((nb, ds), &s)| {
                let s = s as usize;
                nb.copy_from_slice(&sorted_nb[s * k..(s + 1) * k]);
                ds.copy_from_slice(&sorted_ds[s * k..(s + 1) * k]);
            });
        Self {
            k,
            rows: Arc::new(Rows {
                neighbours,
                distances,
            }),
            counts: Vec::new(),
        }
    }

    /// Use only the first `count(i)` neighbours of each point `i` (clamped to `1..=k`): a
    /// smaller neighbourhood where the caller finds the nearest ones suffice. `count` sees the
    /// point's full list of neighbours and distances.
    pub fn shrink(&mut self, count: impl Fn(usize, &[u32], &[f64]) -> usize + Sync) {
        let k = self.k;
        self.counts = (0..self.len())
            .into_par_iter()
            .map(|i| {
                let range = i * k..(i + 1) * k;
                let c = count(
                    i,
                    &self.rows.neighbours[range.clone()],
                    &self.rows.distances[range],
                );
                c.clamp(1, k) as u32
            })
            .collect();
    }

    /// Neighbours per point (including the point itself) before any [`KnnGraph::shrink`]:
    /// the most any point has.
    pub fn k(&self) -> usize {
        self.k
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.rows.neighbours.len() / self.k
    }

    /// `true` for an empty graph.
    pub fn is_empty(&self) -> bool {
        self.rows.neighbours.is_empty()
    }

    /// Neighbour indices of point `i`, itself first, then by increasing distance.
    pub fn neighbours(&self, i: usize) -> &[u32] {
        &self.rows.neighbours[self.range(i)]
    }

    /// Distances matching [`KnnGraph::neighbours`].
    pub fn distances(&self, i: usize) -> &[f64] {
        &self.rows.distances[self.range(i)]
    }

    fn range(&self, i: usize) -> std::ops::Range<usize> {
        let used = self.counts.get(i).map_or(self.k, |&c| c as usize);
        i * self.k..i * self.k + used
    }

    /// Distance from point `i` to its farthest listed neighbour.
    pub fn radius(&self, i: usize) -> f64 {
        self.distances(i).last().copied().unwrap_or(0.0)
    }
}

/// Point `i`'s row by a k-d tree search among the points whose squared distance to it is at
/// most `bound2` (at least `k` of them, itself included; infinite where none is known): itself
/// first (even where duplicates tie with it), then its nearest others.
fn tree_row(
    points: &[DVec3],
    index: &PointIndex,
    i: usize,
    bound2: f64,
    nb: &mut [u32],
    ds: &mut [f64],
) {
    let k = nb.len();
    let found = index.nearest_k_within_squared(points[i], k, bound2);
    nb[0] = i as u32;
    ds[0] = 0.0;
    let others = found.into_iter().filter(|&(j, _)| j != i).take(k - 1);
    for (slot, (j, d)) in (1..).zip(others) {
        nb[slot] = j as u32;
        ds[slot] = d;
    }
}

/// Point `i`'s row from `candidates` (the points of the 3 × 3 × 3 block of cells around its
/// cell `c`), or, where they cannot prove it, a squared distance its row lies within
/// (infinite where unknown): with fewer than `k − 1` others, or the farthest of the `k − 1`
/// nearest not nearer than the block's nearest wall (a point beyond it might be nearer; that
/// farthest one bounds the row).
#[allow(clippy::too_many_arguments)]
fn grid_row(
    points: &[DVec3],
    grid: &CellGrid,
    c: [i64; 3],
    i: usize,
    candidates: &[(DVec3, u32)],
    near: &mut Vec<(f64, u32)>,
    nb: &mut [u32],
    ds: &mut [f64],
) -> Result<(), f64> {
    let k = nb.len();
    let p = points[i];
    let want = k - 1;
    if want == 0 {
        nb[0] = i as u32;
        ds[0] = 0.0;
        return Ok(());
    }
    // The others by squared distance, the `want` nearest by (distance, index) selected, then
    // sorted.
    near.clear();
    near.extend(
        candidates
            .iter()
            .filter(|c| c.1 as usize != i)
            .map(|&(q, j)| ((q - p).length_squared(), j)),
    );
    if near.len() < want {
        return Err(f64::INFINITY);
    }
    let by_distance = |a: &(f64, u32), b: &(f64, u32)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
    near.select_nth_unstable_by(want - 1, by_distance);
    near.truncate(want);
    near.sort_unstable_by(by_distance);
    let farthest = near[want - 1].0;
    let wall = grid.wall_distance(c, p);
    // Not proven where either is NaN (a non-finite point): the tree answers, unbounded.
    if farthest.partial_cmp(&(wall * wall)) != Some(std::cmp::Ordering::Less) {
        // With a hair of slack, so the tree's own rounding of the distances keeps them.
        return Err(if farthest.is_finite() {
            farthest * (1.0 + 1e-9)
        } else {
            f64::INFINITY
        });
    }
    nb[0] = i as u32;
    ds[0] = 0.0;
    for (slot, &(d2, j)) in (1..).zip(near.iter()) {
        nb[slot] = j;
        ds[slot] = d2.sqrt();
    }
    Ok(())
}

/// A graph's rows: `k` neighbour ids and distances per point.
#[derive(Debug, PartialEq)]
struct Rows {
    neighbours: Vec<u32>,
    distances: Vec<f64>,
}

/// Points bucketed in a uniform grid for [`KnnGraph::build`].
struct CellGrid {
    origin: DVec3,
    cell: f64,
    /// (cell key, point) sorted by key, then point.
    order: Vec<(u64, u32)>,
    /// Key → range of `order`.
    ranges: HashMap<u64, (u32, u32), BuildHasherDefault<MulHasher>>,
}

/// Points sampled (evenly by index) to size the cells.
const CELL_SAMPLES: usize = 64;
/// Fewer points than this are searched in the tree alone.
const GRID_FROM: usize = 512;

impl CellGrid {
    /// Cells as wide as the 75th percentile of sampled points' `k`-neighbourhood radii (most
    /// points then find all their neighbours in their 3 × 3 × 3 block); `None` where that
    /// cannot work: few points, a non-finite one, a degenerate radius or a box too many cells
    /// wide.
    fn new(points: &[DVec3], index: &PointIndex, k: usize) -> Option<Self> {
        if points.len() < GRID_FROM || k < 2 {
            return None;
        }
        let step = (points.len() / CELL_SAMPLES).max(1);
        let mut radii: Vec<f64> = (0..points.len())
            .step_by(step)
            .map(|i| index.nearest_k(points[i], k).last().map_or(0.0, |l| l.1))
            .collect();
        radii.sort_by(f64::total_cmp);
        let cell = radii[radii.len() * 3 / 4];
        if !points.iter().all(|p| p.is_finite()) {
            return None;
        }
        let (lo, hi) = points.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let cells = ((hi - lo) / cell).max_element();
        if !(cell > 0.0 && cell.is_finite() && cells < (1u64 << KEY_BITS) as f64 - 8.0) {
            return None;
        }
        // Two cells of margin below, so every point's cell is at least 1 on each axis (even
        // where rounding puts the lowest a hair below its cell) and the block around it has
        // non-negative coordinates.
        let origin = lo - DVec3::splat(2.0 * cell);
        let mut order: Vec<(u64, u32)> = points
            .par_iter()
            .enumerate()
            .map(|(i, p)| (key(cell_of(*p - origin, cell)), i as u32))
            .collect();
        order.par_sort_unstable();
        let mut ranges = HashMap::default();
        let mut start = 0;
        for s in 1..=order.len() {
            if s == order.len() || order[s].0 != order[start].0 {
                ranges.insert(order[start].0, (start as u32, s as u32));
                start = s;
            }
        }
        Some(Self {
            origin,
            cell,
            order,
            ranges,
        })
    }

    /// The cell of point `p`.
    fn cell_of(&self, p: DVec3) -> [i64; 3] {
        cell_of(p - self.origin, self.cell)
    }

    /// The points of the 3 × 3 × 3 block of cells around cell `c`, into `out`.
    fn gather_block(&self, c: [i64; 3], points: &[DVec3], out: &mut Vec<(DVec3, u32)>) {
        out.clear();
        for z in c[2] - 1..=c[2] + 1 {
            for y in c[1] - 1..=c[1] + 1 {
                for x in c[0] - 1..=c[0] + 1 {
                    if let Some(&(s, e)) = self.ranges.get(&key([x, y, z])) {
                        out.extend(
                            self.order[s as usize..e as usize]
                                .iter()
                                .map(|&(_, j)| (points[j as usize], j)),
                        );
                    }
                }
            }
        }
    }

    /// How far `p` (in cell `c`) lies from the nearest wall of the block around that cell.
    fn wall_distance(&self, c: [i64; 3], p: DVec3) -> f64 {
        let lo = self.origin
            + DVec3::new(c[0] as f64 - 1.0, c[1] as f64 - 1.0, c[2] as f64 - 1.0) * self.cell;
        let hi = lo + DVec3::splat(3.0 * self.cell);
        (p - lo).min(hi - p).min_element()
    }
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    #[test]
    fn graph_rows_are_self_then_nearest_others() {
        // A dense sphere, a far sparse cluster, exact duplicates: self first, then the k − 1
        // nearest others.
        let mut pts = crate::sampling::Shape::Sphere { radius: 1.0 }
            .sample(20_000, 3)
            .positions;
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        for _ in 0..200 {
            pts.push(DVec3::new(
                rng.random_range(-5.0..5.0),
                rng.random_range(-5.0..5.0),
                4.0,
            ));
        }
        for i in 0..100 {
            pts.push(pts[i * 7]);
        }
        let index = PointIndex::new(&pts);
        for k in [2, 8, 20] {
            let graph = KnnGraph::build(&pts, &index, k);
            for (i, p) in pts.iter().enumerate() {
                let want: Vec<f64> = index
                    .nearest_k(*p, k + 1)
                    .into_iter()
                    .filter(|&(j, _)| j != i)
                    .take(k - 1)
                    .map(|(_, d)| d)
                    .collect();
                let got = &graph.distances(i)[1..];
                assert_eq!(graph.neighbours(i)[0] as usize, i);
                for (g, w) in got.iter().zip(&want) {
                    assert!(
                        (g - w).abs() <= 1e-12 * (1.0 + w),
                        "point {i}, k {k}: {got:?} vs {want:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn grid_rows_match_the_trees_on_uneven_density() {
        // A dense patch, a sparse sheet far off and points scattered in the box: the grid's
        // rows (with the tree's where a block cannot prove them) are the tree's rows exactly.
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut pts: Vec<DVec3> = (0..6000)
            .map(|_| DVec3::new(rng.random_range(0.0..1.0), rng.random_range(0.0..1.0), 0.0))
            .collect();
        pts.extend((0..400).map(|_| {
            DVec3::new(
                rng.random_range(0.0..30.0),
                rng.random_range(0.0..30.0),
                5.0,
            )
        }));
        pts.extend((0..100).map(|_| {
            DVec3::new(
                rng.random_range(-10.0..40.0),
                rng.random_range(-10.0..40.0),
                rng.random_range(-10.0..10.0),
            )
        }));
        let index = PointIndex::new(&pts);
        for k in [2, 8, 20] {
            let grid = CellGrid::new(&pts, &index, k).expect("a grid for 6,500 points");
            let by_grid = KnnGraph::from_grid(&pts, &index, k, &grid);
            let by_tree = KnnGraph::from_tree(&pts, &index, k);
            assert_eq!(by_grid.rows.neighbours, by_tree.rows.neighbours, "k {k}");
            for (g, t) in by_grid.rows.distances.iter().zip(&by_tree.rows.distances) {
                assert!((g - t).abs() <= 1e-12 * t, "k {k}: {g} vs {t}");
            }
        }
    }

    #[test]
    fn rows_the_block_cannot_prove_are_searched_within_its_farthest_candidate() {
        // A lattice (exact ties at every distance) beside a sparse sheet: where a block cannot
        // prove a row, the tree searched only out to the block's farthest pick finds the
        // unbounded search's row.
        let mut pts: Vec<DVec3> = (0..40)
            .flat_map(|i| (0..40).map(move |j| DVec3::new(i as f64, j as f64, 0.0) * 0.1))
            .collect();
        pts.extend((0..200).map(|i| DVec3::new((i % 20) as f64, (i / 20) as f64, 3.0)));
        let index = PointIndex::new(&pts);
        let k = 20;
        let grid = CellGrid::new(&pts, &index, k).expect("a grid");
        let (mut candidates, mut near) = (Vec::new(), Vec::new());
        let (mut nb, mut ds) = (vec![0u32; k], vec![0.0; k]);
        let (mut bounded, mut unbounded) = (0, 0);
        for (i, &p) in pts.iter().enumerate() {
            let c = grid.cell_of(p);
            grid.gather_block(c, &pts, &mut candidates);
            let Err(bound2) = grid_row(&pts, &grid, c, i, &candidates, &mut near, &mut nb, &mut ds)
            else {
                continue;
            };
            if bound2.is_finite() {
                bounded += 1;
            } else {
                unbounded += 1;
            }
            let (mut wide_nb, mut wide_ds) = (vec![0u32; k], vec![0.0; k]);
            tree_row(&pts, &index, i, bound2, &mut nb, &mut ds);
            tree_row(&pts, &index, i, f64::INFINITY, &mut wide_nb, &mut wide_ds);
            assert_eq!(ds, wide_ds, "point {i}");
        }
        assert!(
            bounded > 100 && unbounded > 0,
            "{bounded} bounded, {unbounded} unbounded"
        );
    }

    #[test]
    fn a_non_finite_point_leaves_the_graph_to_the_tree() {
        let mut pts = crate::sampling::Shape::Sphere { radius: 1.0 }
            .sample(1_000, 3)
            .positions;
        let index = PointIndex::new(&pts);
        assert!(CellGrid::new(&pts, &index, 8).is_some());
        pts.push(DVec3::new(f64::NAN, 0.0, 0.0));
        let index = PointIndex::new(&pts);
        assert!(CellGrid::new(&pts, &index, 8).is_none());
    }

    #[test]
    fn shrunk_rows_are_prefixes_with_their_own_radius() {
        let pts = crate::sampling::Shape::Sphere { radius: 1.0 }
            .sample(2_000, 5)
            .positions;
        let index = PointIndex::new(&pts);
        let full = KnnGraph::build(&pts, &index, 20);
        let mut shrunk = full.clone();
        // 0 and past k clamp to 1 and k.
        shrunk.shrink(|i, hood, dist| {
            assert_eq!((hood, dist), (full.neighbours(i), full.distances(i)));
            [0, 7, 14, 30][i % 4]
        });
        for i in 0..pts.len() {
            let used = [1, 7, 14, 20][i % 4];
            assert_eq!(shrunk.neighbours(i), &full.neighbours(i)[..used]);
            assert_eq!(shrunk.distances(i), &full.distances(i)[..used]);
            assert_eq!(shrunk.radius(i), full.distances(i)[used - 1]);
        }
        assert_eq!((shrunk.k(), shrunk.len()), (20, pts.len()));
    }
}
