//! Deterministic sample sets and analytic references for probe tests, benches and reports.
//!
//! Samples sit at cell centres of a regular lattice (never exactly on an edge), each carrying
//! its cell's area, so sums over samples approximate surface integrals.

use glam::DVec3;

use super::{Probe, ProbePose, ProbeRenderer, SampleGrid, SurfaceSample};

/// The plane `z = 0` over `[−half, half]²`, normal `+z`, one sample per `spacing`² cell.
pub fn sheet(half: f64, spacing: f64) -> Vec<SurfaceSample> {
    let n = (2.0 * half / spacing).round().max(1.0) as usize;
    let mut out = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let x = -half + (i as f64 + 0.5) * spacing;
            let y = -half + (j as f64 + 0.5) * spacing;
            out.push(SurfaceSample {
                position: DVec3::new(x, y, 0.0),
                normal: DVec3::Z,
                area: spacing * spacing,
            });
        }
    }
    out
}

/// A thin wall: the sheet `z = 0` (normal `+z`) and its back face `z = −thickness` (normal
/// `−z`) over `[−half, half]²`.
pub fn thin_wall(half: f64, spacing: f64, thickness: f64) -> Vec<SurfaceSample> {
    let front = sheet(half, spacing);
    let back = front.iter().map(|s| SurfaceSample {
        position: s.position - DVec3::new(0.0, 0.0, thickness),
        normal: -DVec3::Z,
        area: s.area,
    });
    let mut out = front.clone();
    out.extend(back);
    out
}

/// A convex 90° edge along `y`: the top face `z = 0, x ≤ 0` (normal `+z`) and the side face
/// `x = 0, z ≤ 0` (normal `+x`), each `half` deep, `2·half` long.
pub fn edge(half: f64, spacing: f64) -> Vec<SurfaceSample> {
    let n = (half / spacing).round().max(1.0) as usize;
    let mut out = Vec::with_capacity(4 * n * n);
    for j in 0..2 * n {
        let y = -half + (j as f64 + 0.5) * spacing;
        for i in 0..n {
            let s = (i as f64 + 0.5) * spacing;
            let area = spacing * spacing;
            out.push(SurfaceSample {
                position: DVec3::new(-s, y, 0.0),
                normal: DVec3::Z,
                area,
            });
            out.push(SurfaceSample {
                position: DVec3::new(0.0, y, -s),
                normal: DVec3::X,
                area,
            });
        }
    }
    out
}

/// Seed 004 Fig. 4 in closed form: the force of a sphere of `radius` whose centre is `h` above
/// (or below) a continuously sampled plane, springs `k_s` N/m³, depth to the nearer crossing:
/// `F(h) = 2π k_s [ (R³ − |h|³)/3 − |h|(R² − h²)/2 ]`, peaking at `h = 0`, zero for `|h| ≥ R`.
pub fn fig4_force(radius: f64, h: f64, surface_stiffness: f64) -> f64 {
    let (r, a) = (radius, h.abs());
    if a >= r {
        return 0.0;
    }
    2.0 * std::f64::consts::PI
        * surface_stiffness
        * ((r.powi(3) - a.powi(3)) / 3.0 - a * (r * r - a * a) / 2.0)
}

/// What a straight sweep of the probe felt.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sweep {
    /// Largest `|F(x_{k+1}) − F(x_k)| / |x_{k+1} − x_k|` along the path, N/mm.
    pub max_jump_n_per_mm: f64,
    /// Largest turn of the force direction per mm between consecutive forces that both exceed
    /// [`TURN_FLOOR`] of the peak (a direction of a vanishing force is not felt), degrees/mm.
    pub max_turn_deg_per_mm: f64,
    /// Largest force magnitude, N.
    pub peak_n: f64,
    /// Smallest force component along `watch` (negative = the force reversed), N.
    pub min_along_watch_n: f64,
}

/// Forces below this fraction of the sweep's peak do not count for [`Sweep::max_turn_deg_per_mm`].
pub const TURN_FLOOR: f64 = 0.05;

/// Move the probe's centre in `steps` equal steps from `from` to `to` (static, zero velocity)
/// and record the force continuity; `watch` is a direction whose sign change means reversal.
/// Allocates the force record (a measurement, not a haptic-rate call).
pub fn sweep(
    renderer: &mut ProbeRenderer,
    probe: &Probe,
    grid: &SampleGrid,
    from: DVec3,
    to: DVec3,
    steps: usize,
    watch: DVec3,
) -> Sweep {
    let steps = steps.max(1);
    let step_mm = (to - from).length() / steps as f64 * 1e3;
    let mut probe = *probe;
    let orientation = probe.pose().orientation;
    let forces: Vec<DVec3> = (0..=steps)
        .map(|k| {
            let position = from.lerp(to, k as f64 / steps as f64);
            match probe.set_pose(ProbePose {
                position,
                orientation,
            }) {
                Ok(()) => renderer.query(&probe, grid, DVec3::ZERO).force,
                Err(_) => DVec3::ZERO,
            }
        })
        .collect();
    let peak_n = forces.iter().fold(0.0f64, |m, f| m.max(f.length()));
    let mut out = Sweep {
        max_jump_n_per_mm: 0.0,
        max_turn_deg_per_mm: 0.0,
        peak_n,
        min_along_watch_n: forces.iter().fold(0.0f64, |m, f| m.min(f.dot(watch))),
    };
    let floor = TURN_FLOOR * peak_n;
    let mut last: Option<(DVec3, usize)> = None;
    for (k, f) in forces.iter().enumerate() {
        if k > 0 {
            let jump = (*f - forces[k - 1]).length() / step_mm;
            out.max_jump_n_per_mm = out.max_jump_n_per_mm.max(jump);
        }
        if f.length() < floor || f.length() == 0.0 {
            continue;
        }
        let d = f.normalize();
        if let Some((e, at)) = last {
            let turn = d.dot(e).clamp(-1.0, 1.0).acos().to_degrees();
            let per_mm = turn / (step_mm * (k - at) as f64);
            out.max_turn_deg_per_mm = out.max_turn_deg_per_mm.max(per_mm);
        }
        last = Some((d, k));
    }
    out
}
