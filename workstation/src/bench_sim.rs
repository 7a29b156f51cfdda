//! `workstation bench-sim`: time one sculpting step per stage on a fitted sphere, with the field
//! error the run came with, and show that static objects do not change the cost.
//!
//! The scene: a sphere of radius 5 cm sampled with `--points` points and fitted (DESIGN §2); a
//! `--grid`³ region covering the whole object (like the papers' Table 3, whose 40³ grid held
//! 16,071 points); a narrow band of `--band-cells` cells simulated; a Gaussian rope pulling the
//! top outward. Each integrator is timed over `--steps` steps after a warm-up; then the same run
//! is repeated with `--static-objects` more objects in the scene.

use std::time::Instant;

use anyhow::Context as _;
use glam::DVec3;
use sim_core::FitParams;
use sim_core::dynamics::stability::{LimitSearch, measure_limit, predicted_limits};
use sim_core::dynamics::{Integrator, NodeParams};
use sim_core::sampling::Shape;
use sim_core::scene::{RegionParams, Scene, SceneObject, SculptStage, StepObserver};
use sim_core::tools::{Profile, Rope};

use crate::cap;
use crate::limits::{MAX_BENCH_GRID, MAX_GEN_POINTS, MAX_STATIC_OBJECTS, MAX_STEPS, OverLimit};

mod report;

pub use report::{BenchSimReport, IntegratorRun, Limits, Spread, print};

/// Sphere radius of the benchmark object (m).
pub const RADIUS: f64 = 0.05;

/// Parsed arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct BenchSimArgs {
    /// Grid nodes per axis of the sculpting region.
    #[arg(long, default_value_t = 40)]
    pub grid: usize,
    /// Points on the sphere.
    #[arg(long, default_value_t = 16_071)]
    pub points: usize,
    /// Timed steps per integrator.
    #[arg(long, default_value_t = 300)]
    pub steps: usize,
    /// Band half-width in grid cells.
    #[arg(long, default_value_t = 3.0)]
    pub band_cells: f64,
    /// Points follow the field every this many steps (display rate = haptic rate / this).
    #[arg(long, default_value_t = 1)]
    pub follow_every: u32,
    /// Static objects added for the region-only comparison.
    #[arg(long, default_value_t = 10)]
    pub static_objects: usize,
    /// Time step (s); 1 ms is the haptic rate.
    #[arg(long, default_value_t = 1e-3)]
    pub dt: f64,
    /// Also measure the explicit integrators' stability limits on this model (slow).
    #[arg(long)]
    pub limits: bool,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

struct StageClock {
    last: Instant,
    times: [f64; 4],
}

impl StepObserver for StageClock {
    fn stage_done(&mut self, stage: SculptStage) {
        let now = Instant::now();
        let i = match stage {
            SculptStage::Tools => 0,
            SculptStage::Integrate => 1,
            SculptStage::Follow => 2,
            SculptStage::Refit => 3,
        };
        self.times[i] += (now - self.last).as_secs_f64() * 1e3;
        self.last = now;
    }
}

fn spread(mut v: Vec<f64>) -> Spread {
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    Spread {
        median: at(0.5),
        p10: at(0.1),
        p90: at(0.9),
    }
}

/// Region parameters of the benchmark: default nodes (explicit limits ≈ 2.3 ms and 2.6 ms),
/// symplectic Euler, points following every `follow_every` steps.
pub fn bench_params(spacing: f64, band_cells: f64, follow_every: u32) -> RegionParams {
    RegionParams {
        node: NodeParams::default(),
        integrator: Integrator::SymplecticEuler,
        follow_every,
        ..RegionParams::new(spacing, band_cells * spacing)
    }
}

/// The fitted benchmark sphere.
pub fn sphere_object(points: usize) -> anyhow::Result<SceneObject> {
    let ps = Shape::Sphere { radius: RADIUS }.sample(points, 1);
    SceneObject::fit("sphere", ps, &FitParams::default()).context("fitting the benchmark sphere")
}

