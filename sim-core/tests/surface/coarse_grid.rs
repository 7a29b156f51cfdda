//! Meshing on a grid coarse for the part: a tube or a slab two to three cells thick.

use glam::DVec3;
use sim_core::mesh::extract_zero_set;
use sim_core::reconstruct::NormalPolicy;
use sim_core::sampling::Shape;

use crate::common::{fit, fit_defaults};

/// The armadillo's ears and claws at resolution 100 are one to three cells thick. There the
/// surface-nets first guess of a cell (the mean of its edge crossings) lies off the surface,
/// between a slab's sheets or inside a tube's bend, and judged by trust there alone such
/// cells were left out: each case below had holes (36–1,012 open edges), broke into pieces
/// (up to 25) or meshed to nothing, where a vertex's trust is now judged where it goes, on
/// the zero set. `workstation fit`'s defaults for a static surface.
#[test]
fn parts_two_to_three_cells_thick_mesh_whole_on_a_coarse_grid() {
    let params = fit_defaults();
    let cases = [
        (
            Shape::Torus {
                major: 0.8,
                minor: 0.03,
            },
            [60, 80],
        ),
        (
            Shape::Torus {
                major: 0.8,
                minor: 0.05,
            },
            [50, 60],
        ),
        (
            Shape::Plate {
                half_size: 1.0,
                thickness: 0.06,
            },
            [50, 80],
        ),
    ];
    let mut failures = Vec::new();
    for (shape, resolutions) in cases {
        let points = shape.sample(20_000, 1);
        let rec = fit(&points, &params, NormalPolicy::Keep);
        let (lo, hi) = sim_core::pointset::bounds(&points.positions).unwrap();
        let pad = DVec3::splat(0.05 * (hi - lo).length() + 2.0 * rec.field.scale());
        let bounds = (lo - pad, hi + pad);
        for resolution in resolutions {
            let mesh = extract_zero_set(&rec.field, bounds, resolution);
            let cell = (bounds.1 - bounds.0).max_element() / resolution as f64;
            let (pieces, open) = (mesh.pieces(), mesh.open_edges());
            let area = mesh.area() / shape.area();
            eprintln!(
                "{shape:?} R {resolution}: {:.2} cells thick, {pieces} pieces, {open} open \
                 edges, area {area:.3} of the truth's",
                (hi - lo).min_element() / cell
            );
            if pieces != 1 || open != 0 || (area - 1.0).abs() > 0.05 {
                failures.push((shape, resolution, pieces, open, area));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}
