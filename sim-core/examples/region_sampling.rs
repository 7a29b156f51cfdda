//! How long a sculpting region's grid takes to sample: evaluating every node
//! (`sparse::sample_trusted_dense`) against the block-sparse engine (`sparse::sample_trusted`),
//! same process, same field, same grid, with the equality of the two checked.
//!
//! `cargo run --release -p sim-core --example region_sampling -- [POINTS] [CELLS] [REPEATS]`

use std::time::Instant;

use glam::DVec3;
use sim_core::grid::GridSpec;
use sim_core::reconstruct::{IgnoreStages, NormalPolicy, reconstruct};
use sim_core::sampling::Shape;
use sim_core::sparse::{sample_trusted, sample_trusted_dense};
use sim_core::{FitParams, NoProgress};

fn main() {
    let arg = |i: usize, d: usize| {
        std::env::args()
            .nth(i)
            .and_then(|s| s.parse().ok())
            .unwrap_or(d)
    };
    let (points, cells, repeats) = (arg(1, 16_071), arg(2, 40), arg(3, 5).max(1));
    let sphere = Shape::Sphere { radius: 0.05 };
    let rec = reconstruct(
        &sphere.sample(points, 1),
        &FitParams::default(),
        NormalPolicy::Keep,
        &mut IgnoreStages,
        &NoProgress,
    )
    .expect("fit");
    // The bench-sim region: the whole sphere plus two cells, `cells` cells across.
    let half = 0.05 * (1.0 + 2.0 / cells as f64);
    let spec = GridSpec::covering(
        DVec3::splat(-half),
        DVec3::splat(half),
        2.0 * half / cells as f64,
    );
    let time = |f: &dyn Fn() -> Vec<f64>| -> (f64, f64, f64, Vec<f64>) {
        let mut t = Vec::new();
        let mut out = Vec::new();
        for _ in 0..repeats {
            let s = Instant::now();
            out = f();
            t.push(s.elapsed().as_secs_f64() * 1e3);
        }
        t.sort_by(f64::total_cmp);
        (t[t.len() / 2], t[0], t[t.len() - 1], out)
    };
    let dense = time(&|| sample_trusted_dense(&rec.field, spec).values().to_vec());
    let sparse = time(&|| sample_trusted(&rec.field, spec).values().to_vec());
    assert_eq!(
        dense.3, sparse.3,
        "the sparse grid differs from the dense one"
    );
    println!(
        "{points} points, {:?} nodes, {repeats} runs: dense {:.1} ms ({:.1}–{:.1}), block-sparse {:.1} ms ({:.1}–{:.1}), {:.2}× faster, identical values",
        spec.dims,
        dense.0,
        dense.1,
        dense.2,
        sparse.0,
        sparse.1,
        sparse.2,
        dense.0 / sparse.0
    );
}
