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

/// A sharp box (edges rounded by 1e-3 of its size, far under the 8 mm spacing): the blend
/// rounds its edges over about a support radius; with `MeshOptions::creases` the vertices
/// there move onto the faces' planes and the edge lines. Measured (20k points, resolution
/// 150, relative to the diagonal): RMS 3.1e-4 → 2.5e-4, p99 1.30e-3 → 0.86e-3, coverage RMS
/// 2.85e-4 → 1.93e-4; the max grows (1.0e-2 → 1.1e-2) near the corners, where three faces
/// meet and the blend's rounding is kept. A smooth torus is left alone. Plain surface nets
/// (vertices at their edge crossings' mean) is farther from the torus than vertices projected
/// onto the zero set: RMS 1.76e-4 against 6.6e-5 at resolution 100.
#[test]
fn creases_sharpen_a_box_and_leave_a_torus_alone_and_projection_brings_vertices_to_the_surface() {
    use sim_core::accuracy::mesh_error;
    use sim_core::mesh::{MeshOptions, extract_zero_set_with};
    let mesh_with = |shape: &Shape, n: usize, res: usize, options: MeshOptions| {
        let points = shape.sample(n, 4);
        let rec = fit(&points, &FitParams::default(), NormalPolicy::Keep);
        let (lo, hi) = shape.bounds();
        let pad = (hi - lo) * 0.1;
        let (mesh, stats) = extract_zero_set_with(&rec.field, (lo - pad, hi + pad), res, &options);
        let e = mesh_error(&mesh, shape, 100_000, 5).unwrap();
        let (to_ref, cover) = e.relative();
        eprintln!(
            "{shape:?} {options:?}: {to_ref:?} coverage {cover:?}, {} sharpened",
            stats.sharpened
        );
        (to_ref, cover, stats.sharpened)
    };
    let sharp = Shape::RoundedBox {
        half: DVec3::new(0.5, 0.4, 0.3),
        radius: 0.001,
    };
    let creases = MeshOptions {
        creases: true,
        ..MeshOptions::default()
    };
    let (plain, plain_cover, none) = mesh_with(&sharp, 20_000, 150, MeshOptions::default());
    let (sharpened, sharpened_cover, moved) = mesh_with(&sharp, 20_000, 150, creases);
    assert_eq!(none, 0);
    assert!(moved > 1000, "{moved}");
    assert!(
        sharpened.rms < 0.9 * plain.rms,
        "{sharpened:?} vs {plain:?}"
    );
    assert!(
        sharpened.p99 < 0.8 * plain.p99,
        "{sharpened:?} vs {plain:?}"
    );
    assert!(sharpened_cover.rms < 0.8 * plain_cover.rms);

    let torus = Shape::Torus {
        major: 1.0,
        minor: 0.3,
    };
    let (projected, _, _) = mesh_with(&torus, 10_000, 100, MeshOptions::default());
    let (torus_creased, _, moved) = mesh_with(&torus, 10_000, 100, creases);
    // Nothing moves; only the quads' diagonals may be chosen otherwise, which helps here.
    assert_eq!(moved, 0);
    assert!(torus_creased.rms <= projected.rms && torus_creased.max <= projected.max);
    let unprojected = MeshOptions {
        unprojected: true,
        ..MeshOptions::default()
    };
    let (mean, _, _) = mesh_with(&torus, 10_000, 100, unprojected);
    assert!(projected.rms < 0.5 * mean.rms, "{projected:?} vs {mean:?}");
}
