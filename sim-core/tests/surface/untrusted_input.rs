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
