//! `workstation bench-view`: big scans end to end (issue 19). For each point count, a dense
//! sampling of a mesh (the bunny by default) is loaded and fitted as a live session's object,
//! then sculpted by a scripted hand on the real threads: the simulation thread
//! ([`crate::live::sim::run`]), a force-mapping thread at 1 kHz
//! ([`ForceMapper`](crate::live::force::ForceMapper) on a scripted cursor, no network) and a
//! renderer thread that prepares splats ([`SplatCache`](crate::live::frames::SplatCache)) for
//! every new snapshot, and optionally draws them headless.
//!
//! Every count is measured against a baseline scene (7,000 points by default) with the same
//! mesh, region, tools and strokes in the same run, so ratios compare like with like on a
//! machine whose load changes. Reported per scene: load + fit time and peak memory; the
//! simulation's field step (tools, integration, publishing: what the force thread waits for)
//! and whole iteration (plus points following, snapshots, commits) p50/p99/max; the force loop's
//! rate and work; frame preparation (snapshot → splats ready) p50/p99, and with
//! `--compare-full` the same for the old full recompute in a second session.
//!
//! The strokes (4 s cycle, repeated): a rope pressed on the bunny's back and pulled 8 mm out
//! along the normal over 1.5 s, then released (committed, resampled); a 5 mm probe pressed 2 mm
//! into the surface and dragged 18 mm sideways over 1.6 s, released.

mod session;

use std::path::PathBuf;

use anyhow::Context as _;
use serde::Serialize;

use crate::cap;
use crate::limits::MAX_GEN_POINTS;

pub use session::{SessionReport, Spread};

/// Parsed arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct BenchViewArgs {
    /// Point counts to measure, comma-separated (each against the baseline, same run).
    #[arg(long, value_delimiter = ',', default_values_t = [100_000usize, 1_000_000])]
    pub points: Vec<usize>,
    /// Points of the baseline scene (same mesh, region and strokes).
    #[arg(long, default_value_t = 7_000)]
    pub baseline: usize,
    /// Mesh whose triangles are sampled (normals interpolated from its vertices).
    #[arg(long, default_value = "data/bunny.ply")]
    pub mesh: PathBuf,
    /// Longest side of the sampled model (m).
    #[arg(long, default_value_t = 0.1)]
    pub size: f64,
    /// Seconds of scripted sculpting measured per scene (after 1 s of warm-up).
    #[arg(long, default_value_t = 8.0)]
    pub seconds: f64,
    /// Also run each scene with the old splat cache (every radius recomputed when anything
    /// moved) and report its frame preparation.
    #[arg(long)]
    pub compare_full: bool,
    /// Draw every prepared frame headless (wgpu; lavapipe without a GPU) and time it.
    #[arg(long)]
    pub draw: bool,
    /// With --draw: draw at most about this many splats, thinned as the window's CPU path
    /// does while the picture changes (`render::thin_splats`; the window uses 150000)
    #[arg(long, value_name = "SPLATS")]
    pub thin: Option<usize>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// One scene's measurements.
#[derive(Debug, Clone, Serialize)]
pub struct SceneRun {
    /// Points sampled.
    pub points: usize,
    /// The session with the incremental splat cache.
    pub session: SessionReport,
    /// The same scene with the old full recompute (`--compare-full`).
    pub full: Option<SessionReport>,
}

/// What `bench-view` measured.
#[derive(Debug, Clone, Serialize)]
pub struct BenchViewReport {
    /// The mesh sampled.
    pub mesh: String,
    /// Worker threads (rayon) available.
    pub threads: usize,
    /// The baseline scene.
    pub baseline: SceneRun,
    /// The scenes measured against it.
    pub scenes: Vec<SceneRun>,
}

