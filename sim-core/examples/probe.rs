//! Scratch: fit an analytic shape and print time and zero-set error. `cargo run --release
//! --example probe -- sphere 10000 20 0.1 0.7 1e-5`.
use std::time::Instant;

use sim_core::accuracy::zero_set_error;
use sim_core::reconstruct::{IgnoreStages, NormalPolicy, reconstruct};
use sim_core::sampling::Shape;
use sim_core::{FitParams, NoProgress};

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let arg = |i: usize, d: f64| a.get(i).and_then(|s| s.parse().ok()).unwrap_or(d);
    let shape = match a.get(1).map(String::as_str).unwrap_or("sphere") {
        "cylinder" => Shape::Cylinder {
            radius: 0.5,
            half_height: 0.8,
        },
        "plate" => Shape::Plate {
            half_size: 0.5,
            thickness: 0.004,
        },
        "torus" => Shape::Torus {
            major: 1.0,
            minor: 0.4,
        },
        _ => Shape::Sphere { radius: 1.0 },
    };
    let n = arg(2, 10000.0) as usize;
    let params = FitParams {
        k: arg(3, 20.0) as usize,
        offset: arg(4, 0.1),
        weight_width: arg(5, 0.7),
        regularization: arg(6, 1e-5),
        size: arg(7, 3.0) as usize,
        support: arg(8, 1.0),
        normal_agreement: arg(9, -0.5),
        ..FitParams::default()
    };
    let pts = shape.sample(n, 1);
    let t = Instant::now();
    let rec = reconstruct(
        &pts,
        &params,
        NormalPolicy::Keep,
        &mut IgnoreStages,
        &NoProgress,
    )
    .unwrap();
    let dt = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let e = zero_set_error(&rec.field, &shape, 10_000, 0.5, 7);
    println!(
        "n={n} {params:?}\nconstruct {dt:.3}s  rms {:.3e} max {:.3e} (rel) unconv {} eval {:.3}s",
        e.rms_relative(),
        e.max_relative(),
        e.unconverged,
        t.elapsed().as_secs_f64()
    );
}
