//! Diagnostic: move a mesh's vertices onto a query-centred MLS surface of the points (an
//! algebraic sphere fitted at each vertex, as APSS fits), everywhere or only between the
//! points, to see how much of a mesh's error is its field's interpolant between the points.
//!
//! ```text
//! cargo run --release -p sim-core --example vertex_mls -- POINTS.ply MESH.ply OUT.ply [KEY=VALUE ...]
//! ```
//!
//! Each point's radius `rᵢ` is the distance to the farthest of its 16 nearest points (itself
//! included); a point weighs
//! `(1 − d²/hᵢ²)⁴` at distance `d < hᵢ = reach · rᵢ` from the vertex. A vertex takes up to three
//! sphere projections, and moves that far times `smoothstep((g − from)/(to − from))`, where
//! `g` is its distance to the nearest point over the median `rᵢ` (`from = to = 0`: everywhere),
//! times `amount` (the zero set of a field mixing the two fits in that proportion).
//! Keys: `reach` (0.9), `from` (0), `to` (0), `amount` (1). Measure OUT with
//! `workstation mesh-error`.
mod common;

use std::process::ExitCode;

use glam::DVec3;
use sim_core::io::{self, Format};
use sim_core::knn::PointIndex;

/// Nearest points (the point itself included) whose farthest sets a point's radius.
const RADIUS_NEIGHBOURS: usize = 16;
/// Sphere projections per vertex.
const ITERATIONS: usize = 3;

/// The step from `x` to the algebraic sphere fitted there; `None` where too few points reach.
fn sphere_step(
    x: DVec3,
    points: &[DVec3],
    normals: &[DVec3],
    radii: &[f64],
    index: &PointIndex,
    search: f64,
    reach: f64,
) -> Option<DVec3> {
    let (mut sw, mut sp, mut sn, mut spn, mut spp, mut count) =
        (0.0, DVec3::ZERO, DVec3::ZERO, 0.0, 0.0, 0);
    for (i, d) in index.within(x, search) {
        let h = reach * radii[i];
        if d >= h {
            continue;
        }
        let t = 1.0 - (d / h).powi(2);
        let w = t.powi(4);
        let q = points[i] - x;
        sw += w;
        sp += w * q;
        sn += w * normals[i];
        spn += w * q.dot(normals[i]);
        spp += w * q.length_squared();
        count += 1;
    }
    if count < 4 {
        return None;
    }
    // s(q) = c + u·q + a|q|² with the weighted means (Guennebaud & Gross 2007).
    let (mp, mn, mpn, mpp) = (sp / sw, sn / sw, spn / sw, spp / sw);
    let spread = mpp - mp.length_squared();
    let a = if spread > 0.0 {
        0.5 * (mpn - mp.dot(mn)) / spread
    } else {
        0.0
    };
    let u = mn - 2.0 * a * mp;
    let c = -u.dot(mp) - a * mpp;
    if a.abs() * mpp.sqrt() < 1e-9 * u.length() {
        // A plane: step along u to it.
        return Some(-u * (c / u.length_squared()));
    }
    let centre = -u / (2.0 * a);
    let rho2 = centre.length_squared() - c / a;
    if rho2 <= 0.0 {
        return None;
    }
    let out = (-centre).try_normalize()?;
    Some(centre + out * rho2.sqrt())
}

fn run(args: &[String]) -> Result<(), String> {
    let [points_file, mesh_file, out_file, overrides @ ..] = args else {
        return Err("usage: vertex_mls POINTS.ply MESH.ply OUT.ply [KEY=VALUE ...]".into());
    };
    let (mut reach, mut from, mut to, mut amount) = (0.9, 0.0, 0.0, 1.0);
    for (key, v) in common::key_values(overrides)? {
        match key {
            "reach" => reach = v,
            "from" => from = v,
            "to" => to = v,
            "amount" => amount = v,
            _ => return Err(format!("{key}: not a key vertex_mls knows")),
        }
    }
    let loaded = common::read_ply(points_file)?;
    let points = &loaded.points.positions;
    let normals = loaded
        .points
        .normals
        .as_ref()
        .ok_or(format!("{points_file}: no normals"))?;
    let mut mesh = common::read_ply(mesh_file)?
        .mesh
        .ok_or(format!("{mesh_file}: no faces"))?;
    let index = PointIndex::new(points);
    let radii: Vec<f64> = points
        .iter()
        .map(|&p| {
            index
                .nearest_k(p, RADIUS_NEIGHBOURS)
                .last()
                .map_or(0.0, |n| n.1)
        })
        .collect();
    let mut sorted = radii.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let search = reach * sorted[sorted.len() - 1];
    let (mut moved, mut total) = (0usize, 0.0);
    for v in &mut mesh.vertices {
        let g = index.nearest(*v).1 / median;
        let share = if to > from {
            let t = ((g - from) / (to - from)).clamp(0.0, 1.0);
            t * t * (3.0 - 2.0 * t)
        } else if g >= from {
            1.0
        } else {
            0.0
        };
        if share == 0.0 {
            continue;
        }
        let mut x = *v;
        for _ in 0..ITERATIONS {
            match sphere_step(x, points, normals, &radii, &index, search, reach) {
                Some(step) if step.is_finite() => x += step,
                _ => break,
            }
        }
        let step = (x - *v) * share * amount;
        total += step.length();
        moved += 1;
        *v += step;
    }
    println!(
        "{moved} of {} vertices moved, mean {:.3e} (median radius {median:.3e})",
        mesh.vertices.len(),
        total / moved.max(1) as f64
    );
    mesh.normals.clear();
    let out = std::fs::File::create(out_file).map_err(|e| format!("{out_file}: {e}"))?;
    io::write_mesh(std::io::BufWriter::new(out), &mesh, Format::Ply)
        .map_err(|e| format!("{out_file}: {e}"))
}

fn main() -> ExitCode {
    common::main("vertex_mls", run)
}
