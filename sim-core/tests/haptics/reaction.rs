//! Sculpting reaction: Newton's third law through an anchor model, and the Hua–Qin mapping.

use glam::{DVec3, Vec3};
use protocol::{ModelKind, ModelRenderer};
use sim_core::bspline_surface::{BicubicPatch, MassSpringMesh, MeshParams, ProbeSculptor};
use sim_core::haptic::{
    ToolReaction, dynamic_stiffness, hua_qin_force, series_stiffness, value_forces_in_space,
};
use sim_core::probe::{ContactParams, DirectionMethod, MagnitudeMethod, Probe, ProbePose};

fn reaction(material: f64) -> ToolReaction {
    ToolReaction {
        applied: DVec3::new(0.0, 0.0, 0.8),
        tool_stiffness: 300.0,
        material_stiffness: material,
        damping: 0.0,
    }
}

#[test]
fn series_stiffness_is_bounded_by_the_tool_and_grows_with_the_material() {
    assert_eq!(series_stiffness(300.0, f64::INFINITY), 300.0);
    assert_eq!(series_stiffness(300.0, 0.0), 0.0);
    assert!((series_stiffness(300.0, 300.0) - 150.0).abs() < 1e-12);
    assert!(series_stiffness(300.0, 100.0) < series_stiffness(300.0, 1000.0));
    assert_eq!(series_stiffness(f64::NAN, 100.0), 0.0);
    // Heavier material resists more over the same horizon.
    assert!(dynamic_stiffness(100.0, 1.0, 0.01) > dynamic_stiffness(100.0, 0.01, 0.01));
    assert_eq!(dynamic_stiffness(100.0, 1.0, 0.0), 100.0);
}

#[test]
fn reaction_is_the_applied_force_reversed_and_a_stiffer_material_feels_stiffer() {
    let cursor = DVec3::new(0.01, 0.02, -0.005);
    let mut felt = Vec::new();
    for material in [50.0, 500.0, f64::INFINITY] {
        let out = reaction(material).output(cursor, 0.01, 0.05);
        assert_eq!(out.force, DVec3::new(0.0, 0.0, -0.8));
        assert_eq!(out.model.kind, ModelKind::Anchor);
        let cmd = out.to_command(0, 0);
        let at = ModelRenderer::new().render(&cmd, cursor.as_vec3(), Vec3::ZERO, 0);
        // f32 wire: 1e-6 N.
        assert!((at.as_dvec3() - out.force).length() < 1e-6, "{at}");
        // Pull 1 mm further: the force grows by k_series × 1 mm.
        let moved = cursor - DVec3::new(0.0, 0.0, 0.001);
        let f = ModelRenderer::new().render(&cmd, moved.as_vec3(), Vec3::ZERO, 0);
        felt.push((f.as_dvec3() - out.force).z);
    }
    assert!(felt[0] < felt[1] && felt[1] < felt[2], "{felt:?}");
    assert!(
        (felt[2] - 0.3).abs() < 1e-5,
        "rigid material: the tool spring alone"
    );
}

#[test]
fn letting_go_releases_and_bad_inputs_are_idle() {
    let out = ToolReaction {
        applied: DVec3::ZERO,
        ..reaction(500.0)
    }
    .output(DVec3::ZERO, 0.01, 0.05);
    assert_eq!(out.force, DVec3::ZERO);
    assert_eq!(out.model.kind, ModelKind::None);
    let nan = ToolReaction {
        applied: DVec3::splat(f64::NAN),
        ..reaction(500.0)
    }
    .output(DVec3::ZERO, 0.01, 0.05);
    assert_eq!(nan.force, DVec3::ZERO);
    assert!(hua_qin_force([(f64::NAN, DVec3::X), (1.0, DVec3::splat(f64::INFINITY))]).is_finite());
}

