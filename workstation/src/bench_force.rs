//! `workstation bench-force`: time the haptic queries of issue 6 and measure, on the same run,
//! their force error against analytic references (DESIGN §7).
//!
//! - Field force: a sphere of radius `--radius` sampled on a grid of spacing `R/--cells`;
//!   seeded contact points at depths 0.1–0.3 R (friction and damping on, VCP found from
//!   scratch every query). Error: largest `|F − F_ref|/|F_ref|` against `k·depth·n_exact`.
//! - Shaped probe: a sphere probe centred on a plane sampled so ≈ `--contacts` samples are in
//!   contact. Error: against seed 004 Fig. 4 in closed form.
//! - Continuity: largest force jump (N/mm) and direction turn (°/mm) sweeping a probe through
//!   a sheet and across a sharp edge, for both direction methods.
//! - B-spline sculpting: one 1 kHz tick of a 30×30 dual with the probe pressing, and the
//!   headless demo of the B-spline probe scene.
//!
//! Each timed query is bracketed by two `Instant::now()` reads (≈20–30 ns of the figure);
//! `--repeats` runs give the spread of the p99.

use anyhow::Context as _;
use glam::DVec3;
use serde::Serialize;
use sim_core::bspline_surface::{BicubicPatch, MeshParams, ProbeSculptor};
use sim_core::grid::GridSpec;
use sim_core::haptic::fixtures::{AnalyticField, contact_points, force_errors};
use sim_core::haptic::{FieldContactParams, FieldForce};
use sim_core::probe::fixtures::{fig4_force, sheet};
use sim_core::probe::{
    ContactParams, DirectionMethod, MagnitudeMethod, Probe, ProbePose, ProbeRenderer, SampleGrid,
};

use crate::cap;
use crate::limits::{
    MAX_CONTACTS, MAX_FORCE_CELLS, MAX_GEN_POINTS, MAX_QUERIES, MAX_REPEATS, OverLimit,
};
use crate::scenes::bspline_probe::{BsplineProbeScene, SceneConfig};

mod continuity;
mod fitted;
mod timing;

pub use continuity::ContinuityRow;
use continuity::continuity;
pub use fitted::FittedErrors;
use fitted::fitted_errors;

pub use timing::Timing;
use timing::time_runs;

/// Parsed arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct BenchForceArgs {
    /// Radius of the analytic sphere field and of the probe, m.
    #[arg(long, default_value_t = 0.02)]
    pub radius: f64,
    /// Grid cells per radius for the field (the bar is R/20).
    #[arg(long, default_value_t = 20.0)]
    pub cells: f64,
    /// Target number of probe contacts.
    #[arg(long, default_value_t = 2000)]
    pub contacts: usize,
    /// Timed queries per run.
    #[arg(long, default_value_t = 20_000)]
    pub queries: usize,
    /// Runs (spread of the p99 across runs).
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Points sampled on the sphere for the fitted-field check (0 skips it).
    #[arg(long, default_value_t = 10_000)]
    pub fit_points: usize,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Everything bench-force measures.
#[derive(Debug, Clone, Serialize)]
pub struct BenchForceReport {
    /// p99 of one field query, µs.
    pub field_query_us_p99: f64,
    /// Largest relative field-force error against the analytic sphere (depth 0.1–0.3 R).
    pub field_force_rel_error: f64,
    /// p99 of one probe query, µs.
    pub probe_query_us_p99: f64,
    /// Samples in contact in the probe query (mean over queries).
    pub probe_contacts: f64,
    /// Field query timing detail, µs.
    pub field_query_us: Timing,
    /// The whole chain (points → fitted field → grid → force) on the same sphere; absent with
    /// `--fit-points 0`.
    pub fitted: Option<FittedErrors>,
    /// Field grid spacing, m.
    pub field_spacing_m: f64,
    /// Largest field-force error as a position, m, at depths 0–0.3 R.
    pub field_position_error_m: f64,
    /// Largest field-force direction error, rad.
    pub field_direction_error_rad: f64,
    /// Convergence order of the field-force error from R/10 → R/20 → R/40 (two values).
    pub field_convergence_orders: [f64; 2],
    /// Probe query timing detail (force only, no contact list), µs.
    pub probe_query_us: Timing,
    /// Probe query that also records every contact (what the sculptor needs), µs.
    pub probe_query_recorded_us: Timing,
    /// Largest relative probe-force error against seed 004 Fig. 4 in closed form.
    pub probe_force_rel_error: f64,
    /// Force jump through a sheet, N/mm: [surface normal, probe normal] (seed 004's spring sum;
    /// all methods in `continuity`).
    pub sheet_jump_n_per_mm: [f64; 2],
    /// Force jump across a sharp edge, N/mm: [surface normal, probe normal].
    pub edge_jump_n_per_mm: [f64; 2],
    /// Direction turn across a sharp edge, °/mm: [surface normal, probe normal].
    pub edge_turn_deg_per_mm: [f64; 2],
    /// Smallest normal force component through the sheet, N (negative = reversal):
    /// [surface normal, probe normal].
    pub sheet_min_normal_force_n: [f64; 2],
    /// One pressed 1 kHz tick of the 30×30 B-spline dual, µs.
    pub sculpt_tick_us: Timing,
    /// Every direction × magnitude method through a sheet, a 2 mm wall and over an edge.
    pub continuity: Vec<ContinuityRow>,
    /// The B-spline probe scene's scripted demo (push from the front, pull from behind), headless.
    pub scene: SceneSummary,
}

