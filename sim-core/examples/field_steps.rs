//! Diagnostic: where the blended field steps. Fits a PLY point file (points and normals) with
//! `workstation fit`'s defaults (or the `KEY=VALUE` overrides `line_probe` takes) and walks
//! 20,000 random lines, each 4 cells long (a cell being `CELL`, e.g. the longest side of the
//! points' box over the resolution), centred on random vertices of `MESH` (the fit's mesh, so
//! the lines cross the surface), 200 samples each. A step is a change between neighbouring
//! samples more than five times what the gradient accounts for (plus a thousandth of a
//! cell) that is still more than a thousandth of a cell across an interval of 1e-12 (a jump,
//! not a steep stretch); the largest is printed in cells.
//!
//! ```text
//! cargo run --release -p sim-core --example field_steps -- POINTS.ply MESH.ply CELL [KEY=VALUE ...]
//! ```
mod common;

use std::process::ExitCode;

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim_core::FitParams;

fn run(args: &[String]) -> Result<(), String> {
    let [points, mesh, cell, overrides @ ..] = args else {
        return Err("usage: field_steps POINTS.ply MESH.ply CELL [KEY=VALUE ...]".into());
    };
    let cell: f64 = cell.parse().map_err(|e| format!("CELL {cell}: {e}"))?;
    if !(cell > 0.0 && cell.is_finite()) {
        return Err(format!("CELL {cell}: expected a positive length"));
    }
    let points = common::read_ply(points)?.points;
    let vertices = common::read_ply(mesh)?.points.positions;
    if vertices.is_empty() {
        return Err("the mesh has no vertices".into());
    }
    let fit_defaults = FitParams {
        normal_weight: 0.25,
        regularization: 3e-4,
        centre_spacing: 0.35,
        gap_fields: 0.12,
        k_even: 16,
        even_lean: 0.2,
        misfit_width: 0.035,
        ..FitParams::default()
    };
    let params = common::fit_params(fit_defaults, overrides)?;
    let rec = common::fit(&points, &params)?;
    let field = &rec.field;
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    const LINES: usize = 20_000;
    const SAMPLES: usize = 200;
    let dt = 4.0 * cell / SAMPLES as f64;
    let (mut steps, mut worst) = (0usize, 0.0f64);
    for _ in 0..LINES {
        let centre = vertices[rng.random_range(0..vertices.len())];
        let dir = DVec3::new(
            rng.random::<f64>() - 0.5,
            rng.random::<f64>() - 0.5,
            rng.random::<f64>() - 0.5,
        )
        .normalize();
        let mut prev = field.value_and_gradient(centre - dir * (2.0 * cell));
        for s in 1..=SAMPLES {
            let here = centre + dir * (-2.0 * cell + dt * s as f64);
            let (f, g) = field.value_and_gradient(here);
            let change = (f - prev.0).abs();
            if change > 5.0 * dt * 0.5 * (g.length() + prev.1.length()) + 1e-3 * cell
                && persists(field, here - dir * dt, here, 1e-3 * cell)
            {
                steps += 1;
                worst = worst.max(change / cell);
            }
            prev = (f, g);
        }
    }
    println!("{LINES} lines of 4 cells: {steps} steps, the largest {worst:.3} cells");
    Ok(())
}

/// Whether `f` still changes by more than `jump` across an interval of 1e-12 or less within
/// `[a, b]` (halving toward the larger change): a step, not a steep stretch of a continuous
/// field.
fn persists(field: &sim_core::GlobalField, mut a: DVec3, mut b: DVec3, jump: f64) -> bool {
    let (mut fa, mut fb) = (field.value(a), field.value(b));
    while (b - a).length() > 1e-12 {
        let m = (a + b) * 0.5;
        let fm = field.value(m);
        if (fm - fa).abs() > (fb - fm).abs() {
            (b, fb) = (m, fm);
        } else {
            (a, fa) = (m, fm);
        }
    }
    (fb - fa).abs() > jump
}

fn main() -> ExitCode {
    common::main("field_steps", run)
}