#[test]
fn hua_qin_equals_the_direct_reaction_at_equilibrium_under_a_uniform_profile() {
    // A pinned 9×9 membrane loaded by 0.01 N on its 3×3 centre nodes (profile s = 1 there),
    // settled: the springs hold the load, so Σ s_j F_int,j = −Σ applied. Residual motion after
    // 3 s at damping 200/s is far below 0.1 %.
    let n = 9;
    let params = MeshParams {
        total_mass: 0.01,
        stiffness: 20.0,
        bending: 0.0,
        damping_rate: 200.0,
        plastic_rate: 0.0,
        pin_border: true,
    };
    let mut mesh = MassSpringMesh::new(
        n,
        BicubicPatch::flat(n, 0.02).unwrap().control().to_vec(),
        params,
    )
    .unwrap();
    let mut ext = vec![DVec3::ZERO; n * n];
    let centre: Vec<usize> = (3..6)
        .flat_map(|i| (3..6).map(move |j| i * n + j))
        .collect();
    for &q in &centre {
        ext[q] = DVec3::new(0.0, 0.0, -0.01);
    }
    for _ in 0..3000 {
        mesh.step(0.001, &ext).unwrap();
    }
    let mut internal = vec![DVec3::ZERO; n * n];
    mesh.internal_forces(&mut internal);
    let hq = hua_qin_force(centre.iter().map(|&q| (1.0, internal[q])));
    let direct = -ext.iter().sum::<DVec3>();
    assert!(
        (hq - direct).length() < 1e-3 * direct.length(),
        "{hq} vs {direct}"
    );
}

#[test]
fn sculpting_reaction_pushes_back_and_hua_qin_agrees_in_direction() {
    let n = 21;
    let params = MeshParams::REFERENCE;
    let contact = ContactParams {
        surface_stiffness: 5.0e6,
        surface_damping: 0.0,
        method: DirectionMethod::SurfaceNormal,
        magnitude: MagnitudeMethod::SpringSum,
    };
    let mut s = ProbeSculptor::new(
        BicubicPatch::flat(n, 0.05).unwrap(),
        params,
        contact,
        0.005,
        0.01,
    )
    .unwrap();
    let r = 0.008;
    let mut probe = Probe::sphere(r).unwrap();
    let mut last = None;
    for t in 0..400 {
        let z = r - 0.006 * (t as f64 / 100.0).min(1.0);
        probe
            .set_pose(ProbePose::at(DVec3::new(0.0, 0.0, z)))
            .unwrap();
        last = Some(s.tick(&probe, DVec3::ZERO, true, 0.001).unwrap());
    }
    let t = last.unwrap();
    let (direct, hq) = (t.output.force, t.hua_qin);
    eprintln!(
        "reaction after hold: direct {direct} hua-qin {hq} ratio {:.3}",
        hq.length() / direct.length()
    );
    assert!(
        direct.z > 0.0 && t.applied.z < 0.0,
        "pushing down, the material pushes up"
    );
    // The profile weights s = d/d_max ≤ 1 discount the rim: Hua–Qin is smaller, same direction.
    assert!(
        hq.angle_between(direct) < 5f64.to_radians(),
        "{hq} vs {direct}"
    );
    assert!(hq.length() > 0.0 && hq.length() <= 1.05 * direct.length());
    // Button up: no more deformation force; what remains is rigid touch, no reaction.
    let up = s.tick(&probe, DVec3::ZERO, false, 0.001).unwrap();
    assert_eq!(up.applied, DVec3::ZERO);
}

#[test]
fn a_rope_pulling_values_outward_is_felt_pulling_back_inward() {
    // Seed 000's rope on a plane's distance field (∇f = +z): value forces −strength·w_j lower
    // the values near the pick, raising the surface. In space that is +z·strength·Σw; the user
    // feels the reverse through an anchor model.
    let (strength, weights) = (0.2, [1.0, 0.6, 0.6, 0.1]);
    let applied = value_forces_in_space(weights.iter().map(|w| (-strength * w, DVec3::Z)));
    assert!(
        (applied - DVec3::new(0.0, 0.0, 0.2 * 2.3)).length() < 1e-12,
        "{applied}"
    );
    let felt = ToolReaction {
        applied,
        tool_stiffness: 200.0,
        material_stiffness: 80.0,
        damping: 0.0,
    }
    .output(DVec3::new(0.0, 0.0, 0.01), 0.005, 0.02);
    assert!(felt.force.z < 0.0 && felt.force.x == 0.0, "{felt:?}");
    assert!(value_forces_in_space([(f64::NAN, DVec3::Z)]) == DVec3::ZERO);
}
