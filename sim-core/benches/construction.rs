//! Criterion benchmarks of the point-set surface: construction (k-NN + fits) at 10k and 67k
//! points, and the per-query costs later stages pay: `value_and_gradient` and Newton projection.
//! Seeded inputs. The speed-against-error table lives in docs/BENCHMARKS.md (`fit_sweep`).

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use glam::DVec3;
use sim_core::reconstruct::{IgnoreStages, NormalPolicy, reconstruct};
use sim_core::sampling::Shape;
use sim_core::{FitParams, NoProgress};

fn construction(c: &mut Criterion) {
    let mut group = c.benchmark_group("construct_sphere");
    group.sample_size(10);
    for n in [10_000usize, 67_038] {
        let points = Shape::Sphere { radius: 1.0 }.sample(n, 1);
        for k in [12usize, 20] {
            let params = FitParams {
                k,
                ..FitParams::default()
            };
            group.bench_with_input(BenchmarkId::new(format!("k{k}"), n), &points, |b, pts| {
                b.iter(|| {
                    reconstruct(
                        pts,
                        &params,
                        NormalPolicy::Keep,
                        &mut IgnoreStages,
                        &NoProgress,
                    )
                    .expect("fit")
                })
            });
        }
    }
    group.finish();
}

fn queries(c: &mut Criterion) {
    let shape = Shape::Torus {
        major: 1.0,
        minor: 0.4,
    };
    let points = shape.sample(67_038, 1);
    let rec = reconstruct(
        &points,
        &FitParams::default(),
        NormalPolicy::Keep,
        &mut IgnoreStages,
        &NoProgress,
    )
    .expect("fit");
    let probes: Vec<DVec3> = shape
        .sample(1024, 2)
        .positions
        .iter()
        .map(|p| *p * 1.003)
        .collect();
    c.bench_function("value_and_gradient_1024_near_surface", |b| {
        b.iter(|| {
            probes
                .iter()
                .map(|&x| rec.field.value_and_gradient(x).0)
                .sum::<f64>()
        })
    });
    c.bench_function("project_to_zero_set_1024", |b| {
        b.iter(|| {
            probes
                .iter()
                .map(|&x| rec.field.project_to_zero_set(x).point.x)
                .sum::<f64>()
        })
    });
}

criterion_group! {
    name = benches;
    // No HTML plots: the workspace's plotters uses ab_glyph fonts, which criterion does not load.
    config = Criterion::default().without_plots();
    targets = construction, queries
}
criterion_main!(benches);
