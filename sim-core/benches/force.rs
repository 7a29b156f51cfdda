//! Haptic query benches (issue 6): the field force at a contact, the shaped probe with ≈2,000
//! contacts, and one pressed tick of the 30×30 B-spline dual. Seeded inputs; the force errors
//! that go with these timings are printed by `workstation bench-force` on the same run.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use sim_core::bspline_surface::{BicubicPatch, MeshParams, ProbeSculptor};
use sim_core::haptic::fixtures::{AnalyticField, contact_points};
use sim_core::haptic::{FieldContactParams, FieldForce};
use sim_core::probe::fixtures::sheet;
use sim_core::probe::{
    ContactParams, DirectionMethod, MagnitudeMethod, Probe, ProbePose, ProbeRenderer, SampleGrid,
};

const R: f64 = 0.02;

fn field(c: &mut Criterion) {
    let sphere = AnalyticField::Sphere { size: R };
    let grid = sphere.grid(R / 20.0);
    let points = contact_points(&sphere, 1024, 4, (0.1, 0.3));
    let mut ff = FieldForce::new(FieldContactParams {
        stiffness: 500.0,
        damping: 1.0,
        friction: 0.3,
        max_search: R,
        approach_margin: 0.1 * R,
        validity_radius: 0.1 * R,
        lifetime_s: 0.05,
    })
    .unwrap();
    let mut i = 0;
    c.bench_function("field_query_sphere_r20", |b| {
        b.iter(|| {
            i = (i + 1) % points.len();
            ff.reset();
            black_box(ff.query(&grid, points[i].0, DVec3::X * 0.05).output.force)
        })
    });
}

fn probe(c: &mut Criterion) {
    let spacing = (std::f64::consts::PI * R * R / 2000.0).sqrt();
    let grid = SampleGrid::new(&sheet(1.5 * R, spacing), 0.25 * R).unwrap();
    // Force only (no contact list) for both direction methods, then with the contact list the
    // sculptor needs.
    let cases = [
        (
            "probe_query_2000_surface_normal",
            DirectionMethod::SurfaceNormal,
            0,
        ),
        (
            "probe_query_2000_probe_normal",
            DirectionMethod::ProbeNormal,
            0,
        ),
        (
            "probe_query_2000_with_contacts",
            DirectionMethod::SurfaceNormal,
            8192,
        ),
    ];
    for (name, method, record) in cases {
        let params = ContactParams {
            surface_stiffness: 1e6,
            surface_damping: 20.0,
            method,
            magnitude: MagnitudeMethod::SpringSum,
        };
        let mut r = ProbeRenderer::new(params, record).unwrap();
        let probe = Probe::sphere(R)
            .unwrap()
            .posed(ProbePose::at(DVec3::ZERO))
            .unwrap();
        c.bench_function(name, |b| {
            b.iter(|| black_box(r.query(&probe, &grid, DVec3::new(0.0, 0.0, -0.01)).force))
        });
    }
}

fn sculpt(c: &mut Criterion) {
    let mesh = MeshParams::REFERENCE;
    let contact = ContactParams {
        surface_stiffness: 5.0e6,
        surface_damping: 0.0,
        method: DirectionMethod::SurfaceNormal,
        magnitude: MagnitudeMethod::SpringSum,
    };
    let patch = BicubicPatch::flat(30, 0.05).unwrap();
    let mut s = ProbeSculptor::new(patch, mesh, contact, 0.005, 0.01).unwrap();
    let probe = Probe::sphere(0.008)
        .unwrap()
        .posed(ProbePose::at(DVec3::new(0.0, 0.0, 0.003)))
        .unwrap();
    c.bench_function("sculpt_tick_30x30_pressed", |b| {
        b.iter(|| {
            black_box(
                s.tick(&probe, DVec3::ZERO, true, 0.001)
                    .unwrap()
                    .output
                    .force,
            )
        })
    });
    c.bench_function("dual_to_control_30x30", |b| {
        b.iter(|| black_box(s.update_display().n()))
    });
}

criterion_group! {
    name = benches;
    // No plots: criterion's plotters backend needs system fonts the CI image lacks.
    config = Criterion::default().without_plots();
    targets = field, probe, sculpt
}
criterion_main!(benches);
