//! The per-query contract: after warm-up, no haptic query allocates, and repeated runs are
//! bit-identical. A counting global allocator (per thread, so parallel tests do not interfere)
//! checks the first; comparing two fresh runs checks the second.

use crate::counting_alloc::allocations_in;
use glam::DVec3;
use sim_core::bspline_surface::{BicubicPatch, MeshParams, ProbeSculptor};
use sim_core::haptic::fixtures::AnalyticField;
use sim_core::haptic::{FieldContactParams, FieldForce, ToolReaction};
use sim_core::probe::fixtures::sheet;
use sim_core::probe::{
    ContactParams, DirectionMethod, MagnitudeMethod, Probe, ProbePose, ProbeRenderer, SampleGrid,
};

fn sculptor() -> ProbeSculptor {
    let mesh = MeshParams {
        plastic_rate: 1.0,
        ..MeshParams::REFERENCE
    };
    let contact = ContactParams {
        surface_stiffness: 5e6,
        surface_damping: 1.5e4,
        method: DirectionMethod::SurfaceNormal,
        magnitude: MagnitudeMethod::SpringSum,
    };
    ProbeSculptor::new(
        BicubicPatch::flat(12, 0.03).unwrap(),
        mesh,
        contact,
        0.005,
        0.004,
    )
    .unwrap()
}

#[test]
fn haptic_queries_do_not_allocate_after_construction() {
    let sphere = AnalyticField::Sphere { size: 0.02 };
    let grid = sphere.grid(0.001);
    let params = FieldContactParams {
        stiffness: 500.0,
        damping: 1.0,
        friction: 0.3,
        max_search: 0.02,
        approach_margin: 0.002,
        validity_radius: 0.002,
        lifetime_s: 0.05,
    };
    let mut ff = FieldForce::new(params).unwrap();
    let samples = sheet(0.03, 0.0005);
    let mut index = SampleGrid::new(&samples, 0.004).unwrap();
    let contact = ContactParams {
        surface_stiffness: 1e6,
        surface_damping: 10.0,
        method: DirectionMethod::ProbeNormal,
        magnitude: MagnitudeMethod::SpringSum,
    };
    let mut pr = ProbeRenderer::new(contact, 10_000).unwrap();
    let probe = Probe::ellipsoid(DVec3::new(0.01, 0.006, 0.008))
        .unwrap()
        .posed(ProbePose::at(DVec3::new(0.001, 0.0, 0.004)))
        .unwrap();
    let mut s = sculptor();
    let tool = Probe::sphere(0.006)
        .unwrap()
        .posed(ProbePose::at(DVec3::new(0.0, 0.0, 0.004)))
        .unwrap();
    let n = allocations_in(|| {
        for k in 0..50 {
            let x = DVec3::new(0.004, 0.005, 0.017 - k as f64 * 1e-4);
            let q = ff.query(&grid, x, DVec3::X * 0.01);
            std::hint::black_box(q.output.to_command(k, 0));
            let f = pr.query(&probe, &index, DVec3::Z * -0.01);
            std::hint::black_box(f.output(probe.center(), 0.005, 0.05).to_command(k, 0));
            std::hint::black_box(pr.query_slice(&probe, &samples, DVec3::ZERO));
            std::hint::black_box(s.tick(&tool, DVec3::ZERO, k % 2 == 0, 0.001).unwrap());
            let reaction = ToolReaction {
                applied: DVec3::Z,
                tool_stiffness: 300.0,
                material_stiffness: 100.0,
                damping: 0.5,
            };
            std::hint::black_box(reaction.output(x, 0.01, 0.05).to_command(k, 0));
        }
        index.update(&samples).unwrap();
        std::hint::black_box(s.update_display().n());
    });
    assert_eq!(n, 0, "{n} allocations in the haptic loop");
    // The counter does count (so the check above can fail).
    assert!(allocations_in(|| drop(std::hint::black_box(vec![1u8; 10]))) > 0);
}

#[test]
fn sculpting_is_deterministic_bit_for_bit() {
    let run = || {
        let mut s = sculptor();
        let mut probe = Probe::sphere(0.006).unwrap();
        let mut forces = Vec::new();
        for k in 0..200 {
            let z = 0.008 - 0.00003 * k as f64;
            probe
                .set_pose(ProbePose::at(DVec3::new(0.0001 * k as f64, 0.0, z)))
                .unwrap();
            forces.push(
                s.tick(&probe, DVec3::new(0.1, 0.0, -0.03), true, 0.001)
                    .unwrap()
                    .output
                    .force,
            );
        }
        (forces, s.update_display().control().to_vec())
    };
    assert_eq!(run(), run());
}

#[test]
fn renderers_move_to_the_force_thread_and_snapshots_are_shared() {
    // Compile-time contract: a force-mapping thread owns the renderers (Send) and reads the
    // simulation's snapshots through an `Arc` (Send + Sync).
    fn owned<T: Send + 'static>() {}
    fn shared<T: Send + Sync + 'static>() {}
    owned::<FieldForce>();
    owned::<ProbeRenderer>();
    owned::<ProbeSculptor>();
    shared::<sim_core::grid::ScalarGrid>();
    shared::<SampleGrid>();
    shared::<Probe>();
}
