//! `workstation delay-study`: what network delay and loss do to a stiff contact, per rendering
//! method, on a virtual clock (no network, no threads, deterministic).
//!
//! The closed loop, at 1 kHz: the fake device's simulated hand (200 N/m, 5 N·s/m grip on a
//! 50 g stylus) presses onto a wall and slides along it ([`sim::hand_script`]); the server's own
//! [`haptics_server::servo::ServoCore`] renders and passes the force through its safety stages;
//! a [`protocol::SimLink`] carries cursors up and commands down with the given one-way delay
//! and loss; the workstation side is the real [`crate::live::force::ForceMapper`] (Kim-style
//! field force with VCP and friction) on the field `f = y` of a 2 kN/m wall, exactly as
//! `workstation run` maps a scene.
//!
//! Methods: (a) `zoh`: commands without model, the server holds the last force; (b) `ewma`:
//! the same, smoothed `E ← 0.9 E + 0.1 F` per tick; (c) `local_model`: the plane model rendered
//! at the current cursor; (d) `local_model_passivity`: (c) plus the server's passivity
//! observer/controller. Then the same four on a surface that moves ([`live`]): a probe pressed
//! into the live simulated field and a rope pull, with delay, jitter and loss, and the method
//! to ship per delay. Outputs in `--out`: `report.json`, `runs.csv`, `summary.md` and PNG plots.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use protocol::LinkParams;

pub mod live;
mod live_report;
mod plots;
mod report;
pub mod sim;

pub use live_report::{LiveReport, LiveRow, Recommendation};
pub use report::{DelayStudyReport, Expectations, RunRow, SweepRow, print};
pub use sim::{Method, RunSpec, Trace, Wall, simulate};

/// Energy a run may deliver to the hand and still count as passive, J (0.5 mJ: under a third
/// of the 1.7 mJ a 700 N/m contact stores at the 1.56 N hold force).
pub const ENERGY_TOLERANCE_J: f64 = 5e-4;
/// Peak-to-peak force during the held press above which a run counts as unstable, N.
pub const HOLD_RIPPLE_N: f64 = 0.2;

