//! The shaped probe: analytic depths, seed 004 Fig. 4, shapes, index, damping, models.

use glam::{DQuat, DVec3, Vec3};
use protocol::ModelRenderer;
use protocol::packet::ModelKind;
use sim_core::probe::fixtures::{edge, fig4_force, sheet};
use sim_core::probe::{
    ContactParams, DirectionMethod, MagnitudeMethod, Probe, ProbeError, ProbePose, ProbeRenderer,
    SampleGrid, SurfaceSample,
};

pub(crate) const R: f64 = 0.02;
pub(crate) const KS: f64 = 1.0e6;

pub(crate) fn renderer(method: DirectionMethod, damping: f64) -> ProbeRenderer {
    let params = ContactParams {
        surface_stiffness: KS,
        surface_damping: damping,
        method,
        magnitude: MagnitudeMethod::SpringSum,
    };
    ProbeRenderer::new(params, 4096).unwrap()
}

pub(crate) fn sphere_at(c: DVec3) -> Probe {
    Probe::sphere(R).unwrap().posed(ProbePose::at(c)).unwrap()
}

#[test]
fn ray_crossing_is_the_nearer_sphere_crossing_along_the_normal() {
    let probe = sphere_at(DVec3::ZERO);
    for &(x, y, z) in &[(0.0, 0.0, 0.005), (0.01, -0.004, -0.003), (0.0, 0.019, 0.0)] {
        let hit = probe.ray_crossing(DVec3::new(x, y, z), DVec3::Z).unwrap();
        let w = (R * R - x * x - y * y).sqrt();
        let expect = (w - z).min(w + z);
        // Closed form vs the stable quadratic: a few ulps of R.
        assert!(
            (hit.depth - expect).abs() < 1e-15,
            "{} vs {expect}",
            hit.depth
        );
        if z != 0.0 {
            assert_eq!(hit.exit_sign, if w - z < w + z { 1.0 } else { -1.0 });
        }
        // On the exit side, `depth` along `exit_sign·n` reaches the surface.
        let on = DVec3::new(x, y, z) + hit.exit_sign * hit.depth * DVec3::Z;
        assert!(probe.value(on).abs() < 1e-12, "{on}");
    }
    assert!(
        probe
            .ray_crossing(DVec3::new(0.0, 0.0, R), DVec3::Z)
            .is_none(),
        "on surface"
    );
    assert!(
        probe
            .ray_crossing(DVec3::splat(f64::NAN), DVec3::Z)
            .is_none()
    );
}

#[test]
fn rotated_ellipsoid_crossing_lies_on_the_probe_and_on_the_normal_line() {
    let q = DQuat::from_euler(glam::EulerRot::XYZ, 0.4, -0.9, 1.3);
    let c = DVec3::new(0.01, -0.02, 0.03);
    let probe = Probe::ellipsoid(DVec3::new(0.03, 0.01, 0.02))
        .unwrap()
        .posed(ProbePose {
            position: c,
            orientation: q,
        })
        .unwrap();
    let n = DVec3::new(0.3, -0.5, 0.8).normalize();
    let p = c + DVec3::new(0.004, 0.002, -0.003);
    let hit = probe.ray_crossing(p, n).unwrap();
    // On the surface to rounding; on the line p + t n; outward normal ∥ gradient.
    assert!(probe.value(hit.point).abs() < 1e-12);
    assert!((hit.point - p).cross(n).length() < 1e-15);
    assert!((hit.point - p).length() - hit.depth < 1e-15);
    let g = probe.gradient(hit.point).normalize();
    assert!((g - hit.probe_normal).length() < 1e-12);
    // The other crossing is farther: walking `depth` the other way stays inside.
    assert!(probe.value(p - hit.exit_sign * hit.depth * n) < 0.0);
    // Exact AABB of the rotated ellipsoid touches the surface: a point on each face is outside
    // or on the probe, and the box is no larger than the bounding sphere.
    let (lo, hi) = probe.aabb();
    assert!((hi - c).max_element() <= 0.03 + 1e-15 && (c - lo).max_element() <= 0.03 + 1e-15);
}

#[test]
fn fig4_force_rises_to_its_peak_when_the_centre_touches_the_plane_then_falls() {
    // A sphere probe passes through a sampled plane (seed 004 Fig. 4). Sampling at R/50 with
    // cell-area weights; the sum approximates the disc integral whose integrand vanishes like a
    // square root at the rim, so the error is ~1e-3 of the peak: 1 % is a safe bound.
    let grid = SampleGrid::new(&sheet(1.2 * R, R / 50.0), R / 4.0).unwrap();
    let mut r = renderer(DirectionMethod::SurfaceNormal, 0.0);
    let peak = fig4_force(R, 0.0, KS);
    let steps = 80;
    let mut forces = Vec::new();
    for k in 0..=steps {
        let h = R - 2.0 * R * k as f64 / steps as f64;
        let f = r.query(&sphere_at(DVec3::new(0.0, 0.0, h)), &grid, DVec3::ZERO);
        let expect = fig4_force(R, h, KS);
        assert!(
            (f.force.length() - expect).abs() <= 0.01 * peak,
            "h={h}: {} vs {expect}",
            f.force.length()
        );
        assert!(
            f.force.x.abs() + f.force.y.abs() < 1e-9 * peak,
            "lateral force {}",
            f.force
        );
        forces.push(f.force.z);
    }
    let top = forces.iter().cloned().fold(f64::MIN, f64::max);
    assert_eq!(
        forces[steps / 2],
        top,
        "peak when the centre is on the plane"
    );
    assert!(
        forces[..=steps / 2].windows(2).all(|w| w[1] > w[0]),
        "rises"
    );
    assert!(forces[steps / 2..].windows(2).all(|w| w[1] < w[0]), "falls");
}

