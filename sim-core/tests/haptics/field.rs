//! Field force: accuracy against analytic fields, convergence, VCP root finding, friction,
//! damping, and agreement of the local model with the full query.

use glam::DVec3;
use protocol::ModelRenderer;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim_core::grid::{GridSpec, ScalarGrid};
use sim_core::haptic::fixtures::{AnalyticField, ForceErrors, force_errors};
use sim_core::haptic::{FieldContactParams, FieldForce, RootStatus};

const K: f64 = 1000.0;

pub fn params() -> FieldContactParams {
    FieldContactParams {
        stiffness: K,
        damping: 0.0,
        friction: 0.0,
        max_search: 0.05,
        approach_margin: 0.0,
        validity_radius: 0.005,
        lifetime_s: 0.05,
    }
}

const R: f64 = 0.02;
const SPHERE: AnalyticField = AnalyticField::Sphere { size: R };
const PLANE: AnalyticField = AnalyticField::Plane { size: R };
const TORUS: AnalyticField = AnalyticField::Torus { size: R };

fn errors(field: AnalyticField, spacing: f64, depths: (f64, f64)) -> ForceErrors {
    force_errors(&field, &field.grid(spacing), &params(), 300, 7, depths)
}

#[test]
fn field_force_is_within_one_percent_at_spacing_r_over_20() {
    // Trilinear interpolation of a distance field misplaces the zero set by ≤ (h²/8)·Σ|∂ᵢᵢφ|
    // ≈ h²/(4R) = R/1600 at h = R/20 (curvature 1/R in two directions). At depths ≥ 0.1R that
    // is ≤ 0.6 % of the force; blended central differences turn the normal by O((h/R)²).
    // Shallower contacts keep the same absolute error (checked as a position below).
    let h = R / 20.0;
    for field in [SPHERE, PLANE, TORUS] {
        let e = errors(field, h, (0.1, 0.3));
        eprintln!("field force {} h=R/20 depth 0.1–0.3R: {e:?}", field.name());
        assert!(e.rel_vector < 0.01, "{field:?}: {e:?}");
        assert!(
            e.rel_magnitude < 0.01 && e.direction_rad < 0.01,
            "{field:?}: {e:?}"
        );
        let shallow = errors(field, h, (0.0, 0.1));
        eprintln!(
            "field force {} h=R/20 depth 0–0.1R: {shallow:?}",
            field.name()
        );
        // Twice the estimate h²/(4R) (the torus's inner side curves by 1/(2R) more).
        assert!(
            shallow.position_m < h * h / (2.0 * R),
            "{field:?}: {shallow:?}"
        );
    }
    // Linear fields are reproduced exactly by trilinear interpolation and central differences.
    assert!(errors(PLANE, R / 5.0, (0.0, 1.0)).rel_vector < 1e-9);
}

#[test]
fn field_force_converges_at_second_order() {
    for field in [SPHERE, TORUS] {
        let errs: Vec<f64> = [5.0, 10.0, 20.0, 40.0]
            .iter()
            .map(|d| errors(field, R / d, (0.1, 0.3)).rel_vector)
            .collect();
        let orders: Vec<f64> = errs.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
        eprintln!(
            "field force {} errors {errs:.3?} orders {orders:.2?}",
            field.name()
        );
        // Both interpolants are second order; allow 1.6 for pre-asymptotic spacings.
        assert!(orders.iter().all(|&o| o > 1.6), "{field:?}: {orders:?}");
    }
}

#[test]
fn vcp_root_is_bracketed_or_falls_back_as_documented() {
    let grid = SPHERE.grid(R / 20.0);
    let x = DVec3::new(0.0, 0.0, 0.8 * R) + DVec3::splat(0.002);
    let mut ff = FieldForce::new(params()).unwrap();
    let c = ff.query(&grid, x, DVec3::ZERO).contact.unwrap();
    assert!(
        matches!(c.root, RootStatus::Bracketed { iterations } if iterations <= 12),
        "{c:?}"
    );
    // The VCP is on the interpolated zero set to the root tolerance.
    let s = grid.sample(c.surface_point).unwrap();
    assert!(s.value.abs() < 1e-8, "{s:?}");
    // A search cap shorter than the depth: first-order fallback |f|/|∇f| along the normal.
    let mut short = FieldForce::new(FieldContactParams {
        max_search: 1e-4,
        ..params()
    })
    .unwrap();
    let q = short.query(&grid, x, DVec3::ZERO);
    let c = q.contact.unwrap();
    assert_eq!(c.root, RootStatus::Fallback);
    let s = grid.sample(x).unwrap();
    let expect = (-s.value / s.gradient.length()).min(1e-4);
    assert!((c.depth - expect).abs() < 1e-15 && q.output.force.is_finite());
}

