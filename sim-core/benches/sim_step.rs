//! Criterion benchmarks of the dynamic model (issue 5) on the papers' Table 3 case: a sphere of
//! 16,071 points, a 40³ region grid over the whole object, a 3-cell band. Per integrator: the
//! integrator step alone; and one full sculpting step (rope, integrate, points follow) with a
//! rope dragged around the top. Seeded inputs. Timings with their field error are printed by
//! `workstation bench-sim` and tabulated in docs/BENCHMARKS.md.

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use sim_core::FitParams;
use sim_core::dynamics::{Integrator, Stepper};
use sim_core::sampling::Shape;
use sim_core::scene::{RegionParams, Scene, SceneObject};
use sim_core::tools::{Profile, Rope};

const R: f64 = 0.05;

fn scene(integrator: Integrator) -> Scene {
    let ps = Shape::Sphere { radius: R }.sample(16_071, 1);
    let object = SceneObject::fit("sphere", ps, &FitParams::default()).expect("fit");
    let mut scene = Scene::new();
    let id = scene.add(object);
    let h = 2.0 * R / 35.0;
    let params = RegionParams {
        integrator,
        ..RegionParams::new(h, 3.0 * h)
    };
    let half = R + 2.0 * h;
    scene
        .open_region(id, DVec3::splat(-half), DVec3::splat(half), params)
        .expect("region");
    scene
}

fn rope_at(i: usize) -> Rope {
    let phase = std::f64::consts::TAU * i as f64 * 1e-3 / 0.2;
    let tilt = 20f64.to_radians();
    Rope {
        path: vec![
            R * DVec3::new(
                tilt.sin() * phase.cos(),
                tilt.sin() * phase.sin(),
                tilt.cos(),
            ),
        ],
        radius: 0.4 * R,
        strength: 100.0 * 0.1 * R,
        profile: Profile::Gaussian,
        sheet: None,
    }
}

fn steps(c: &mut Criterion) {
    let mut group = c.benchmark_group("sim_step_40cubed_16k");
    group.sample_size(30);
    for integrator in [
        Integrator::SymplecticEuler,
        Integrator::forward_euler(1e6),
        Integrator::backward_euler(),
    ] {
        let mut s = scene(integrator);
        // Load the model once so the integrator works on a non-trivial state.
        for i in 0..50 {
            s.step(1e-3, &[rope_at(i)]).expect("step");
        }
        let mut model = s.region().expect("region").model().clone();
        let mut stepper = Stepper::new(integrator);
        group.bench_function(format!("integrate/{}", integrator.name()), |b| {
            b.iter(|| stepper.step(&mut model, 1e-3).expect("step"))
        });
        let mut i = 50;
        group.bench_function(format!("full_step/{}", integrator.name()), |b| {
            b.iter(|| {
                i += 1;
                s.step(1e-3, &[rope_at(i)]).expect("step")
            })
        });
    }
    group.finish();
}

criterion_group!(benches, steps);
criterion_main!(benches);