#[test]
fn ellipsoid_axes_and_orientation_change_the_contact() {
    let grid = SampleGrid::new(&sheet(0.05, 0.001), 0.01).unwrap();
    let mut r = renderer(DirectionMethod::SurfaceNormal, 0.0);
    let mut probe = Probe::ellipsoid(DVec3::new(0.03, 0.01, 0.01)).unwrap();
    probe
        .set_pose(ProbePose::at(DVec3::new(0.0, 0.0, 0.008)))
        .unwrap();
    let flat = r.query(&probe, &grid, DVec3::ZERO);
    let upright = DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2);
    probe
        .set_pose(ProbePose {
            position: DVec3::new(0.0, 0.0, 0.028),
            orientation: upright,
        })
        .unwrap();
    let tip = r.query(&probe, &grid, DVec3::ZERO);
    // Same 2 mm intrusion: lying flat touches a long strip, standing on end a small disc.
    assert!(
        flat.contact_area > 2.0 * tip.contact_area,
        "{flat:?} {tip:?}"
    );
    probe.set_semi_axes(DVec3::splat(0.02)).unwrap();
    assert!(matches!(
        probe.set_semi_axes(DVec3::new(0.0, 1.0, 1.0)),
        Err(ProbeError::BadSemiAxes(_))
    ));
    assert_eq!(
        probe.semi_axes(),
        DVec3::splat(0.02),
        "failed update leaves the probe unchanged"
    );
}

#[test]
fn indexed_query_equals_brute_force_and_is_deterministic() {
    let samples: Vec<SurfaceSample> = edge(0.04, 0.0013);
    let grid = SampleGrid::new(&samples, 0.007).unwrap();
    let q = DQuat::from_euler(glam::EulerRot::ZYX, 0.7, 0.2, -0.4);
    let probe = Probe::ellipsoid(DVec3::new(0.015, 0.008, 0.011))
        .unwrap()
        .posed(ProbePose {
            position: DVec3::new(0.002, 0.003, 0.001),
            orientation: q,
        })
        .unwrap();
    for method in [DirectionMethod::SurfaceNormal, DirectionMethod::ProbeNormal] {
        let mut r = renderer(method, 50.0);
        let v = DVec3::new(0.01, 0.0, -0.02);
        let a = r.query(&probe, &grid, v);
        let mut seen: Vec<u32> = r.contacts().iter().map(|c| c.sample).collect();
        let b = r.query_slice(&probe, &samples, v);
        let mut seen_b: Vec<u32> = r.contacts().iter().map(|c| c.sample).collect();
        seen.sort_unstable();
        seen_b.sort_unstable();
        assert_eq!(seen, seen_b, "same contacts");
        assert!(a.contact_count > 100);
        // Different summation order only: relative 1e-12.
        assert!(
            (a.force - b.force).length() <= 1e-12 * a.force.length(),
            "{a:?} {b:?}"
        );
        assert_eq!(r.query(&probe, &grid, v), a, "bit-identical on repeat");
    }
}

#[test]
fn damping_resists_approach_and_never_pulls() {
    let grid = SampleGrid::new(&sheet(0.03, 0.001), 0.01).unwrap();
    let mut r = renderer(DirectionMethod::SurfaceNormal, 2.0e4);
    let probe = sphere_at(DVec3::new(0.0, 0.0, R - 0.003));
    let rest = r.query(&probe, &grid, DVec3::ZERO);
    let pushing = r.query(&probe, &grid, DVec3::new(0.0, 0.0, -0.1));
    let leaving_fast = r.query(&probe, &grid, DVec3::new(0.0, 0.0, 100.0));
    let expect = rest.spring + rest.damping * 0.1;
    assert!(
        (pushing.force.z - expect).abs() < 1e-12 * expect,
        "{pushing:?}"
    );
    assert_eq!(
        leaving_fast.force,
        DVec3::ZERO,
        "clamped: springs never pull"
    );
}