/// Run the benchmark.
pub fn run(args: &BenchViewArgs) -> anyhow::Result<BenchViewReport> {
    cap!("--baseline", args.baseline, MAX_GEN_POINTS, "points")?;
    for &n in &args.points {
        cap!("--points", n, MAX_GEN_POINTS, "points")?;
    }
    anyhow::ensure!(
        args.seconds.is_finite() && args.seconds > 0.0 && args.seconds <= 3600.0,
        "--seconds must be in (0, 3600] (got {})",
        args.seconds
    );
    anyhow::ensure!(
        args.size.is_finite() && args.size > 0.0,
        "--size must be positive"
    );
    anyhow::ensure!(
        args.baseline >= 1000 && args.points.iter().all(|&n| n >= 1000),
        "point counts must be at least 1000 (the region needs points)"
    );
    let mesh = std::fs::canonicalize(&args.mesh)
        .with_context(|| format!("the mesh {}", args.mesh.display()))?;
    let scene = |n: usize, full: bool| -> anyhow::Result<SessionReport> {
        if !args.json {
            eprintln!(
                "scene of {n} points ({} splat cache)…",
                if full { "old full" } else { "incremental" }
            );
        }
        session::run(&session::SessionSpec {
            mesh: mesh.clone(),
            points: n,
            size: args.size,
            seconds: args.seconds,
            full,
            draw: args.draw,
            thin: args.thin,
            quiet: args.json,
        })
    };
    let measure = |n: usize| -> anyhow::Result<SceneRun> {
        Ok(SceneRun {
            points: n,
            session: scene(n, false)?,
            full: if args.compare_full {
                Some(scene(n, true)?)
            } else {
                None
            },
        })
    };
    let baseline = measure(args.baseline)?;
    let scenes = args
        .points
        .iter()
        .map(|&n| measure(n))
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok(BenchViewReport {
        mesh: args.mesh.display().to_string(),
        threads: rayon::current_num_threads(),
        baseline,
        scenes,
    })
}

/// Print the report as a table, or JSON.
pub fn print(report: &BenchViewReport, json: bool) -> anyhow::Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(report)?);
        return Ok(());
    }
    let b = &report.baseline.session;
    println!(
        "bench-view: {} sampled, {} threads; ratios are against the {}-point baseline of the same run",
        report.mesh, report.threads, report.baseline.points
    );
    println!(
        "{:>9} {:>7} {:>8} {:>8} {:>17} {:>17} {:>9} {:>8} {:>9} {:>17} {:>17}",
        "points",
        "fit s",
        "peak MiB",
        "region",
        "field step µs",
        "sim iter µs",
        "sim Hz",
        "force Hz",
        "force p99",
        "frame prep ms",
        "old prep ms"
    );
    println!(
        "{:>9} {:>7} {:>8} {:>8} {:>17} {:>17} {:>9} {:>8} {:>9} {:>17} {:>17}",
        "", "", "", "points", "p50 / p99", "p50 / p99", "", "", "work µs", "p50 / p99", "p50 / p99"
    );
    let row = |r: &SceneRun| {
        let s = &r.session;
        let old = r.full.as_ref().map_or("—".to_string(), |f| {
            format!("{:.2} / {:.2}", f.frame_prep_ms.p50, f.frame_prep_ms.p99)
        });
        println!(
            "{:>9} {:>7.2} {:>8.0} {:>8} {:>8.0} / {:>6.0} {:>8.0} / {:>6.0} {:>9.0} {:>8.0} {:>9.1} {:>8.2} / {:>6.2} {:>17}",
            r.points,
            s.fit_s,
            s.peak_rss_mib,
            s.region_points,
            s.field_step_us.p50,
            s.field_step_us.p99,
            s.sim_iteration_us.p50,
            s.sim_iteration_us.p99,
            s.sim_hz,
            s.force_hz,
            s.force_work_us.p99,
            s.frame_prep_ms.p50,
            s.frame_prep_ms.p99,
            old
        );
    };
    row(&report.baseline);
    for r in &report.scenes {
        row(r);
    }
    for r in &report.scenes {
        let s = &r.session;
        let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { f64::NAN };
        println!(
            "{} vs {}: field step p50 ×{:.2} p99 ×{:.2}; sim iteration p50 ×{:.2} p99 ×{:.2}; force rate ×{:.3}; frame prep p50 ×{:.1}",
            r.points,
            report.baseline.points,
            ratio(s.field_step_us.p50, b.field_step_us.p50),
            ratio(s.field_step_us.p99, b.field_step_us.p99),
            ratio(s.sim_iteration_us.p50, b.sim_iteration_us.p50),
            ratio(s.sim_iteration_us.p99, b.sim_iteration_us.p99),
            ratio(s.force_hz, b.force_hz),
            ratio(s.frame_prep_ms.p50, b.frame_prep_ms.p50),
        );
    }
    for r in std::iter::once(&report.baseline).chain(&report.scenes) {
        let s = &r.session;
        println!(
            "{}: {} strokes; {} snapshots prepared, {:.0} radii recomputed per snapshot (mean); resampling {} inserted, {} removed, {} projected{}",
            r.points,
            s.strokes,
            s.frames,
            s.mean_recomputed,
            s.resample_inserted,
            s.resample_removed,
            s.resample_projected,
            s.draw_ms.map_or(String::new(), |d| format!(
                "; draw p50 {:.1} ms p99 {:.1} ms",
                d.p50, d.p99
            ))
        );
    }
    Ok(())
}
