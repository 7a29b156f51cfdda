//! Nearest-neighbour queries over a fixed point set: a k-d tree (`kiddo`'s immutable tree, which
//! tolerates duplicate and coplanar points) and the k-NN graph used by normals and fits.
//!
//! Contract: built once (a graph may then be shrunk per point, [`KnnGraph::shrink`], before
//! use), then immutable, `Send + Sync`; [`PointIndex::nearest`] does not allocate.

use glam::DVec3;
use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use rayon::prelude::*;

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
        let Some(k) = std::num::NonZero::new(k.min(self.len)) else {
            return Vec::new();
        };
        self.tree
            .nearest_n::<SquaredEuclidean>(&x.to_array(), k)
            .into_iter()
            .map(|nn| (nn.item as usize, nn.distance.max(0.0).sqrt()))
            .collect()
    }
}

/// For every point, its `k` nearest points (itself first), stored row by row.
#[derive(Debug, Clone, PartialEq)]
pub struct KnnGraph {
    k: usize,
    neighbours: Vec<u32>,
    distances: Vec<f64>,
    /// How many of each point's `k` listed neighbours are in use (empty: all of them); see
    /// [`KnnGraph::shrink`].
    counts: Vec<u32>,
}

impl KnnGraph {
    /// Query `index` for the `k` nearest of every point (k is capped at the point count, ≥ 1).
    /// Runs on all cores.
    pub fn build(points: &[DVec3], index: &PointIndex, k: usize) -> Self {
        let k = k.clamp(1, points.len());
        let mut neighbours = vec![0u32; points.len() * k];
        let mut distances = vec![0.0; points.len() * k];
        neighbours
            .par_chunks_mut(k)
            .zip(distances.par_chunks_mut(k))
            .enumerate()
            .for_each(|(i, (nb, ds))| {
                let found = index.nearest_k(points[i], k);
                // Put the point itself first even when duplicates tie with it.
                nb[0] = i as u32;
                ds[0] = 0.0;
                let others = found.into_iter().filter(|&(j, _)| j != i).take(k - 1);
                for (slot, (j, d)) in (1..).zip(others) {
                    nb[slot] = j as u32;
                    ds[slot] = d;
                }
            });
        Self {
            k,
            neighbours,
            distances,
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
                let c = count(i, &self.neighbours[range.clone()], &self.distances[range]);
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
        self.neighbours.len() / self.k
    }

    /// `true` for an empty graph.
    pub fn is_empty(&self) -> bool {
        self.neighbours.is_empty()
    }

    /// Neighbour indices of point `i`, itself first, then by increasing distance.
    pub fn neighbours(&self, i: usize) -> &[u32] {
        &self.neighbours[self.range(i)]
    }

    /// Distances matching [`KnnGraph::neighbours`].
    pub fn distances(&self, i: usize) -> &[f64] {
        &self.distances[self.range(i)]
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