#[test]
fn friction_sticks_until_mu_times_normal_then_slides() {
    let grid = PLANE.grid(R / 10.0);
    let mut ff = FieldForce::new(FieldContactParams {
        friction: 0.5,
        ..params()
    })
    .unwrap();
    let depth = 0.002;
    ff.query(&grid, DVec3::new(0.0, 0.0, -depth), DVec3::ZERO);
    let f = ff
        .query(&grid, DVec3::new(0.0004, 0.0, -depth), DVec3::ZERO)
        .output
        .force;
    // Stuck: tangential = −k·0.4 mm = −0.4 N (< μN = 1 N); normal unchanged.
    assert!((f - DVec3::new(-0.4, 0.0, 2.0)).length() < 1e-9, "{f}");
    let q = ff.query(&grid, DVec3::new(0.005, 0.0, -depth), DVec3::ZERO);
    let f = q.output.force;
    assert!(
        (f - DVec3::new(-1.0, 0.0, 2.0)).length() < 1e-9,
        "slip at μN: {f}"
    );
    // The VCP slid to 1 mm behind the tip and stays there while sliding on.
    assert!((q.contact.unwrap().vcp.x - 0.004).abs() < 1e-12);
    // Leaving the surface releases it: a fresh contact starts unstressed.
    ff.query(&grid, DVec3::new(0.005, 0.0, 0.001), DVec3::ZERO);
    let f = ff
        .query(&grid, DVec3::new(0.006, 0.0, -depth), DVec3::ZERO)
        .output
        .force;
    assert!((f - DVec3::new(0.0, 0.0, 2.0)).length() < 1e-9, "{f}");
}

#[test]
fn damping_resists_approach_and_never_pulls() {
    let grid = PLANE.grid(R / 10.0);
    let mut ff = FieldForce::new(FieldContactParams {
        damping: 5.0,
        ..params()
    })
    .unwrap();
    let x = DVec3::new(0.0, 0.0, -0.001);
    let f = ff.query(&grid, x, DVec3::new(0.0, 0.0, -0.1)).output.force;
    assert!((f.z - (1.0 + 0.5)).abs() < 1e-9, "{f}");
    assert_eq!(
        ff.query(&grid, x, DVec3::new(0.0, 0.0, 10.0)).output.force,
        DVec3::ZERO
    );
}

#[test]
fn the_local_model_renders_the_query_force_at_the_cursor_along_a_sliding_path() {
    // Same formulas on both sides; the wire is f32: relative 1e-5 plus 1e-6 N.
    let grid = SPHERE.grid(R / 20.0);
    let p = FieldContactParams {
        friction: 0.4,
        damping: 2.0,
        ..params()
    };
    let mut ff = FieldForce::new(p).unwrap();
    let mut server = ModelRenderer::new();
    let dir = DVec3::new(0.5, 0.6, 0.62).normalize();
    let tangent = dir.cross(DVec3::Z).normalize();
    for k in 0..200 {
        let s = k as f64 * 0.003 / 200.0;
        let x = (R - 0.0015 - 0.001 * (k as f64 * 0.05).sin()) * dir + s * tangent;
        let v = tangent * 0.015 + dir * 0.001;
        let q = ff.query(&grid, x, v);
        let rendered = server
            .render(&q.output.to_command(k, 0), x.as_vec3(), v.as_vec3(), 0)
            .as_dvec3();
        let f = q.output.force;
        assert!(
            (rendered - f).length() <= 1e-5 * f.length() + 1e-6,
            "tick {k}: {rendered} vs {f}"
        );
    }
}

#[test]
fn a_deep_contact_model_still_covers_the_cursor() {
    // 8 mm deep, validity radius 5 mm: the radius is about the cursor, not the contact point.
    let grid = PLANE.grid(R / 10.0);
    let mut ff = FieldForce::new(params()).unwrap();
    let x = DVec3::new(0.0, 0.0, -0.008);
    let q = ff.query(&grid, x, DVec3::ZERO);
    let f =
        ModelRenderer::new().render(&q.output.to_command(0, 0), x.as_vec3(), glam::Vec3::ZERO, 0);
    assert!(
        (f.as_dvec3() - q.output.force).length() < 1e-5 * K * 0.008,
        "{f}"
    );
}

