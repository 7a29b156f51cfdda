//! Shared fixtures: exact signed-distance grids and small models.

use glam::DVec3;
use sim_core::dynamics::{DynamicGrid, NodeParams};
use sim_core::grid::{GridSpec, ScalarGrid};

/// A sphere's exact signed distance sampled on a cube grid of `n` nodes per axis spanning
/// `[-half, half]³`.
pub fn sphere_grid(radius: f64, half: f64, n: usize) -> ScalarGrid {
    let spacing = 2.0 * half / (n - 1) as f64;
    let spec = GridSpec::covering(DVec3::splat(-half), DVec3::splat(half), spacing);
    ScalarGrid::from_fn(spec, |x| x.length() - radius)
}

/// A model of every node of an `n³` sphere grid (no band): the smallest useful system.
pub fn small_model(n: usize, params: NodeParams) -> DynamicGrid {
    DynamicGrid::new(&sphere_grid(0.3, 0.5, n), f64::INFINITY, params).unwrap()
}

/// Seeded displacement pattern of amplitude `amp` (deterministic, no RNG dependency).
pub fn perturb(model: &mut DynamicGrid, amp: f64) {
    let n = model.active_len();
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    let u: Vec<f64> = (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            amp * ((x >> 11) as f64 / (1u64 << 53) as f64 - 0.5)
        })
        .collect();
    model.set_state(&u, &vec![0.0; n]).unwrap();
}

/// A fitted analytic shape as a scene object (seeded samples with exact normals).
pub fn fitted_object(
    shape: sim_core::sampling::Shape,
    n: usize,
    seed: u64,
) -> sim_core::scene::SceneObject {
    let ps = shape.sample(n, seed);
    sim_core::scene::SceneObject::fit("shape", ps, &sim_core::FitParams::default()).unwrap()
}