fn timed_run(
    object: &SceneObject,
    statics: usize,
    params: RegionParams,
    args: &BenchSimArgs,
) -> anyhow::Result<(IntegratorRun, usize, Scene)> {
    let mut scene = Scene::new();
    let id = scene.add(object.clone());
    for k in 0..statics {
        let mut o = object.clone();
        o.name = format!("static-{k}");
        scene.add(o);
    }
    let half = RADIUS + 2.0 * params.spacing;
    scene.open_region(id, DVec3::splat(-half), DVec3::splat(half), params)?;
    // A rope dragged around the top: 20° from the pole, one turn per 200 ms, so the field and
    // the points never settle (a held rope would make the follow stage free once settled).
    let mut rope = Rope {
        path: vec![DVec3::new(0.0, 0.0, RADIUS)],
        radius: 0.4 * RADIUS,
        strength: params.node.anchor * 0.1 * RADIUS,
        profile: Profile::Gaussian,
        sheet: None,
    };
    let warmup = 20.min(args.steps);
    let (mut step, mut tools, mut integ, mut follow, mut publish) =
        (vec![], vec![], vec![], vec![], vec![]);
    let (mut cg, mut visited, mut exact) = (0.0, 0.0, 0.0);
    for i in 0..warmup + args.steps {
        let start = Instant::now();
        let phase = std::f64::consts::TAU * (i as f64 * args.dt) / 0.2;
        let tilt = 20f64.to_radians();
        rope.path[0] = RADIUS
            * DVec3::new(
                tilt.sin() * phase.cos(),
                tilt.sin() * phase.sin(),
                tilt.cos(),
            );
        let ropes = std::slice::from_ref(&rope);
        let mut clock = StageClock {
            last: start,
            times: [0.0; 4],
        };
        let r = scene.step_observed(args.dt, ropes, &mut clock)?;
        let p0 = Instant::now();
        let snapshot = scene.publish();
        let pub_ms = p0.elapsed().as_secs_f64() * 1e3;
        drop(snapshot);
        if i >= warmup {
            step.push(start.elapsed().as_secs_f64() * 1e3);
            tools.push(clock.times[0]);
            integ.push(clock.times[1]);
            follow.push(clock.times[2]);
            publish.push(pub_ms);
            cg += r.step.cg_iterations as f64;
            visited += r.follow.visited as f64;
            exact += r.follow.exact_evaluations as f64;
        }
    }
    let mean_step = step.iter().sum::<f64>() / step.len() as f64;
    let region = scene.region().context("region open")?;
    let memory = region.memory_bytes();
    let top = scene.objects()[id]
        .positions
        .iter()
        .map(|p| p.z)
        .fold(f64::NEG_INFINITY, f64::max);
    let t0 = Instant::now();
    let moved = scene.end_stroke()?;
    let refit_ms = t0.elapsed().as_secs_f64() * 1e3;
    Ok((
        IntegratorRun {
            integrator: params.integrator.name().into(),
            step_ms: spread(step),
            tools_ms: spread(tools),
            integrate_ms: spread(integ),
            follow_ms: spread(follow),
            publish_ms: spread(publish),
            refit_ms,
            moved_points: moved,
            bump_height: top - RADIUS,
            cg_iterations: cg / args.steps.max(1) as f64,
            visited_points: visited / args.steps.max(1) as f64,
            exact_evaluations: exact / args.steps.max(1) as f64,
            step_ms_mean: mean_step,
        },
        memory,
        scene,
    ))
}

/// The caps on `--grid`, `--points`, `--steps` and `--static-objects` (see [`crate::limits`]).
fn check_counts(args: &BenchSimArgs) -> Result<(), OverLimit> {
    cap!("--grid", args.grid, MAX_BENCH_GRID, "nodes per side")?;
    cap!("--points", args.points, MAX_GEN_POINTS, "points")?;
    cap!("--steps", args.steps, MAX_STEPS, "steps")?;
    cap!(
        "--static-objects",
        args.static_objects,
        MAX_STATIC_OBJECTS,
        "objects"
    )?;
    cap!(
        "--points × (1 + --static-objects)",
        args.points * (1 + args.static_objects),
        MAX_GEN_POINTS,
        "points"
    )
}