/// Parsed arguments.
#[derive(Debug, Clone, clap::Args)]
#[command(long_about = "\
Simulate a hand pressing onto and sliding along a stiff wall (2 kN/m, clamped by the server to \
its device's 700 N/m and 3.3 N) through the real servo core and force mapper, with a simulated \
link of the given one-way delays and losses both ways, for four rendering methods: (a) zoh, the \
last force held; (b) ewma, the force smoothed; (c) local_model, the contact plane rendered at \
the current cursor; (d) local_model_passivity, (c) with the passivity controller. Reports per \
run the RMS force error against the same method without delay, peak force, the energy the \
device delivered to the hand (> 0: the interface generated energy) and whether the held press \
was steady; then a deadband sweep (packets sent vs force error). Then the same methods on a \
surface that moves: a probe pressed into the live simulated field (the surface gives way \
under it) and a rope pull, through the workstation's own simulation, at each delay clean, \
with --live-jitter-ms and with each loss: force error against the run without delay and \
against the ideal, energy the link added, and the depth error of the sculpted shape; it says \
which method it would ship for which delay (--no-live skips this part, ~1 s per run). \
Everything runs on a virtual clock: the same flags give the same numbers.

Writes OUT/report.json, OUT/runs.csv, OUT/live_runs.csv, OUT/summary.md and the PNG plots \
error_vs_delay.png, traces_20ms.png, traces_100ms.png, energy_vs_delay.png, deadband.png and \
live_error_vs_delay.png.

Example: workstation delay-study --out out/delay --delays-ms 0,5,20,50,100 --loss 0,0.05,0.2")]
pub struct DelayStudyArgs {
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// One-way delays to run, ms (each both ways: the round trip is twice this).
    #[arg(long, value_delimiter = ',', default_value = "0,5,20,50,100")]
    pub delays_ms: Vec<f64>,
    /// Loss probabilities per packet per direction, in [0, 1).
    #[arg(long, value_delimiter = ',', default_value = "0,0.05,0.2")]
    pub loss: Vec<f64>,
    /// Simulated seconds per run (the press-and-slide script is 5.3 s; longer runs repeat it).
    #[arg(long, default_value_t = sim::SCRIPT_S)]
    pub seconds: f64,
    /// Seed of the links' loss draws.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Perceptual deadband (Weber fraction K) on both streams for the main grid; 0 = off.
    #[arg(long, default_value_t = 0.0)]
    pub deadband: f64,
    /// EWMA smoothing α of method (b), in [0, 1).
    #[arg(long, default_value_t = f64::from(sim::EWMA_ALPHA))]
    pub ewma_alpha: f64,
    /// Deadband values for the sweeps (local model at 20 ms one way, and zoh at 0 ms; no loss).
    #[arg(long, value_delimiter = ',', default_value = "0.02,0.05,0.1,0.2")]
    pub deadband_sweep: Vec<f64>,
    /// Skip the runs on the surface that moves (the probe press and the rope pull through the
    /// live simulation, about 1 s of compute each).
    #[arg(long)]
    pub no_live: bool,
    /// Jitter of the live runs' jittered conditions (each delay > 0 once with it), ms.
    #[arg(long, default_value_t = 10.0)]
    pub live_jitter_ms: f64,
    /// Print the JSON report to stdout instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// RMS of `|a − b|` over the common length.
pub fn rms_error(a: &[Vec3], b: &[Vec3]) -> f64 {
    let n = a.len().min(b.len()).max(1);
    let s: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| f64::from((*x - *y).length_squared()))
        .sum();
    (s / n as f64).sqrt()
}

/// RMS of `|a|`.
pub fn rms(a: &[Vec3]) -> f64 {
    rms_error(a, &vec![Vec3::ZERO; a.len()])
}

/// Largest `|a|`.
pub fn peak(a: &[Vec3]) -> f64 {
    a.iter().map(|f| f64::from(f.length())).fold(0.0, f64::max)
}

/// Peak-to-peak of `|F|` in the steady part of the held press, N.
pub fn hold_ripple(t: &Trace) -> (f64, f64) {
    let (a, b) = sim::HOLD_WINDOW_S;
    let w =
        &t.force[((a * 1e3) as usize).min(t.force.len())..((b * 1e3) as usize).min(t.force.len())];
    if w.is_empty() {
        return (0.0, 0.0);
    }
    let mags = w.iter().map(|f| f64::from(f.length()));
    let (lo, hi) = mags.fold((f64::INFINITY, 0.0f64), |(l, h), m| (l.min(m), h.max(m)));
    let mean = w.iter().map(|f| f64::from(f.length())).sum::<f64>() / w.len() as f64;
    (mean, hi - lo)
}

fn spec(method: Method, delay_ms: f64, loss: f64, deadband: f64, args: &DelayStudyArgs) -> RunSpec {
    RunSpec {
        method,
        link: LinkParams {
            loss,
            seed: args.seed,
            ..LinkParams::delay((delay_ms * 1e6).round() as u64)
        },
        deadband: deadband as f32,
        seconds: args.seconds,
        ewma_alpha: args.ewma_alpha as f32,
    }
}

fn validate(args: &DelayStudyArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.seconds.is_finite() && args.seconds >= 2.5 && args.seconds <= 600.0,
        "--seconds must be in 2.5 … 600 (the held press ends at 2.2 s)"
    );
    anyhow::ensure!(
        args.delays_ms
            .iter()
            .all(|d| d.is_finite() && (0.0..=1000.0).contains(d)),
        "--delays-ms must be in 0 … 1000"
    );
    anyhow::ensure!(
        args.loss
            .iter()
            .all(|l| l.is_finite() && (0.0..1.0).contains(l)),
        "--loss must be in [0, 1)"
    );
    anyhow::ensure!(
        args.deadband_sweep
            .iter()
            .chain([&args.deadband])
            .all(|k| k.is_finite() && (0.0..=1.0).contains(k)),
        "--deadband and --deadband-sweep must be in [0, 1]"
    );
    anyhow::ensure!(
        args.live_jitter_ms.is_finite() && (0.0..=1000.0).contains(&args.live_jitter_ms),
        "--live-jitter-ms must be in 0 … 1000"
    );
    anyhow::ensure!(
        args.ewma_alpha.is_finite() && (0.0..1.0).contains(&args.ewma_alpha),
        "--ewma-alpha must be in [0, 1)"
    );
    Ok(())
}

