//! Regressions from the robustness review: grid sizes driven by user spacings.

use glam::DVec3;
use sim_core::grid::{GridSpec, MAX_NODES};
use sim_core::sampling::Shape;
use sim_core::scene::{RegionParams, Scene};

use crate::common::fitted_object;

#[test]
fn absurd_grids_are_errors_not_overflow_panics() {
    // A spacing of 1e-300 over a unit box used to panic with "attempt to add with overflow"
    // (and, without overflow checks, wrap to a tiny grid).
    for spacing in [1e-300, 1e-6, f64::MIN_POSITIVE] {
        let r = GridSpec::try_covering(DVec3::ZERO, DVec3::ONE, spacing);
        assert!(r.is_err(), "{spacing}: {r:?}");
    }
    let ok = GridSpec::try_covering(DVec3::ZERO, DVec3::ONE, 0.01).unwrap();
    assert_eq!(ok.dims, [101, 101, 101]);
    assert!(ok.node_count() <= MAX_NODES);
    let mut scene = Scene::new();
    let id = scene.add(fitted_object(Shape::Sphere { radius: 0.05 }, 500, 1));
    let r = scene.open_region(
        id,
        DVec3::splat(-0.06),
        DVec3::splat(0.06),
        RegionParams::new(1e-200, 0.01),
    );
    assert!(r.is_err(), "{:?}", r.map(|_| ()));
    assert!(scene.region().is_none());
}
