//! Surface nets over the field: closed, outward-oriented and on the zero set.

use std::collections::HashMap;

use glam::DVec3;
use sim_core::FitParams;
use sim_core::mesh::extract_zero_set;
use sim_core::reconstruct::NormalPolicy;
use sim_core::sampling::Shape;

use crate::common::fit;

#[test]
fn sphere_mesh_is_closed_outward_and_on_the_surface() {
    let sphere = Shape::Sphere { radius: 1.0 };
    let rec = fit(
        &sphere.sample(8000, 1),
        &FitParams::default(),
        NormalPolicy::Keep,
    );
    let mesh = extract_zero_set(&rec.field, (DVec3::splat(-1.2), DVec3::splat(1.2)), 48);
    assert!(mesh.triangles.len() > 5000);
    // Vertices are projected onto the zero set: within 3e-4 R of the sphere (the field's own
    // max error at 8k points is ~1e-4 R).
    for v in &mesh.vertices {
        assert!((v.length() - 1.0).abs() < 3e-4, "{v}: {}", v.length() - 1.0);
    }
    // Every edge is shared by exactly two triangles with opposite directions (closed, oriented).
    let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
        }
        let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
        assert!(
            (b - a).cross(c - a).dot(a + b + c) > 0.0,
            "triangle faces inward"
        );
    }
    assert!(
        edges.values().all(|&v| v == 0),
        "mesh has boundary or inconsistent orientation"
    );
    let chi = mesh.vertices.len() as i64 - edges.len() as i64 + mesh.triangles.len() as i64;
    assert_eq!(chi, 2, "Euler characteristic of a sphere");
    assert!(
        mesh.normals
            .iter()
            .zip(&mesh.vertices)
            .all(|(n, v)| n.dot(*v) > 0.99)
    );
}