/// Run the whole study (no files written; see [`write()`]).
pub fn study(
    args: &DelayStudyArgs,
    bar: &ProgressBar,
) -> anyhow::Result<(DelayStudyReport, Vec<(RunRow, Trace)>)> {
    validate(args)?;
    let wall = Wall::new()?;
    let mut rows = Vec::new();
    // References: each method without delay, loss or deadband.
    let mut refs = Vec::new();
    for m in Method::ALL {
        refs.push((m, simulate(&wall, &spec(m, 0.0, 0.0, 0.0, args))?));
        bar.inc(1);
    }
    let reference = |m: Method| &refs.iter().find(|(r, _)| *r == m).expect("all methods").1;
    let ideal = reference(Method::LocalModel);
    for &loss in &args.loss {
        for &d in &args.delays_ms {
            for m in Method::ALL {
                let t = simulate(&wall, &spec(m, d, loss, args.deadband, args))?;
                let row = report::row(m, d, loss, args.deadband, &t, reference(m), ideal);
                rows.push((row, t));
                bar.inc(1);
            }
        }
    }
    // The deadband sweeps, no loss: the local model at 20 ms one way, and the held force
    // (zoh) at 0 ms, where what the force stream carries is what the hand feels.
    let mut sweep = Vec::new();
    for (m, d) in [(Method::LocalModel, 20.0), (Method::Zoh, 0.0)] {
        let base = simulate(&wall, &spec(m, d, 0.0, 0.0, args))?;
        sweep.push(report::sweep_row(m, d, 0.0, &base, &base));
        for &k in &args.deadband_sweep {
            let t = simulate(&wall, &spec(m, d, 0.0, k, args))?;
            sweep.push(report::sweep_row(m, d, k, &t, &base));
            bar.inc(1);
        }
    }
    let mut report = report::assemble(args, &rows, sweep);
    if !args.no_live {
        report.live = Some(live_report::study(args, bar, &report.runs)?);
    }
    Ok((report, rows))
}

/// Number of runs [`study`] makes (for the progress bar).
pub fn run_count(args: &DelayStudyArgs) -> u64 {
    (Method::ALL.len() * (1 + args.loss.len() * args.delays_ms.len())
        + 2 * args.deadband_sweep.len()) as u64
        + live_report::run_count(args)
}

/// Write the report files and plots into `dir`.
pub fn write(
    dir: &Path,
    report: &DelayStudyReport,
    rows: &[(RunRow, Trace)],
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let json = serde_json::to_string_pretty(report)?;
    std::fs::write(dir.join("report.json"), json + "\n")?;
    std::fs::write(dir.join("runs.csv"), report::csv(report))?;
    std::fs::write(dir.join("summary.md"), report::summary_md(report))?;
    plots::all(dir, report, rows)?;
    if let Some(live) = &report.live {
        std::fs::write(dir.join("live_runs.csv"), live_report::csv(live))?;
        live_report::plot(&dir.join("live_error_vs_delay.png"), live)?;
    }
    Ok(())
}

/// The command: run, write, return the report.
pub fn run(args: &DelayStudyArgs) -> anyhow::Result<DelayStudyReport> {
    validate(args)?;
    let bar = if args.json {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(run_count(args))
    };
    bar.set_style(
        ProgressStyle::with_template("delay study {bar:40} {pos}/{len} runs ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let (report, rows) = study(args, &bar)?;
    bar.finish_and_clear();
    write(&args.out, &report, &rows)?;
    Ok(report)
}

#[cfg(test)]
mod tests;
