//! The safety net behind the trusted zero set: a piece of a mesh that no point supports is cut
//! and reported. A point supports the piece holding its nearest mesh vertex, so a piece the
//! points lie on keeps them however small it is (an island of a range map, a separate part),
//! while a sliver the blend leaves inside a solid, nearer to the main surface's points than to
//! any point of its own, has none. This is not a size filter: size is never consulted, and the
//! trusted zero set stays what stops fragments at their source (see the module docs); this
//! catches what gets past it and says what it cut.
//!
//! Contract: a mesh with one piece is returned untouched at the cost of one pass over its
//! triangles; otherwise the kept triangles keep their order and the kept vertices theirs.

use glam::DVec3;
use rayon::prelude::*;

use super::TriMesh;
use crate::knn::PointIndex;

/// A piece [`TriMesh::cut_unsupported_pieces`] removed.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CutPiece {
    /// Its triangles.
    pub triangles: usize,
    /// The mean of its vertices.
    pub centre: [f64; 3],
    /// How far its nearest vertex lies from the nearest point.
    pub distance: f64,
}

impl TriMesh {
    /// Remove every connected piece ([`TriMesh::components`]) that holds no point's nearest
    /// vertex, and say what was removed (largest first). `points` are the points the surface
    /// was made from (not samples added between them); with none, nothing is cut.
    pub fn cut_unsupported_pieces(&mut self, points: &[DVec3]) -> Vec<CutPiece> {
        let (labels, sizes) = self.components();
        if sizes.len() <= 1 || points.is_empty() {
            return Vec::new();
        }
        // Used vertices only: a lone vertex no triangle uses belongs to no piece.
        let used: Vec<u32> = (0..self.vertices.len() as u32)
            .filter(|&v| labels[v as usize] != u32::MAX)
            .collect();
        let positions: Vec<DVec3> = used.iter().map(|&v| self.vertices[v as usize]).collect();
        let index = PointIndex::new(&positions);
        let supported = points
            .par_iter()
            .fold(
                || vec![false; sizes.len()],
                |mut seen, &p| {
                    let (item, _) = index.nearest(p);
                    seen[labels[used[item] as usize] as usize] = true;
                    seen
                },
            )
            .reduce(
                || vec![false; sizes.len()],
                |a, b| a.iter().zip(b).map(|(&x, y)| x || y).collect(),
            );
        // Every point marks one piece, so some piece is always kept.
        if supported.iter().all(|&s| s) {
            return Vec::new();
        }
        let cut = self.report_pieces(&labels, &sizes, &supported, points);
        self.keep_pieces(&labels, &supported);
        cut
    }

    /// The pieces not `kept`, largest first: triangles, centre, distance to the nearest point.
    fn report_pieces(
        &self,
        labels: &[u32],
        sizes: &[usize],
        kept: &[bool],
        points: &[DVec3],
    ) -> Vec<CutPiece> {
        let index = PointIndex::new(points);
        let mut sum = vec![(DVec3::ZERO, 0usize, f64::INFINITY); sizes.len()];
        for (v, &label) in self.vertices.iter().zip(labels) {
            if label != u32::MAX && !kept[label as usize] {
                let s = &mut sum[label as usize];
                s.0 += *v;
                s.1 += 1;
                s.2 = s.2.min(index.nearest(*v).1);
            }
        }
        (0..sizes.len())
            .filter(|&c| !kept[c])
            .map(|c| {
                let (total, n, distance) = sum[c];
                CutPiece {
                    triangles: sizes[c],
                    centre: (total / n.max(1) as f64).to_array(),
                    distance,
                }
            })
            .collect()
    }

