//! Big scans (issue 19): dense samplings of a triangle mesh with normals (a stand-in for a lab
//! scan of 10⁵–10⁷ points), points put in spatial order, and the peak memory a fit reports.
//!
//! Spatial order matters once scans are large: the renderer's snapshots share unchanged chunks
//! of consecutive points ([`crate::live::points`]), so the points a stroke moves should sit in
//! few chunks. A scanner's output is usually ordered by scan line; a random sampling is not.
//! [`spatial_order`] sorts along a Morton (Z-order) curve; objects of at least
//! [`SPATIAL_ORDER_MIN`] points are sorted when a scene loads them.

use glam::DVec3;
use sim_core::PointSet;
use sim_core::mesh::TriMesh;

/// Objects with at least this many points are put in spatial order when loaded (below it the
/// snapshots are small anyway and the file's order is kept, as it always was).
pub const SPATIAL_ORDER_MIN: usize = 65_536;

/// SplitMix64: a seeded stream without a dependency.
#[derive(Debug, Clone)]
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
}

/// `n` points on `mesh`, uniform by area, seeded; each normal interpolates the mesh's vertex
/// normals (from its faces when it has none) across its triangle, so the sampled surface has
/// smooth normals like a scan's. With `size`, positions are centred on the mesh's bounding-box
/// centre and scaled so the box's longest side is `size` m; without, they stay where the mesh
/// is (so the mesh is their ground truth). The result is in spatial order.
pub fn sample_mesh(mesh: &TriMesh, n: usize, seed: u64, size: Option<f64>) -> PointSet {
    let normals = if mesh.normals.len() == mesh.vertices.len() {
        mesh.normals.clone()
    } else {
        mesh.vertex_normals()
    };
    let (centre, scale) = size.map_or((DVec3::ZERO, 1.0), |s| scaling_to(&mesh.vertices, s));
    let mut cumulative = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0;
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
        total += 0.5 * (b - a).cross(c - a).length();
        cumulative.push(total);
    }
    let mut rng = Rng(seed);
    let mut out = PointSet {
        positions: Vec::with_capacity(n),
        normals: Some(Vec::with_capacity(n)),
        colors: None,
    };
    if cumulative.is_empty() || total.is_nan() || total <= 0.0 {
        return out;
    }
    for _ in 0..n {
        let r = rng.unit() * total;
        let t = cumulative
            .partition_point(|&c| c < r)
            .min(cumulative.len() - 1);
        let (mut u, mut v) = (rng.unit(), rng.unit());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let [a, b, c] = mesh.triangles[t].map(|i| i as usize);
        let w = 1.0 - u - v;
        let (pa, pb, pc) = (mesh.vertices[a], mesh.vertices[b], mesh.vertices[c]);
        let p = pa * w + pb * u + pc * v;
        let face = (pb - pa).cross(pc - pa).normalize_or(DVec3::Z);
        let nrm = (normals[a] * w + normals[b] * u + normals[c] * v)
            .try_normalize()
            .unwrap_or(face);
        out.positions.push((p - centre) * scale);
        if let Some(ns) = out.normals.as_mut() {
            ns.push(nrm);
        }
    }
    spatial_order(&mut out);
    out
}

/// The centre and factor that map `points` by `(p − centre) · factor` so their bounding box is
/// centred at the origin with its longest side `size`: its centre and `size` over that side. A
/// set with no extent is only moved (factor 1); an empty one is left as it is.
pub fn scaling_to(points: &[DVec3], size: f64) -> (DVec3, f64) {
    let Some((lo, hi)) = sim_core::pointset::bounds(points) else {
        return (DVec3::ZERO, 1.0);
    };
    let side = (hi - lo).max_element();
    (0.5 * (lo + hi), if side > 0.0 { size / side } else { 1.0 })
}

/// Sort `points` (and their normals and colours) along a Morton curve over their bounding box.
pub fn spatial_order(points: &mut PointSet) {
    let order = sim_core::pointset::morton_order(&points.positions);
    let take = |v: &[DVec3]| order.iter().map(|&i| v[i as usize]).collect::<Vec<_>>();
    points.positions = take(&points.positions);
    if let Some(n) = &points.normals {
        points.normals = Some(take(n));
    }
    if let Some(c) = &points.colors {
        points.colors = Some(order.iter().map(|&i| c[i as usize]).collect());
    }
}

/// Peak resident set size of this process so far (`VmHWM`), KiB; 0 where unknown.
pub fn peak_rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        })
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sampled_mesh_lies_on_it_with_unit_normals_in_spatial_order() {
        // A unit square in z = 0, two triangles.
        let mesh = TriMesh {
            vertices: vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            normals: Vec::new(),
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        };
        let p = sample_mesh(&mesh, 5000, 3, Some(0.1));
        assert_eq!(p.len(), 5000);
        let n = p.normals.as_ref().unwrap();
        assert!(
            p.positions
                .iter()
                .all(|x| x.z == 0.0 && x.x.abs() <= 0.05 && x.y.abs() <= 0.05)
        );
        assert!(
            n.iter()
                .all(|v| (v.length() - 1.0).abs() < 1e-12 && v.z.abs() > 0.999)
        );
        // Consecutive points are close: the mean step is far below a random order's (~0.05).
        let step: f64 = p
            .positions
            .windows(2)
            .map(|w| w[0].distance(w[1]))
            .sum::<f64>()
            / 4999.0;
        assert!(step < 0.01, "mean step {step}");
        assert_eq!(sample_mesh(&mesh, 5000, 3, Some(0.1)), p, "seeded");
        assert!(peak_rss_kib() > 0);
        // Without a size the points stay on the mesh where it is (the square spans 0..1, its
        // centre is not the origin): `fit sample:MESH:N` measures against the mesh itself.
        let kept = sample_mesh(&mesh, 1000, 4, None);
        assert!(
            kept.positions
                .iter()
                .all(|x| x.z == 0.0 && (0.0..=1.0).contains(&x.x) && (0.0..=1.0).contains(&x.y))
        );
        assert!(kept.positions.iter().any(|x| x.x > 0.75));
    }
}