#[test]
fn non_finite_inputs_give_finite_forces() {
    let mut samples = sheet(0.03, 0.002);
    let grid = SampleGrid::new(&samples, 0.01).unwrap();
    let mut r = renderer(DirectionMethod::ProbeNormal, 10.0);
    let mut probe = sphere_at(DVec3::new(0.0, 0.0, 0.01));
    let f = r.query(&probe, &grid, DVec3::new(f64::NAN, 0.0, f64::INFINITY));
    assert!(
        f.force.is_finite() && f.force.z > 0.0,
        "NaN velocity is ignored: {f:?}"
    );
    let bad = ProbePose::at(DVec3::new(f64::NAN, 0.0, 0.0));
    assert_eq!(probe.set_pose(bad), Err(ProbeError::BadPose));
    let unnormalised = ProbePose {
        position: DVec3::ZERO,
        orientation: DQuat::from_xyzw(0.0, 0.0, 0.0, 2.0),
    };
    assert_eq!(probe.set_pose(unnormalised), Err(ProbeError::BadPose));
    samples[7].position.x = f64::NAN;
    assert_eq!(
        SampleGrid::new(&samples, 0.01).unwrap_err(),
        ProbeError::BadSample { index: 7 }
    );
    // A plain slice with a poisoned sample: it is skipped, the force stays finite.
    let f = r.query_slice(&probe, &samples, DVec3::ZERO);
    assert!(f.force.is_finite() && f.contact_count > 0);
    assert!(SampleGrid::new(&samples[..1], f64::NAN).is_err());
}

#[test]
fn update_rebins_moved_samples_allocation_free_with_fixed_count() {
    let samples = sheet(0.03, 0.002);
    let mut grid = SampleGrid::new(&samples, 0.01).unwrap();
    let moved: Vec<SurfaceSample> = samples
        .iter()
        .map(|s| SurfaceSample {
            position: s.position + DVec3::new(0.5, 0.0, -0.004),
            ..*s
        })
        .collect();
    grid.update(&moved).unwrap();
    let mut r = renderer(DirectionMethod::SurfaceNormal, 0.0);
    let a = r.query(&sphere_at(DVec3::new(0.5, 0.0, 0.01)), &grid, DVec3::ZERO);
    let b = r.query_slice(&sphere_at(DVec3::new(0.5, 0.0, 0.01)), &moved, DVec3::ZERO);
    assert!(a.contact_count > 0 && (a.force - b.force).length() <= 1e-12 * a.force.length());
    assert!(matches!(
        grid.update(&moved[1..]),
        Err(ProbeError::SampleCountChanged { .. })
    ));
}

#[test]
fn local_model_reproduces_the_probe_force_at_the_cursor_and_near_it() {
    let grid = SampleGrid::new(&sheet(0.04, 0.0008), 0.01).unwrap();
    let mut r = renderer(DirectionMethod::SurfaceNormal, 500.0);
    let c = DVec3::new(0.001, -0.002, R - 0.004);
    let v = DVec3::new(0.0, 0.01, -0.02);
    let f = r.query(&sphere_at(c), &grid, v);
    let out = f.output(c, 0.005, 0.05);
    assert_eq!(out.model.kind, ModelKind::Plane);
    let cmd = out.to_command(1, 2);
    let rendered = ModelRenderer::new().render(&cmd, c.as_vec3(), v.as_vec3(), 0);
    // f32 wire: relative 1e-5.
    assert!(
        (rendered.as_dvec3() - f.force).length() <= 1e-5 * f.force.length(),
        "{rendered} vs {}",
        f.force
    );
    // 0.2 mm deeper: the plane's stiffness is k_s·A, the true force grows by k_s·∫ΔA too, so
    // the model is a first-order prediction; its error is second order: < 5 % of the change.
    let c2 = c - DVec3::new(0.0, 0.0, 0.0002);
    let truth = r.query(&sphere_at(c2), &grid, DVec3::ZERO).force;
    let model = ModelRenderer::new()
        .render(&cmd, c2.as_vec3(), Vec3::ZERO, 0)
        .as_dvec3();
    let at_rest = r.query(&sphere_at(c), &grid, DVec3::ZERO).force;
    assert!(
        (model - truth).length() <= 0.05 * (truth - at_rest).length(),
        "{model} vs {truth}"
    );
    // Deep: the centre 5 mm below the sheet, the equivalent plane depth far beyond the 5 mm
    // radius; the model still covers the cursor (its radius grows by the offset).
    let deep = DVec3::new(0.0, 0.0, -0.005);
    let f = r.query(&sphere_at(deep), &grid, DVec3::ZERO);
    let cmd = f.output(deep, 0.005, 0.05).to_command(0, 0);
    let at = ModelRenderer::new()
        .render(&cmd, deep.as_vec3(), Vec3::ZERO, 0)
        .as_dvec3();
    assert!(
        (at - f.force).length() <= 1e-5 * f.force.length(),
        "{at} vs {}",
        f.force
    );
    let none = r
        .query(&sphere_at(DVec3::new(0.0, 0.0, 1.0)), &grid, DVec3::ZERO)
        .output(c, 0.005, 0.05);
    assert_eq!(none.model.kind, ModelKind::None);
    assert_eq!(none.force, DVec3::ZERO);
}