/// What the B-spline probe scene's demo script felt and made.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct SceneSummary {
    /// Haptic ticks run (1 kHz).
    pub ticks: usize,
    /// Largest force on the user, N.
    pub peak_force_n: f64,
    /// Largest reaction while sculpting, N.
    pub peak_reaction_n: f64,
    /// Largest server-vs-workstation force difference at the same cursor, N.
    pub max_model_mismatch_n: f64,
    /// Final dent depth and bulge height, m.
    pub dent_m: f64,
    /// Final bulge height, m.
    pub bulge_m: f64,
}

fn field_params(r: f64) -> FieldContactParams {
    FieldContactParams {
        stiffness: 500.0,
        damping: 1.0,
        friction: 0.3,
        max_search: r,
        approach_margin: 0.1 * r,
        validity_radius: 0.1 * r,
        lifetime_s: 0.05,
    }
}

/// The caps on `--cells`, `--contacts`, `--queries`, `--repeats` and `--fit-points` (see
/// [`crate::limits`]).
fn check_counts(args: &BenchForceArgs) -> Result<(), OverLimit> {
    cap!("--cells", args.cells, MAX_FORCE_CELLS, "cells per radius")?;
    cap!("--contacts", args.contacts, MAX_CONTACTS, "contacts")?;
    cap!("--queries", args.queries, MAX_QUERIES, "queries")?;
    cap!("--repeats", args.repeats, MAX_REPEATS, "runs")?;
    cap!("--fit-points", args.fit_points, MAX_GEN_POINTS, "points")
}