#[test]
fn the_local_model_predicts_the_query_near_the_contact() {
    // A frictionless model from the query at x0, rendered at x0 + δ (|δ| ≤ 1 mm), against a
    // fresh query there. The plane misses the sphere by ≤ |δ|²/(2R) in depth and its normal
    // lags the surface's by ≤ |δ|/R: bound k·|δ|²/R + |F|·|δ|/R + 1 % (interpolation).
    let grid = SPHERE.grid(R / 20.0);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let x0 = (R - 0.002) * DVec3::new(0.3, 0.5, 0.81).normalize();
    let model = FieldForce::new(params())
        .unwrap()
        .query(&grid, x0, DVec3::ZERO)
        .output
        .to_command(0, 0);
    for _ in 0..100 {
        let d = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ) * 0.00057;
        let x = x0 + d;
        let truth = FieldForce::new(params())
            .unwrap()
            .query(&grid, x, DVec3::ZERO)
            .output
            .force;
        let rendered = ModelRenderer::new()
            .render(&model, x.as_vec3(), glam::Vec3::ZERO, 0)
            .as_dvec3();
        let bound = K * d.length_squared() / R + truth.length() * (d.length() / R + 0.01);
        assert!(
            (rendered - truth).length() <= bound,
            "δ={d}: {rendered} vs {truth}"
        );
    }
}

#[test]
fn approach_sends_the_surface_plane_before_contact() {
    let grid = PLANE.grid(R / 10.0);
    let mut ff = FieldForce::new(FieldContactParams {
        approach_margin: 0.003,
        ..params()
    })
    .unwrap();
    let q = ff.query(&grid, DVec3::new(0.0, 0.0, 0.002), DVec3::ZERO);
    assert_eq!(q.output.force, DVec3::ZERO);
    let cmd = q.output.to_command(0, 0);
    let f =
        ModelRenderer::new().render(&cmd, glam::Vec3::new(0.0, 0.0, -0.001), glam::Vec3::ZERO, 0);
    assert!((f.z - 1.0).abs() < 1e-5, "server renders the onset: {f}");
    let far = ff.query(&grid, DVec3::new(0.0, 0.0, 0.004), DVec3::ZERO);
    assert_eq!(far.output.model.kind, protocol::ModelKind::None);
}

#[test]
fn non_finite_and_degenerate_inputs_give_zero_or_finite_forces() {
    let grid = SPHERE.grid(R / 10.0);
    let mut ff = FieldForce::new(params()).unwrap();
    let inside = DVec3::splat(0.3 * R);
    for x in [
        DVec3::splat(f64::NAN),
        DVec3::new(f64::INFINITY, 0.0, 0.0),
        DVec3::splat(10.0),
    ] {
        assert_eq!(
            ff.query(&grid, x, DVec3::ZERO).output.force,
            DVec3::ZERO,
            "{x}"
        );
    }
    let f = ff.query(&grid, inside, DVec3::splat(f64::NAN)).output.force;
    assert!(f.is_finite() && f.length() > 0.0);
    let flat = ScalarGrid::from_fn(
        GridSpec::covering(DVec3::ZERO, DVec3::splat(0.01), 0.001),
        |_| -1.0,
    );
    assert_eq!(
        ff.query(&flat, DVec3::splat(0.005), DVec3::ZERO)
            .output
            .force,
        DVec3::ZERO
    );
    assert!(
        FieldForce::new(FieldContactParams {
            stiffness: f64::NAN,
            ..params()
        })
        .is_err()
    );
    assert!(
        FieldForce::new(FieldContactParams {
            max_search: 0.0,
            ..params()
        })
        .is_err()
    );
}

#[test]
fn field_queries_are_deterministic() {
    let grid = TORUS.grid(R / 10.0);
    let run = || {
        let mut ff = FieldForce::new(FieldContactParams {
            friction: 0.3,
            damping: 1.0,
            ..params()
        })
        .unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        (0..50)
            .map(|_| {
                ff.query(
                    &grid,
                    TORUS.interior_point(&mut rng, 0.004).0,
                    DVec3::X * 0.01,
                )
                .output
                .force
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(run(), run());
}