/// Run the benchmark.
pub fn run(args: &BenchSimArgs) -> anyhow::Result<BenchSimReport> {
    anyhow::ensure!(args.grid >= 8, "--grid must be at least 8");
    anyhow::ensure!(args.points >= 100, "--points must be at least 100");
    anyhow::ensure!(args.steps >= 1, "--steps must be at least 1");
    check_counts(args)?;
    anyhow::ensure!(
        args.dt.is_finite() && args.dt > 0.0,
        "--dt must be positive"
    );
    anyhow::ensure!(
        args.band_cells > 0.0,
        "--band-cells must be positive (got {}; inf: every node)",
        args.band_cells
    );
    let t0 = Instant::now();
    let object = sphere_object(args.points)?;
    let fit_ms = t0.elapsed().as_secs_f64() * 1e3;
    // Two cells of margin on each side: the grid spans 2R + 4h with `grid` nodes.
    let spacing = 2.0 * RADIUS / (args.grid as f64 - 5.0);
    let base = bench_params(spacing, args.band_cells, args.follow_every);

    let t1 = Instant::now();
    let mut probe = Scene::new();
    let id = probe.add(object.clone());
    let half = RADIUS + 2.0 * spacing;
    probe.open_region(id, DVec3::splat(-half), DVec3::splat(half), base)?;
    let region_ms = t1.elapsed().as_secs_f64() * 1e3;
    let snap = probe.publish().context("region open")?;
    let (mut se, mut emax) = (0.0, 0.0f64);
    for p in &object.positions {
        let n = p.normalize() * RADIUS; // exact sphere point
        let e = snap.sample(n).map_or(f64::NAN, |s| s.value.abs());
        se += e * e;
        emax = emax.max(e);
    }
    let field_error_rms = (se / object.positions.len() as f64).sqrt();
    let model = probe.region().context("region open")?.model();
    let (active_nodes, grid_nodes) = (model.active_len(), model.spec().node_count());
    let limits = args.limits.then(|| {
        let (fe_p, se_p) = predicted_limits(model);
        let search = LimitSearch {
            steps: 500,
            rounds: 10,
            ..LimitSearch::default()
        };
        Limits {
            forward_euler_measured: measure_limit(
                model,
                Integrator::forward_euler(1e9),
                1e-5,
                1e-1,
                &search,
            ),
            forward_euler_predicted: fe_p,
            symplectic_euler_measured: measure_limit(
                model,
                Integrator::SymplecticEuler,
                1e-5,
                1e-1,
                &search,
            ),
            symplectic_euler_predicted: se_p,
        }
    });

    let mut runs = Vec::new();
    let mut memory_bytes = 0;
    for integrator in [
        Integrator::SymplecticEuler,
        Integrator::forward_euler(1e6),
        Integrator::backward_euler(),
    ] {
        let (run, mem, _) = timed_run(&object, 0, RegionParams { integrator, ..base }, args)?;
        if integrator == Integrator::SymplecticEuler {
            memory_bytes = mem;
        }
        runs.push(run);
    }
    let (with_static, memory_bytes_with_static, scene) =
        timed_run(&object, args.static_objects, base, args)?;
    // Static objects are bit-for-bit untouched.
    for o in &scene.objects()[1..] {
        anyhow::ensure!(o.positions == object.positions, "a static object moved");
    }
    Ok(BenchSimReport {
        step_ms: runs[0].step_ms.median,
        field_error: field_error_rms,
        field_error_rms,
        field_error_max: emax,
        field_error_relative: field_error_rms / RADIUS,
        grid: args.grid,
        points: object.positions.len(),
        active_nodes,
        grid_nodes,
        spacing,
        dt: args.dt,
        fit_ms,
        region_ms,
        runs,
        with_static,
        static_objects: args.static_objects,
        memory_bytes,
        memory_bytes_with_static,
        limits,
    })
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        args: BenchSimArgs,
    }

    #[test]
    fn bad_band_is_an_error_naming_the_flag() {
        // Used to fail after fitting the sphere as "band half-width NaN must be ≥ 0".
        for v in ["nan", "-1", "0"] {
            let cli = Cli::parse_from(["bench-sim", &format!("--band-cells={v}")]);
            let msg = format!("{:#}", run(&cli.args).unwrap_err());
            assert!(msg.contains("--band-cells"), "{v}: {msg}");
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
        args: BenchSimArgs,
    }

    fn error_of(flags: &[&str]) -> String {
        let cli = Cli::parse_from(std::iter::once("bench-sim").chain(flags.iter().copied()));
        run(&cli.args).unwrap_err().to_string()
    }

    #[test]
    fn counts_over_their_caps_are_named_errors() {
        assert_eq!(
            error_of(&["--steps", "1000001"]),
            "--steps = 1000001 is over the limit of 1000000 steps (MAX_STEPS)"
        );
        assert!(error_of(&["--points", "20000001"]).contains("(MAX_GEN_POINTS)"));
        assert!(error_of(&["--grid", "257"]).starts_with("--grid = 257"));
        assert!(error_of(&["--static-objects", "101"]).contains("(MAX_STATIC_OBJECTS)"));
        assert_eq!(
            error_of(&["--points", "1000000", "--static-objects", "20"]),
            "--points × (1 + --static-objects) = 21000000 is over the limit of 20000000 points (MAX_GEN_POINTS)"
        );
    }
}