/// Run every measurement.
pub fn run(args: &BenchForceArgs) -> anyhow::Result<BenchForceReport> {
    anyhow::ensure!(
        args.radius.is_finite() && args.radius > 0.0,
        "--radius must be positive and finite (got {})",
        args.radius
    );
    anyhow::ensure!(
        args.cells.is_finite() && args.cells >= 2.0,
        "--cells must be finite and at least 2 (got {})",
        args.cells
    );
    check_counts(args)?;
    let r = args.radius;
    let sphere = AnalyticField::Sphere { size: r };
    let h = r / args.cells;
    // `AnalyticField::grid` panics on a grid it cannot build: check it here, as an error.
    let (lo, hi) = sphere.region(3.0 * h);
    GridSpec::try_covering(lo, hi, h)
        .with_context(|| format!("--radius {r} with --cells {}", args.cells))?;
    let grid = sphere.grid(h);
    let params = field_params(r);
    let errors = force_errors(&sphere, &grid, &params, 2000, 1, (0.1, 0.3));
    let shallow = force_errors(&sphere, &grid, &params, 2000, 2, (0.0, 0.3));
    let conv: Vec<f64> = [10.0, 20.0, 40.0]
        .iter()
        .map(|c| force_errors(&sphere, &sphere.grid(r / c), &params, 500, 3, (0.1, 0.3)).rel_vector)
        .collect();
    // Query points: seeded contacts, tip velocities along the surface.
    let points: Vec<(DVec3, DVec3)> = contact_points(&sphere, args.queries.max(1), 4, (0.1, 0.3))
        .into_iter()
        .map(|(x, _, n)| (x, n.any_orthonormal_vector() * 0.05))
        .collect();
    let fitted = match args.fit_points {
        0 => None,
        n => Some(fitted_errors(n, &sphere, h, &params)?),
    };
    let mut ff = FieldForce::new(params)?;
    let mut sink = DVec3::ZERO;
    let field_t = time_runs(args.repeats, points.len(), |i| {
        ff.reset();
        sink += ff.query(&grid, points[i].0, points[i].1).output.force;
    });

    // Probe: plane spacing for ≈ `contacts` samples inside a centred sphere (disc area π r²).
    let spacing = (std::f64::consts::PI * r * r / args.contacts.max(1) as f64).sqrt();
    let samples = sheet(1.5 * r, spacing);
    let index = SampleGrid::new(&samples, 0.1 * r)?;
    let ks = 1.0e6;
    let contact = |method| ContactParams {
        surface_stiffness: ks,
        surface_damping: 20.0,
        method,
        magnitude: MagnitudeMethod::SpringSum,
    };
    let mut pr = ProbeRenderer::new(contact(DirectionMethod::SurfaceNormal), 0)?;
    let mut recording =
        ProbeRenderer::new(contact(DirectionMethod::SurfaceNormal), 4 * args.contacts)?;
    let mut probe = Probe::sphere(r)?;
    let offsets: Vec<DVec3> = (0..64)
        .map(|i| {
            DVec3::new(
                (i % 8) as f64 * 1e-4,
                (i / 8) as f64 * 1e-4,
                (i % 5) as f64 * 1e-4,
            )
        })
        .collect();
    let (mut contacts, mut probe_err) = (0usize, 0.0f64);
    for o in &offsets {
        probe.set_pose(ProbePose::at(*o))?;
        let f = pr.query(&probe, &index, DVec3::ZERO);
        let reference = fig4_force(r, o.z, ks);
        probe_err = probe_err.max((f.force - DVec3::Z * reference).length() / reference);
    }
    let probe_t = time_runs(args.repeats, args.queries.max(1) / 4, |i| {
        let o = offsets[i % offsets.len()];
        if probe.set_pose(ProbePose::at(o)).is_ok() {
            let f = pr.query(&probe, &index, DVec3::new(0.0, 0.0, -0.01));
            contacts += f.contact_count;
            sink += f.force;
        }
    });
    let recorded_t = time_runs(args.repeats, args.queries.max(1) / 4, |i| {
        let o = offsets[i % offsets.len()];
        if probe.set_pose(ProbePose::at(o)).is_ok() {
            sink += recording
                .query(&probe, &index, DVec3::new(0.0, 0.0, -0.01))
                .force;
        }
    });
    let timed_probe_queries =
        (args.queries.max(1) / 4) * args.repeats.max(1) + (args.queries.max(1) / 4).min(1000);

    let rows = continuity(r, ks)?;
    let (sn, pn) = (&rows[0], &rows[1]);

    let sculpt_t = time_sculpt(args.repeats, 2000)?;
    let mut scene = BsplineProbeScene::new(SceneConfig::default())?;
    let demo = scene.run_script(&BsplineProbeScene::demo_script())?;
    std::hint::black_box(sink);
    Ok(BenchForceReport {
        field_query_us_p99: field_t.p99,
        field_force_rel_error: errors.rel_vector,
        probe_query_us_p99: probe_t.p99,
        probe_contacts: contacts as f64 / timed_probe_queries as f64,
        field_query_us: field_t,
        fitted,
        field_spacing_m: h,
        field_position_error_m: shallow.position_m,
        field_direction_error_rad: errors.direction_rad,
        field_convergence_orders: [(conv[0] / conv[1]).log2(), (conv[1] / conv[2]).log2()],
        probe_query_us: probe_t,
        probe_query_recorded_us: recorded_t,
        probe_force_rel_error: probe_err,
        sheet_jump_n_per_mm: [sn.sheet_jump_n_per_mm, pn.sheet_jump_n_per_mm],
        edge_jump_n_per_mm: [sn.edge_jump_n_per_mm, pn.edge_jump_n_per_mm],
        edge_turn_deg_per_mm: [sn.edge_turn_deg_per_mm, pn.edge_turn_deg_per_mm],
        sheet_min_normal_force_n: [sn.sheet_min_normal_force_n, pn.sheet_min_normal_force_n],
        sculpt_tick_us: sculpt_t,
        continuity: rows.clone(),
        scene: SceneSummary {
            ticks: demo.ticks,
            peak_force_n: demo.peak_force_n,
            peak_reaction_n: demo.peak_reaction_n,
            max_model_mismatch_n: demo.max_model_mismatch_n,
            dent_m: demo.final_dent_m,
            bulge_m: demo.final_bulge_m,
        },
    })
}

/// Time pressed 1 ms ticks of a 30×30 dual with a probe holding 5 mm into it.
fn time_sculpt(repeats: usize, ticks: usize) -> anyhow::Result<Timing> {
    let mesh = MeshParams::REFERENCE;
    let contact = ContactParams {
        surface_stiffness: 5.0e6,
        surface_damping: 1.5e4,
        method: DirectionMethod::SurfaceNormal,
        magnitude: MagnitudeMethod::SpringSum,
    };
    let mut s = ProbeSculptor::new(BicubicPatch::flat(30, 0.05)?, mesh, contact, 0.005, 0.01)?;
    let probe = Probe::sphere(0.008)?.posed(ProbePose::at(DVec3::new(0.0, 0.0, 0.003)))?;
    let mut failed = None;
    let t = time_runs(repeats, ticks, |_| {
        if let Err(e) = s.tick(&probe, DVec3::ZERO, true, 0.001) {
            failed = Some(e);
        }
    });
    match failed {
        Some(e) => Err(e.into()),
        None => Ok(t),
    }
}

