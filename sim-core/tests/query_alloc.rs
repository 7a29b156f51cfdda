//! `value_and_gradient` and `project_to_zero_set` must not allocate: they run per haptic tick
//! and per grid node. A counting global allocator proves it for queries near and far from the
//! surface, including the nearest-point fallback.

#[path = "support/counting_alloc.rs"]
mod counting_alloc;

use glam::DVec3;
use sim_core::reconstruct::{IgnoreStages, NormalPolicy, reconstruct};
use sim_core::sampling::Shape;
use sim_core::{FitParams, NoProgress};

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

#[test]
fn queries_do_not_allocate() {
    let shape = Shape::Torus {
        major: 1.0,
        minor: 0.4,
    };
    let rec = reconstruct(
        &shape.sample(5000, 1),
        &FitParams::default(),
        NormalPolicy::Keep,
        &mut IgnoreStages,
        &NoProgress,
    )
    .expect("fit");
    let probes: Vec<DVec3> = shape
        .sample(500, 2)
        .positions
        .iter()
        .flat_map(|p| [*p * 1.01, *p * 0.99, *p * 3.0, DVec3::ZERO])
        .collect();
    let before = counting_alloc::allocations();
    let mut sum = 0.0;
    for &x in &probes {
        let (f, g) = rec.field.value_and_gradient(x);
        sum += f + g.x + rec.field.project_to_zero_set(x).point.y;
    }
    let after = counting_alloc::allocations();
    assert!(sum.is_finite());
    assert_eq!(
        after - before,
        0,
        "{} allocations in {} queries",
        after - before,
        probes.len()
    );
}
