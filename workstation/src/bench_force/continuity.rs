//! Continuity sweeps (issue 6): a sphere probe through a sheet, through a two-faced thin wall,
//! and across a 90° edge, 0.1 mm steps, for every direction and magnitude method.

use glam::DVec3;
use serde::Serialize;
use sim_core::probe::fixtures::{Sweep, edge, sheet, sweep, thin_wall};
use sim_core::probe::{
    ContactParams, DirectionMethod, MagnitudeMethod, Probe, ProbeError, ProbeRenderer, SampleGrid,
};

/// One method's sweeps.
#[derive(Debug, Clone, Serialize)]
pub struct ContinuityRow {
    /// Direction method.
    pub method: String,
    /// Magnitude method.
    pub magnitude: String,
    /// Largest force jump through a sheet, N/mm.
    pub sheet_jump_n_per_mm: f64,
    /// Smallest normal force through the sheet, N (negative: reversed).
    pub sheet_min_normal_force_n: f64,
    /// Largest force jump through a 2 mm two-faced wall, N/mm.
    pub wall_jump_n_per_mm: f64,
    /// Peak force through the wall, N.
    pub wall_peak_n: f64,
    /// Largest force jump across the edge, N/mm.
    pub edge_jump_n_per_mm: f64,
    /// Largest direction turn across the edge (forces ≥ 5 % of peak), °/mm.
    pub edge_turn_deg_per_mm: f64,
}

/// Run the sweeps for a probe of radius `r` and springs `ks` (N/m³).
pub fn continuity(r: f64, ks: f64) -> Result<Vec<ContinuityRow>, ProbeError> {
    let sheet_grid = SampleGrid::new(&sheet(1.5 * r, r / 25.0), r / 3.0)?;
    let wall_grid = SampleGrid::new(&thin_wall(1.5 * r, r / 25.0, 0.002), r / 3.0)?;
    let edge_grid = SampleGrid::new(&edge(3.0 * r, r / 25.0), r / 3.0)?;
    let probe = Probe::sphere(r)?;
    let (above, below) = (
        DVec3::new(0.003, 0.002, 1.1 * r),
        DVec3::new(0.003, 0.002, -1.1 * r),
    );
    let z = 0.9 * r;
    let (left, right) = (DVec3::new(-1.5 * r, 0.0, z), DVec3::new(1.2 * r, 0.0, z));
    let mut rows = Vec::new();
    for magnitude in [MagnitudeMethod::SpringSum, MagnitudeMethod::VectorSum] {
        for method in [DirectionMethod::SurfaceNormal, DirectionMethod::ProbeNormal] {
            let params = ContactParams {
                surface_stiffness: ks,
                surface_damping: 0.0,
                method,
                magnitude,
            };
            let mut pr = ProbeRenderer::new(params, 0)?;
            let mut run = |grid: &SampleGrid, a: DVec3, b: DVec3, steps: usize| -> Sweep {
                sweep(&mut pr, &probe, grid, a, b, steps, DVec3::Z)
            };
            let s = run(&sheet_grid, above, below, 440);
            let w = run(&wall_grid, above, below - DVec3::new(0.0, 0.0, 0.002), 460);
            let e = run(&edge_grid, left, right, 540);
            rows.push(ContinuityRow {
                method: format!("{method:?}"),
                magnitude: format!("{magnitude:?}"),
                sheet_jump_n_per_mm: s.max_jump_n_per_mm,
                sheet_min_normal_force_n: s.min_along_watch_n,
                wall_jump_n_per_mm: w.max_jump_n_per_mm,
                wall_peak_n: w.peak_n,
                edge_jump_n_per_mm: e.max_jump_n_per_mm,
                edge_turn_deg_per_mm: e.max_turn_deg_per_mm,
            });
        }
    }
    Ok(rows)
}
