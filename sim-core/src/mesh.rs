//! Triangle meshes, and extraction of a field's zero set by surface nets: one vertex per grid
//! cell crossed by the surface (the mean of its edge crossings, then Newton-projected onto the
//! zero set), one quad per crossed grid edge, oriented so triangle normals point outward.
//!
//! Contract: only cells with a corner inside some local support emit geometry, so sign changes
//! of the nearest-point fallback far from the surface cannot create spurious sheets. Vertices
//! are finite.

use glam::DVec3;
use rayon::prelude::*;

use crate::field::GlobalField;
use crate::projection::{ProjectOptions, project_to_zero_set_with};

/// An indexed triangle mesh; triangles are counter-clockwise seen from outside.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions.
    pub vertices: Vec<DVec3>,
    /// Unit vertex normals (empty, or one per vertex).
    pub normals: Vec<DVec3>,
    /// Vertex index triples.
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Area-weighted vertex normals from the triangles' winding (zero for a vertex that no
    /// non-degenerate triangle uses). For a consistently wound mesh they face outward.
    pub fn vertex_normals(&self) -> Vec<DVec3> {
        let mut n = vec![DVec3::ZERO; self.vertices.len()];
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| self.vertices[i as usize]);
            let area_normal = (b - a).cross(c - a);
            if area_normal.is_finite() {
                for &i in t {
                    n[i as usize] += area_normal;
                }
            }
        }
        n.into_iter()
            .map(|v| v.try_normalize().unwrap_or(DVec3::ZERO))
            .collect()
    }
}

/// Extract the zero set of `field` inside `bounds` on a grid whose longest side has `resolution`
/// cells (clamped to 8..=1024). Runs on all cores.
pub fn extract_zero_set(field: &GlobalField, bounds: (DVec3, DVec3), resolution: usize) -> TriMesh {
    let (lo, hi) = bounds;
    let extent = (hi - lo).max(DVec3::splat(1e-300));
    let h = extent.max_element() / resolution.clamp(8, 1024) as f64;
    let dims = ((extent / h).ceil().as_uvec3() + glam::UVec3::ONE).max(glam::UVec3::splat(2));
    let [nx, ny, nz] = [dims.x as usize, dims.y as usize, dims.z as usize];
    let node = |i: usize, j: usize, k: usize| lo + DVec3::new(i as f64, j as f64, k as f64) * h;
    // Node values, and whether a local support covers the node.
    let values: Vec<(f64, bool)> = (0..nx * ny * nz)
        .into_par_iter()
        .map(|flat| {
            let (i, j, k) = (flat % nx, (flat / nx) % ny, flat / (nx * ny));
            let x = node(i, j, k);
            (field.value(x), field.is_covered(x))
        })
        .collect();
    let at = |i: usize, j: usize, k: usize| values[(k * ny + j) * nx + i].0;
    let covered = |i: usize, j: usize, k: usize| values[(k * ny + j) * nx + i].1;
    let (cx, cy, cz) = (nx - 1, ny - 1, nz - 1);
    let opts = ProjectOptions::default();
    // One vertex per crossed cell with at least one covered corner.
    let cell_vertex: Vec<Option<DVec3>> = (0..cx * cy * cz)
        .into_par_iter()
        .map(|flat| {
            let (i, j, k) = (flat % cx, (flat / cx) % cy, flat / (cx * cy));
            let mut corner = [0.0; 8];
            let mut any_covered = false;
            for (c, v) in corner.iter_mut().enumerate() {
                let (a, b, d) = (i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2));
                *v = at(a, b, d);
                any_covered |= covered(a, b, d);
            }
            if !any_covered {
                return None;
            }
            let (mut sum, mut count) = (DVec3::ZERO, 0.0);
            for (a, b) in CUBE_EDGES {
                let (fa, fb) = (corner[a], corner[b]);
                if (fa < 0.0) != (fb < 0.0) {
                    let t = fa / (fa - fb);
                    let pa = corner_offset(a);
                    sum += pa + (corner_offset(b) - pa) * t;
                    count += 1.0;
                }
            }
            if count == 0.0 {
                return None;
            }
            let guess = node(i, j, k) + sum / count * h;
            let pr = project_to_zero_set_with(field, guess, &opts);
            let ok = pr.converged && (pr.point - guess).length() < 2.0 * h;
            Some(if ok { pr.point } else { guess })
        })
        .collect();
    let mut mesh = TriMesh::default();
    let mut id = vec![u32::MAX; cell_vertex.len()];
    for (c, v) in cell_vertex.iter().enumerate() {
        if let Some(p) = v {
            id[c] = mesh.vertices.len() as u32;
            mesh.vertices.push(*p);
        }
    }
    let cell = |i: usize, j: usize, k: usize| id[(k * cy + j) * cx + i];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let f0 = at(i, j, k);
                // Edges along +x, +y, +z from this node, with the four cells around each,
                // listed counter-clockwise about the edge direction.
                for axis in 0..3 {
                    let (f1, quad) = match axis {
                        0 if i + 1 < nx && j > 0 && k > 0 => (
                            at(i + 1, j, k),
                            [(i, j - 1, k - 1), (i, j, k - 1), (i, j, k), (i, j - 1, k)],
                        ),
                        1 if j + 1 < ny && i > 0 && k > 0 => (
                            at(i, j + 1, k),
                            [(i - 1, j, k - 1), (i - 1, j, k), (i, j, k), (i, j, k - 1)],
                        ),
                        2 if k + 1 < nz && i > 0 && j > 0 => (
                            at(i, j, k + 1),
                            [(i - 1, j - 1, k), (i, j - 1, k), (i, j, k), (i - 1, j, k)],
                        ),
                        _ => continue,
                    };
                    if (f0 < 0.0) == (f1 < 0.0) {
                        continue;
                    }
                    if quad.iter().any(|&(a, b, c)| a >= cx || b >= cy || c >= cz) {
                        continue;
                    }
                    let v = quad.map(|(a, b, c)| cell(a, b, c));
                    if v.contains(&u32::MAX) {
                        continue;
                    }
                    // Inside → outside along +axis: the quad's normal (+axis) is outward.
                    let tris = if f0 < 0.0 {
                        [[v[0], v[1], v[2]], [v[0], v[2], v[3]]]
                    } else {
                        [[v[0], v[2], v[1]], [v[0], v[3], v[2]]]
                    };
                    mesh.triangles.extend(tris);
                }
            }
        }
    }
    mesh.normals = mesh
        .vertices
        .par_iter()
        .map(|&p| {
            field
                .value_and_gradient(p)
                .1
                .try_normalize()
                .unwrap_or(DVec3::Z)
        })
        .collect();
    mesh
}

const CUBE_EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

fn corner_offset(c: usize) -> DVec3 {
    DVec3::new((c & 1) as f64, ((c >> 1) & 1) as f64, (c >> 2) as f64)
}

/// The point of triangle `abc` closest to `p` (Ericson, Real-Time Collision Detection §5.1.5).
pub fn closest_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE || !denom.is_finite() {
        return a; // degenerate triangle
    }
    let (v, w) = (vb / denom, vc / denom);
    a + ab * v + ac * w
}
