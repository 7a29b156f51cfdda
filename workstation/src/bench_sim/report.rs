//! The `bench-sim` report: its JSON shape (`step_ms` and `field_error` at the top) and table.

use serde::Serialize;

/// Median and spread of a stage's time (ms).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Spread {
    /// Median.
    pub median: f64,
    /// 10th percentile.
    pub p10: f64,
    /// 90th percentile.
    pub p90: f64,
}

/// One integrator's timings.
#[derive(Debug, Clone, Serialize)]
pub struct IntegratorRun {
    /// Integrator name.
    pub integrator: String,
    /// Whole step (tools + integrate + follow + publish), ms.
    pub step_ms: Spread,
    /// Tools stage, ms.
    pub tools_ms: Spread,
    /// Integrator stage, ms.
    pub integrate_ms: Spread,
    /// Points-follow stage, ms.
    pub follow_ms: Spread,
    /// Snapshot publication, ms.
    pub publish_ms: Spread,
    /// End-of-stroke refit of moved points (one call), ms.
    pub refit_ms: f64,
    /// Points moved during the stroke.
    pub moved_points: usize,
    /// Height of the bump at the top after the stroke (m).
    pub bump_height: f64,
    /// Mean CG iterations per step (backward Euler).
    pub cg_iterations: f64,
    /// Mean points visited by the follow stage per step.
    pub visited_points: f64,
    /// Mean exact base-field evaluations (Taylor refreshes) per step.
    pub exact_evaluations: f64,
    /// Mean whole-step time, ms (includes follow stages amortised over `--follow-every`).
    pub step_ms_mean: f64,
}

/// Everything `bench-sim` measured.
#[derive(Debug, Clone, Serialize)]
pub struct BenchSimReport {
    /// Median step time of the default integrator (symplectic Euler), ms.
    pub step_ms: f64,
    /// The field error of the run (m): RMS of the published grid field at the exact sphere.
    pub field_error: f64,
    /// Same as `field_error` (named for its statistic).
    pub field_error_rms: f64,
    /// Largest such error (m).
    pub field_error_max: f64,
    /// `field_error_rms / radius`.
    pub field_error_relative: f64,
    /// Grid nodes per axis.
    pub grid: usize,
    /// Points.
    pub points: usize,
    /// Simulated (band) nodes.
    pub active_nodes: usize,
    /// All grid nodes.
    pub grid_nodes: usize,
    /// Grid spacing (m).
    pub spacing: f64,
    /// Time step (s).
    pub dt: f64,
    /// Field fitting time (not per step), ms.
    pub fit_ms: f64,
    /// Region set-up (grid resampling of the field), ms.
    pub region_ms: f64,
    /// Per-integrator timings with one object.
    pub runs: Vec<IntegratorRun>,
    /// Symplectic run with `static_objects` more objects in the scene.
    pub with_static: IntegratorRun,
    /// Static objects added.
    pub static_objects: usize,
    /// Simulation memory with one object (bytes).
    pub memory_bytes: usize,
    /// Simulation memory with the static objects added (bytes).
    pub memory_bytes_with_static: usize,
    /// Measured and predicted explicit limits (s), when `--limits`.
    pub limits: Option<Limits>,
}

/// Stability limits on the benchmark model (s).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Limits {
    /// Forward Euler, measured.
    pub forward_euler_measured: f64,
    /// Forward Euler, predicted `c/(m ω²)`.
    pub forward_euler_predicted: f64,
    /// Symplectic Euler, measured.
    pub symplectic_euler_measured: f64,
    /// Symplectic Euler, predicted.
    pub symplectic_euler_predicted: f64,
}

/// Print the report as JSON or as a table.
pub fn print(report: &BenchSimReport, json: bool) -> anyhow::Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(report)?);
        return Ok(());
    }
    let r = report;
    println!(
        "grid {}³ (h = {:.2} mm), {} points, {} of {} nodes simulated, dt = {} ms",
        r.grid,
        r.spacing * 1e3,
        r.points,
        r.active_nodes,
        r.grid_nodes,
        r.dt * 1e3
    );
    println!(
        "field error at the exact sphere: rms {:.2e} m ({:.3} % of R), max {:.2e} m",
        r.field_error_rms,
        r.field_error_relative * 100.0,
        r.field_error_max
    );
    println!("step_ms {:.4} (symplectic Euler, median)", r.step_ms);
    println!(
        "{:<18} {:>24} {:>7} {:>7} {:>9} {:>7} {:>7} {:>7} {:>7} {:>7}",
        "integrator",
        "step ms p50 [p10,p90]",
        "mean",
        "tools",
        "integrate",
        "follow",
        "publish",
        "refit",
        "visited",
        "exact"
    );
    for run in r.runs.iter().chain(std::iter::once(&r.with_static)) {
        println!(
            "{:<18} {:>8.4} [{:.4},{:.4}] {:>7.4} {:>7.4} {:>9.4} {:>7.4} {:>7.4} {:>7.2} {:>7.0} {:>7.0}",
            run.integrator,
            run.step_ms.median,
            run.step_ms.p10,
            run.step_ms.p90,
            run.step_ms_mean,
            run.tools_ms.median,
            run.integrate_ms.median,
            run.follow_ms.median,
            run.publish_ms.median,
            run.refit_ms,
            run.visited_points,
            run.exact_evaluations
        );
    }
    println!(
        "(last row: symplectic with {} static objects) memory {} B → {} B",
        r.static_objects, r.memory_bytes, r.memory_bytes_with_static
    );
    if let Some(l) = r.limits {
        println!(
            "stability limits: forward Euler {:.3e} s (predicted {:.3e}), symplectic {:.3e} s (predicted {:.3e})",
            l.forward_euler_measured,
            l.forward_euler_predicted,
            l.symplectic_euler_measured,
            l.symplectic_euler_predicted
        );
    }
    Ok(())
}