/// Print the report as a table or JSON.
pub fn print(r: &BenchForceReport, json: bool) -> anyhow::Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(r)?);
        return Ok(());
    }
    let t = |name: &str, x: &Timing| {
        println!(
            "{name:<22} p50 {:>7.3} µs  p99 {:>7.3} µs [runs {:.3}–{:.3}]  p99.9 {:>7.3} µs",
            x.p50, x.p99, x.p99_min, x.p99_max, x.p999
        )
    };
    t("field query", &r.field_query_us);
    println!(
        "  h = {:.3} mm: rel error {:.3e}, direction {:.2e} rad, as position {:.2} µm; orders {:.2}, {:.2}",
        r.field_spacing_m * 1e3,
        r.field_force_rel_error,
        r.field_direction_error_rad,
        r.field_position_error_m * 1e6,
        r.field_convergence_orders[0],
        r.field_convergence_orders[1]
    );
    if let Some(f) = &r.fitted {
        println!(
            "  fitted sphere ({} points → field → grid): depth 0.1–0.3 R rel error {:.3e}, direction {:.2e} rad; depth < 0.05 R position {:.2} µm, direction {:.2e} rad",
            f.points,
            f.deep_rel_error,
            f.deep_direction_rad,
            f.shallow_position_m * 1e6,
            f.shallow_direction_rad
        );
    }
    t("probe query", &r.probe_query_us);
    t("  + contact list", &r.probe_query_recorded_us);
    println!(
        "  {:.0} contacts: rel error vs Fig. 4 {:.3e}",
        r.probe_contacts, r.probe_force_rel_error
    );
    println!(
        "  {:<14} {:<10} {:>10} {:>9} {:>10} {:>8} {:>10} {:>9}",
        "direction",
        "magnitude",
        "sheet N/mm",
        "min Fz N",
        "wall N/mm",
        "wall N",
        "edge N/mm",
        "edge °/mm"
    );
    for c in &r.continuity {
        println!(
            "  {:<14} {:<10} {:>10.3} {:>9.3} {:>10.3} {:>8.3} {:>10.3} {:>9.2}",
            c.method,
            c.magnitude,
            c.sheet_jump_n_per_mm,
            c.sheet_min_normal_force_n,
            c.wall_jump_n_per_mm,
            c.wall_peak_n,
            c.edge_jump_n_per_mm,
            c.edge_turn_deg_per_mm
        );
    }
    t("sculpt tick 30×30", &r.sculpt_tick_us);
    let d = &r.scene;
    println!(
        "scene demo: {} ticks, peak force {:.3} N (sculpting {:.3} N), dent {:.2} mm, bulge {:.2} mm, server mismatch {:.1e} N",
        d.ticks,
        d.peak_force_n,
        d.peak_reaction_n,
        d.dent_m * 1e3,
        d.bulge_m * 1e3,
        d.max_model_mismatch_n
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        args: BenchForceArgs,
    }

    #[test]
    fn bad_sizes_are_errors_naming_the_flag() {
        // `--radius inf`, `--cells inf` and `--cells 1e300` used to panic in the grid builder.
        for (flag, value) in [
            ("--radius", "inf"),
            ("--radius", "nan"),
            ("--cells", "inf"),
            ("--cells", "1e300"),
        ] {
            let cli = Cli::parse_from(["bench-force", flag, value, "--fit-points", "0"]);
            let msg = format!("{:#}", run(&cli.args).unwrap_err());
            assert!(msg.contains(flag), "{flag} {value}: {msg}");
        }
    }
}

#[cfg(test)]
mod limit_tests {
    use clap::Parser;

    use super::*;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: BenchForceArgs,
    }

    fn error_of(flags: &[&str]) -> String {
        let cli = Cli::parse_from(std::iter::once("bench-force").chain(flags.iter().copied()));
        run(&cli.args).unwrap_err().to_string()
    }

    #[test]
    fn counts_over_their_caps_are_named_errors() {
        assert_eq!(
            error_of(&["--contacts", "1000001"]),
            "--contacts = 1000001 is over the limit of 1000000 contacts (MAX_CONTACTS)"
        );
        assert!(error_of(&["--queries", "1000001"]).contains("(MAX_QUERIES)"));
        assert!(error_of(&["--repeats", "101"]).contains("(MAX_REPEATS)"));
        assert!(error_of(&["--fit-points", "20000001"]).contains("(MAX_GEN_POINTS)"));
        assert_eq!(
            error_of(&["--cells", "1000"]),
            "--cells = 1000 is over the limit of 200 cells per radius (MAX_FORCE_CELLS)"
        );
    }
}
