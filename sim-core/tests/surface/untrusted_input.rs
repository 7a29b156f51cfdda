//! Regressions from the robustness review: untrusted counts in file headers, and queries at
//! non-finite or overflowing positions.

use glam::DVec3;
use sim_core::FitParams;
use sim_core::io::{self, Format, IoError};
use sim_core::reconstruct::NormalPolicy;
use sim_core::sampling::Shape;

use crate::common::fit;

fn binary_ply(tail_header: &str, data: &[u8]) -> Vec<u8> {
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty double x\n\
         property double y\nproperty double z\n{tail_header}end_header\n"
    )
    .into_bytes();
    b.extend_from_slice(&[0u8; 24]);
    b.extend_from_slice(data);
    b
}

#[test]
fn binary_ply_counts_are_bounded_by_the_data() {
    // An element without properties and a count of 10¹² used to spin for hours.
    let t = std::time::Instant::now();
    let l = io::read(
        &binary_ply("element junk 1000000000000\n", &[])[..],
        Format::Ply,
    )
    .unwrap();
    assert_eq!(l.points.positions, vec![DVec3::ZERO]);
    // A count the remaining bytes cannot hold is an error naming the element, at once.
    let bytes = binary_ply(
        "element extra 1000000000000\nproperty uchar v\n",
        &[1, 2, 3],
    );
    match io::read(&bytes[..], Format::Ply) {
        Err(IoError::Record {
            element, reason, ..
        }) => {
            assert_eq!(element, "extra");
            assert!(reason.contains("1000000000000"), "{reason}");
        }
        other => panic!("{other:?}"),
    }
    assert!(t.elapsed().as_secs_f64() < 1.0, "{:?}", t.elapsed());
}

#[test]
fn queries_at_non_finite_and_overflowing_positions() {
    let pts = Shape::Sphere { radius: 1.0 }.sample(2000, 6);
    let rec = fit(&pts, &FitParams::default(), NormalPolicy::Keep);
    for x in [
        DVec3::NAN,
        DVec3::new(f64::INFINITY, 0.0, 0.0),
        DVec3::new(f64::NEG_INFINITY, 1.0, f64::NAN),
        DVec3::splat(f64::MAX),
        DVec3::new(-f64::MAX, f64::MAX, 0.0),
    ] {
        let (f, g) = rec.field.value_and_gradient(x);
        assert!(f.is_finite() && g.is_finite(), "{x}: {f} {g}");
        // Used to report a NaN/inf start, or one at 1.8e308, as converged onto the surface.
        let p = rec.field.project_to_zero_set(x);
        assert!(!p.converged, "{x}: {p:?}");
        if x.is_finite() {
            assert!(f > 1e300, "{x}: f = {f} (far outside)");
            assert!(p.point.is_finite(), "{x}: {p:?}");
        }
    }
}

/// Some scanners write normals whose signs are noise. A field fitted to them has no consistent
/// inside, so they are reoriented (and only they): a sphere whose normals point in or out at
/// random comes back facing out everywhere; oriented normals, and the two sides of a part
/// thinner than the spacing (which face apart but lie off each other's planes), are left alone.
#[test]
fn unoriented_normals_are_reoriented_and_oriented_ones_left_alone() {
    use sim_core::knn::PointIndex;
    use sim_core::normals::{UNORIENTED_SHARE, orient_if_unoriented, unoriented_share};
    let sphere = Shape::Sphere { radius: 0.05 }.sample(3000, 11);
    let outward = sphere.normals.clone().unwrap();
    let mut random: Vec<DVec3> = outward
        .iter()
        .enumerate()
        .map(|(i, n)| if (i * 7919) % 13 < 6 { -*n } else { *n })
        .collect();
    let index = PointIndex::new(&sphere.positions);
    let share = unoriented_share(&sphere.positions, &index, &random);
    assert!(share > 0.35, "random signs: {share}");
    assert_eq!(
        orient_if_unoriented(&sphere.positions, &mut random),
        Some(share)
    );
    for (p, n) in sphere.positions.iter().zip(&random) {
        assert!(p.dot(*n) > 0.0, "{p} faces in after reorienting");
    }
    // Oriented: untouched.
    let mut same = outward.clone();
    assert_eq!(orient_if_unoriented(&sphere.positions, &mut same), None);
    assert_eq!(same, outward);
    // A leaf 3 mm thick sampled every 3 mm or so: its sides face apart, not unoriented.
    let leaf = Shape::Ellipsoid {
        radii: DVec3::new(0.04, 0.025, 0.0015),
    }
    .sample(600, 5);
    let given = leaf.normals.clone().unwrap();
    let index = PointIndex::new(&leaf.positions);
    let share = unoriented_share(&leaf.positions, &index, &given);
    assert!(share < UNORIENTED_SHARE / 2.0, "leaf: {share}");
    let mut kept = given.clone();
    assert_eq!(orient_if_unoriented(&leaf.positions, &mut kept), None);
    assert_eq!(kept, given);
}

/// `reconstruct` with `KeepConsistent` makes the same check on its own k-NN graph (no tree or
/// searches of its own): random signs come back facing out, with the same share as the tree's
/// check; oriented normals are kept as given. `Keep` never touches them.
#[test]
fn keep_consistent_reorients_unoriented_normals_on_the_fits_graph() {
    use sim_core::knn::PointIndex;
    use sim_core::normals::{unoriented_share, unoriented_share_in};
    use sim_core::pointset::PointSet;
    let sphere = Shape::Sphere { radius: 0.05 }.sample(3000, 11);
    let outward = sphere.normals.clone().unwrap();
    let random: Vec<DVec3> = outward
        .iter()
        .enumerate()
        .map(|(i, n)| if (i * 7919) % 13 < 6 { -*n } else { *n })
        .collect();
    let index = PointIndex::new(&sphere.positions);
    let knn = sim_core::knn::KnnGraph::build(&sphere.positions, &index, 20);
    let by_tree = unoriented_share(&sphere.positions, &index, &random);
    let by_graph = unoriented_share_in(&sphere.positions, &knn, &random);
    assert_eq!(by_tree, by_graph);
    let scrambled = PointSet {
        normals: Some(random.clone()),
        ..sphere.clone()
    };
    let rec = fit(
        &scrambled,
        &FitParams::default(),
        NormalPolicy::KeepConsistent,
    );
    assert_eq!(rec.reoriented, Some(by_graph));
    for (p, n) in sphere.positions.iter().zip(&rec.normals) {
        assert!(p.dot(*n) > 0.0, "{p} faces in after reorienting");
    }
    // The fit's normals are the given ones, renormalised: compare directions.
    let same = |a: &[DVec3], b: &[DVec3]| a.iter().zip(b).all(|(a, b)| a.dot(*b) > 1.0 - 1e-9);
    let kept = fit(&scrambled, &FitParams::default(), NormalPolicy::Keep);
    assert_eq!(kept.reoriented, None);
    assert!(
        same(&kept.normals, &random),
        "Keep changed the given normals"
    );
    let oriented = fit(&sphere, &FitParams::default(), NormalPolicy::KeepConsistent);
    assert_eq!(oriented.reoriented, None);
    assert!(
        same(&oriented.normals, &outward),
        "oriented normals were changed"
    );
}