    /// Keep only the triangles of `kept` pieces and the vertices they use (renumbered in
    /// order; normals follow their vertices).
    fn keep_pieces(&mut self, labels: &[u32], kept: &[bool]) {
        let keep_vertex = |v: usize| labels[v] != u32::MAX && kept[labels[v] as usize];
        let mut new_id = vec![u32::MAX; self.vertices.len()];
        let mut next = 0u32;
        for (v, id) in new_id.iter_mut().enumerate() {
            if keep_vertex(v) {
                *id = next;
                next += 1;
            }
        }
        let retain = |items: &mut Vec<DVec3>| {
            let mut v = 0;
            items.retain(|_| {
                v += 1;
                keep_vertex(v - 1)
            });
        };
        retain(&mut self.vertices);
        if !self.normals.is_empty() {
            retain(&mut self.normals);
        }
        self.triangles.retain(|t| keep_vertex(t[0] as usize));
        for t in &mut self.triangles {
            *t = t.map(|v| new_id[v as usize]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed tetrahedron of edge about `size` at `at` (outward winding).
    fn tetrahedron(at: DVec3, size: f64) -> TriMesh {
        let v = [
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(1.0, -1.0, -1.0),
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(-1.0, -1.0, 1.0),
        ];
        TriMesh {
            vertices: v.iter().map(|&p| at + p * size).collect(),
            normals: v.iter().map(|p| p.normalize()).collect(),
            triangles: vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]],
        }
    }

    fn joined(parts: &[TriMesh]) -> TriMesh {
        let mut m = TriMesh::default();
        for p in parts {
            let base = m.vertices.len() as u32;
            m.vertices.extend(&p.vertices);
            m.normals.extend(&p.normals);
            m.triangles
                .extend(p.triangles.iter().map(|t| t.map(|v| v + base)));
        }
        m
    }

    #[test]
    fn a_piece_no_point_lies_nearest_to_is_cut_and_reported() {
        let big = tetrahedron(DVec3::ZERO, 1.0);
        // A sliver inside the big one, nearer to its points than any of them is to it.
        let stray = tetrahedron(DVec3::new(0.1, 0.0, 0.0), 0.05);
        let island = tetrahedron(DVec3::new(5.0, 0.0, 0.0), 0.05);
        let mut mesh = joined(&[big.clone(), stray.clone(), island.clone()]);
        // Points on the big one's corners and on the island's: the stray piece has none.
        let points: Vec<DVec3> = big
            .vertices
            .iter()
            .chain(&island.vertices)
            .copied()
            .collect();
        let cut = mesh.cut_unsupported_pieces(&points);
        assert_eq!(cut.len(), 1, "{cut:?}");
        assert_eq!(cut[0].triangles, 4);
        let centre = DVec3::from_array(cut[0].centre);
        assert!(
            (centre - DVec3::new(0.1, 0.0, 0.0)).length() < 1e-12,
            "{centre}"
        );
        // The stray piece's nearest vertex to the nearest point (a corner of the big one).
        let nearest = stray
            .vertices
            .iter()
            .flat_map(|v| points.iter().map(move |p| (*v - *p).length()))
            .fold(f64::INFINITY, f64::min);
        assert_eq!(cut[0].distance, nearest);
        // The island, however small, keeps its points; what is left is the two, in order.
        assert_eq!(mesh, joined(&[big, island]));
        assert_eq!(mesh.components().1, vec![4, 4]);
    }

    #[test]
    fn one_piece_or_no_points_cut_nothing() {
        let one = tetrahedron(DVec3::ZERO, 1.0);
        let mut mesh = one.clone();
        assert!(mesh.cut_unsupported_pieces(&[DVec3::splat(9.0)]).is_empty());
        assert_eq!(mesh, one);
        let two = joined(&[one.clone(), tetrahedron(DVec3::splat(3.0), 1.0)]);
        let mut mesh = two.clone();
        assert!(mesh.cut_unsupported_pieces(&[]).is_empty());
        assert_eq!(mesh, two);
        // Every piece supported: untouched.
        let mut mesh = two.clone();
        let points = [DVec3::ZERO, DVec3::splat(3.0)];
        assert!(mesh.cut_unsupported_pieces(&points).is_empty());
        assert_eq!(mesh, two);
    }

    #[test]
    fn points_nearer_the_smaller_piece_keep_it_and_cut_the_larger() {
        // Support, not size, decides: with every point on the small piece the large one goes.
        let large = tetrahedron(DVec3::ZERO, 1.0);
        let small = tetrahedron(DVec3::splat(4.0), 0.1);
        let mut mesh = joined(&[large, small.clone()]);
        let cut = mesh.cut_unsupported_pieces(&small.vertices);
        assert_eq!(cut.len(), 1);
        assert_eq!(mesh, small);
    }
}
