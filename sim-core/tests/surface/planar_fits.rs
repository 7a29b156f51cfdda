//! A neighbourhood on its centre's tangent plane skips the local fit's solve (its answer is
//! the plane), and only such a neighbourhood does.

use glam::{DMat3, DVec3};
use sim_core::FitParams;
use sim_core::local_fit::{FitScratch, LocalFrame, Neighbourhood, fit_local, is_tangent_plane};

/// A 5 × 5 patch of points 0.1 apart on the plane through `centre` facing `normal` (tilted, so
/// the plane is not an axis plane and its points carry rounding), each facing `normal`.
fn tilted_patch(centre: DVec3, normal: DVec3) -> (Vec<DVec3>, Vec<DVec3>) {
    let (t1, t2) = sim_core::linalg::tangent_frame(normal);
    let mut points = Vec::new();
    for a in -2..=2 {
        for b in -2..=2 {
            points.push(centre + t1 * (0.1 * a as f64) + t2 * (0.1 * b as f64));
        }
    }
    let normals = vec![normal; points.len()];
    (points, normals)
}

fn fit(points: &[DVec3], normals: &[DVec3], params: &FitParams) -> (LocalFrame, Vec<f64>) {
    let hood = Neighbourhood {
        center: points[12],
        normal: normals[12],
        points,
        normals,
        fallback_radius: 0.1,
    };
    let mut coeffs = vec![0.0; params.size.pow(3)];
    let frame = fit_local(
        &hood,
        params,
        &mut FitScratch::new(params.size),
        &mut coeffs,
    );
    (frame, coeffs)
}

#[test]
fn only_a_neighbourhood_on_the_tangent_plane_is_written_as_the_plane() {
    let rotation = DMat3::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1);
    let normal = rotation * DVec3::Z;
    let centre = DVec3::new(0.31, -1.7, 2.9);
    for params in [
        FitParams::default(),
        FitParams {
            regularization: 3e-4,
            normal_weight: 0.25,
            ..FitParams::default()
        },
        FitParams {
            size: 4,
            ..FitParams::default()
        },
    ] {
        let (mut points, normals) = tilted_patch(centre, normal);
        let (frame, coeffs) = fit(&points, &normals, &params);
        assert!(
            is_tangent_plane(params.size, &frame, &coeffs),
            "a sampled plane (size {})",
            params.size
        );
        // One neighbour 1e-6 of the patch's radius off the plane: solved, and the answer
        // moves off the plane by about that much, so the skip (offsets of zero, within 1e-9 of
        // the edge where it is taken) is the limit of the solve's answers, not a different one.
        let radius = (points[0] - centre).length();
        points[7] += normal * (1e-6 * radius);
        let (frame, coeffs) = fit(&points, &normals, &params);
        assert!(!is_tangent_plane(params.size, &frame, &coeffs));
        let edge = 2.0 * frame.half;
        let (_, plane) = fit(&tilted_patch(centre, normal).0, &normals, &params);
        let moved = coeffs
            .iter()
            .zip(&plane)
            .map(|(a, b)| (a - b).abs() / edge)
            .fold(0.0, f64::max);
        assert!(
            moved > 1e-9 && moved < 1e-4,
            "size {}: {moved}",
            params.size
        );
        // A neighbour facing 0.1° away is not on the plane either.
        points[7] -= normal * (1e-6 * radius);
        let mut tilted = normals.clone();
        tilted[7] = (normal + rotation * DVec3::X * 0.1f64.to_radians()).normalize();
        let (frame, coeffs) = fit(&points, &tilted, &params);
        assert!(!is_tangent_plane(params.size, &frame, &coeffs));
    }
}
