//! Diagnostic: why the zero set lies where it does at one place. Fits a PLY point file (points
//! and normals) and, along a line through a point `C` in direction `N`, prints where the
//! blended field crosses zero and where each local field covering `C` would put it on its own,
//! beside that field's centre, normal, support radius and its own tangent plane's crossing (the
//! plane its fit is regularised toward). A local field whose zero lies far from the others' and
//! from its own plane is bending the surface there. Gap fields are marked.
//!
//! ```text
//! cargo run --release -p sim-core --example line_probe -- POINTS.ply CX,CY,CZ NX,NY,NZ HALF [KEY=VALUE ...]
//! ```
//!
//! `HALF` is the half-length of the searched segment (world units). Keys override the library's
//! [`FitParams`]: `k`, `weight_width`, `normal_weight`, `regularization`, `centre_spacing`,
//! `offset`, `gap_fields`, `k_even`, `even_lean`, `misfit_width`. `workstation fit`'s
//! defaults are `normal_weight=0.25 regularization=3e-4 centre_spacing=0.35 gap_fields=0.12
//! k_even=16 even_lean=0.2 misfit_width=0.035`. Crossings are offsets along `N` from `C`; `-`
//! means none in the segment.
mod common;

use std::process::ExitCode;

use glam::DVec3;
use sim_core::FitParams;
use sim_core::bspline::eval3_value;

fn vector(s: &str) -> Result<DVec3, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{s}: {e}"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(DVec3::new(x, y, z)),
        _ => Err(format!("{s}: expected three finite numbers x,y,z")),
    }
}

/// The sign change of `f` on `[-half, half]` nearest `0` (400 steps, linear interpolation):
/// a local field can have a second zero sheet within the segment, and the one through `C`'s
/// neighbourhood is the one that bends the blend there.
fn zero_crossing(f: impl Fn(f64) -> f64, half: f64) -> Option<f64> {
    const STEPS: usize = 400;
    let mut prev = (-half, f(-half));
    let mut nearest: Option<f64> = None;
    for s in 1..=STEPS {
        let t = -half + 2.0 * half * s as f64 / STEPS as f64;
        let v = f(t);
        if (v < 0.0) != (prev.1 < 0.0) {
            let z = prev.0 + (t - prev.0) * prev.1 / (prev.1 - v);
            if nearest.is_none_or(|n| z.abs() < n.abs()) {
                nearest = Some(z);
            }
        }
        prev = (t, v);
    }
    nearest
}

fn shown(t: Option<f64>) -> String {
    t.map_or("-".into(), |t| format!("{t:+.5}"))
}

fn run(args: &[String]) -> Result<(), String> {
    let [file, c, n, half, overrides @ ..] = args else {
        return Err("usage: line_probe POINTS.ply CX,CY,CZ NX,NY,NZ HALF [KEY=VALUE ...]".into());
    };
    let (c, n) = (vector(c)?, vector(n)?.normalize());
    let half: f64 = half.parse().map_err(|e| format!("HALF {half}: {e}"))?;
    let params = common::fit_params(FitParams::default(), overrides)?;
    let loaded = common::read_ply(file)?;
    let rec = common::fit(&loaded.points, &params)?;
    let field = &rec.field;
    println!(
        "blended field: zero at {} (trusted at C: {})",
        shown(zero_crossing(|t| field.value(c + n * t), half)),
        field.is_trusted(c)
    );
    let size = params.size;
    let mut rows = Vec::new();
    for s in 0..field.len() {
        let gap = s >= field.len() - field.gap_field_count();
        let frame = field.slot_frame(s);
        let r = field.slot_support(s);
        let reach = (c - frame.center).length() / r;
        if reach >= 1.0 {
            continue;
        }
        let coeffs = field.slot_coefficients(s);
        let own = zero_crossing(
            |t| {
                let [u, v, w] = frame.to_local(c + n * t);
                eval3_value(size, coeffs, u, v, w)
            },
            half,
        );
        let normal = frame.axes[2];
        let plane = (frame.center - c).dot(normal) / n.dot(normal);
        rows.push((reach, own, plane, frame.center - c, normal, r, gap));
    }
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    println!(
        "{} local fields cover C, nearest (distance / support radius) first:",
        rows.len()
    );
    for (reach, own, plane, rel, normal, r, gap) in rows {
        println!(
            "  reach {reach:.2}  zero {:>9}  own plane {:+.5}  centre C{:+.4},{:+.4},{:+.4}  \
             normal {:+.2},{:+.2},{:+.2}  support {r:.4}{}",
            shown(own),
            plane,
            rel.x,
            rel.y,
            rel.z,
            normal.x,
            normal.y,
            normal.z,
            if gap { "  (gap field)" } else { "" },
        );
    }
    Ok(())
}

fn main() -> ExitCode {
    common::main("line_probe", run)
}
