//! The live part of `delay-study`: its grid of conditions, its rows, which method it would
//! ship for which delay, its Markdown and its plot.

use std::fmt::Write as _;
use std::path::Path;

use indicatif::ProgressBar;
use plotters::prelude::*;
use protocol::LinkParams;
use serde::Serialize;

use super::live::{LiveSpec, LiveTrace, Sculpt, shape_difference, simulate_live};
use super::plots::err;
use super::sim::Method;
use super::{DelayStudyArgs, ENERGY_TOLERANCE_J, RunRow, peak, rms_error};

/// One live run's figures.
#[derive(Debug, Clone, Serialize)]
pub struct LiveRow {
    /// The stroke.
    pub sculpt: Sculpt,
    /// Rendering method.
    pub method: Method,
    /// One-way delay, ms (both directions).
    pub delay_ms: f64,
    /// Extra delay drawn uniformly from `[0, jitter]` per packet, ms.
    pub jitter_ms: f64,
    /// Loss probability per packet per direction.
    pub loss: f64,
    /// RMS of |F − F_ref|, F_ref = the same method and stroke without delay, jitter or loss, N.
    pub force_error_rms_n: f64,
    /// RMS of |F − F_ideal|, F_ideal = the local model without delay on the same stroke, N.
    pub force_error_vs_ideal_rms_n: f64,
    /// Largest output force, N.
    pub peak_force_n: f64,
    /// Net energy the device delivered to the hand, J (> 0: generated). Not zero without
    /// delay: the committed dent is shallower than the probe, so the material pushes the
    /// lifting probe out.
    pub energy_generated_j: f64,
    /// `energy_generated_j` minus the reference run's: what the link added, J.
    pub energy_added_j: f64,
    /// The passivity observer's largest in-contact deficit, J.
    pub observer_min_j: f64,
    /// Energy the passivity controller dissipated, J.
    pub pc_dissipated_j: f64,
    /// The committed shape's height on the stroke's axis above the ball's top, m (< 0: dent).
    pub height_m: f64,
    /// `|height − height_ref|`, m.
    pub depth_error_m: f64,
    /// Largest difference of the committed field from the reference's near the surface, m.
    pub shape_difference_m: f64,
    /// The stroke was committed (its press and release both reached the simulation).
    pub committed: bool,
    /// Times the server's watchdog began fading.
    pub watchdog_fades: u64,
    /// Packets lost on both links.
    pub lost: u64,
}

/// The method the study would ship at one delay, and why.
#[derive(Debug, Clone, Serialize)]
pub struct Recommendation {
    /// One-way delay, ms.
    pub delay_ms: f64,
    /// The method.
    pub method: Method,
    /// Its force error vs the ideal, summed over both strokes and every jitter/loss condition
    /// at this delay, N.
    pub summed_error_vs_ideal_n: f64,
    /// The rule, in words.
    pub why: String,
}

/// The live part of the report.
#[derive(Debug, Clone, Serialize)]
pub struct LiveReport {
    /// The conditions, in words.
    pub conditions: String,
    /// Every run.
    pub runs: Vec<LiveRow>,
    /// The default method per delay.
    pub recommendation: Vec<Recommendation>,
}

/// `(delay, jitter, loss)` of every live condition: each delay clean, with the jitter (when it
/// is > 0 and the delay is), and with each nonzero loss.
pub fn conditions(args: &DelayStudyArgs) -> Vec<(f64, f64, f64)> {
    let mut c = Vec::new();
    for &d in &args.delays_ms {
        c.push((d, 0.0, 0.0));
        if d > 0.0 && args.live_jitter_ms > 0.0 {
            c.push((d, args.live_jitter_ms, 0.0));
        }
        c.extend(args.loss.iter().filter(|&&l| l > 0.0).map(|&l| (d, 0.0, l)));
    }
    c
}

/// Number of live runs (for the progress bar); 0 with `--no-live`.
pub fn run_count(args: &DelayStudyArgs) -> u64 {
    if args.no_live {
        return 0;
    }
    (Sculpt::ALL.len() * Method::ALL.len() * (1 + conditions(args).len())) as u64
}

fn link(args: &DelayStudyArgs, (d, j, l): (f64, f64, f64)) -> LinkParams {
    LinkParams {
        jitter_ns: (j * 1e6).round() as u64,
        loss: l,
        seed: args.seed,
        ..LinkParams::delay((d * 1e6).round() as u64)
    }
}

/// Run the live grid; `wall` is the wall study's runs, which the recommendation also reads.
pub fn study(
    args: &DelayStudyArgs,
    bar: &ProgressBar,
    wall: &[RunRow],
) -> anyhow::Result<LiveReport> {
    let mut runs = Vec::new();
    for sculpt in Sculpt::ALL {
        let spec = |method, c| LiveSpec {
            sculpt,
            method,
            link: link(args, c),
            ewma_alpha: args.ewma_alpha as f32,
        };
        let mut refs: Vec<(Method, LiveTrace)> = Vec::new();
        for m in Method::ALL {
            refs.push((m, simulate_live(&spec(m, (0.0, 0.0, 0.0)))?));
            bar.inc(1);
        }
        let reference = |m: Method| &refs.iter().find(|(r, _)| *r == m).expect("all").1;
        for c in conditions(args) {
            for m in Method::ALL {
                let t = simulate_live(&spec(m, c))?;
                runs.push(row(
                    sculpt,
                    m,
                    c,
                    &t,
                    reference(m),
                    reference(Method::LocalModel),
                ));
                bar.inc(1);
            }
        }
    }
    let recommendation = recommend(&runs, wall);
    Ok(LiveReport {
        conditions: format!(
            "Virtual clock at 1 kHz, {:.1} s per run. A 5 cm ball of 2,000 points, its top in a \
             sculpting region (2.5 mm grid, 8 mm band, 1 ms steps) simulated by the workstation's \
             own SimCore from the cursors as they arrive. probe_press: an 8 mm probe pressed \
             toward 12 mm into the ball at 10 mm/s, held, the button let go there (commit), \
             lifted. rope_pull: the top grabbed and pulled 18 mm out at 15 mm/s, held, let go \
             (60 N/m rope). Hand and server as in the wall study; seed {}; jitter draws each \
             packet's extra delay uniformly (so packets reorder). References: the same method \
             without delay; the ideal: the local model without delay.",
            super::live::SCRIPT_S,
            args.seed
        ),
        runs,
        recommendation,
    })
}

fn row(
    sculpt: Sculpt,
    method: Method,
    (delay_ms, jitter_ms, loss): (f64, f64, f64),
    t: &LiveTrace,
    reference: &LiveTrace,
    ideal: &LiveTrace,
) -> LiveRow {
    LiveRow {
        sculpt,
        method,
        delay_ms,
        jitter_ms,
        loss,
        force_error_rms_n: rms_error(&t.force, &reference.force),
        force_error_vs_ideal_rms_n: rms_error(&t.force, &ideal.force),
        peak_force_n: peak(&t.force),
        energy_generated_j: t.energy_delivered_j,
        energy_added_j: t.energy_delivered_j - reference.energy_delivered_j,
        observer_min_j: t.observer_min_j,
        pc_dissipated_j: t.pc_dissipated_j,
        height_m: t.height_m,
        depth_error_m: (t.height_m - reference.height_m).abs(),
        shape_difference_m: shape_difference(&t.field, &reference.field, 0.004),
        committed: t.strokes == 1,
        watchdog_fades: t.fades,
        lost: t.lost,
    }
}

/// Per delay: among the methods that, at that delay, held the wall stable and passive in
/// every run of the wall study and, on the moving surface, added no more than
/// [`ENERGY_TOLERANCE_J`], never faded and always committed, the one with the smallest force
/// error against the ideal summed over both strokes and all conditions. A default must feel
/// right on what moves and on what does not.
pub fn recommend(runs: &[LiveRow], wall: &[RunRow]) -> Vec<Recommendation> {
    let mut delays: Vec<f64> = runs.iter().map(|r| r.delay_ms).collect();
    delays.sort_by(f64::total_cmp);
    delays.dedup();
    delays
        .into_iter()
        .filter_map(|d| {
            let best = Method::ALL
                .into_iter()
                .filter_map(|m| {
                    let mine: Vec<_> = runs
                        .iter()
                        .filter(|r| r.method == m && r.delay_ms == d)
                        .collect();
                    let moving_ok = mine.iter().all(|r| {
                        r.energy_added_j <= ENERGY_TOLERANCE_J
                            && r.watchdog_fades == 0
                            && r.committed
                    });
                    let wall_ok = wall
                        .iter()
                        .filter(|r| r.method == m && r.delay_ms == d)
                        .all(|r| r.stable && r.passive);
                    (moving_ok && wall_ok)
                        .then(|| (m, mine.iter().map(|r| r.force_error_vs_ideal_rms_n).sum()))
                })
                .min_by(|a: &(Method, f64), b| a.1.total_cmp(&b.1))?;
            Some(Recommendation {
                delay_ms: d,
                method: best.0,
                summed_error_vs_ideal_n: best.1,
                why: format!(
                    "at {d} ms one way: stable and passive on the wall in every run, added \
                     ≤ {:.1} mJ, never faded and committed every stroke on the moving surface, \
                     and of those the smallest force error against the ideal (summed over both \
                     strokes, with and without jitter and loss)",
                    ENERGY_TOLERANCE_J * 1e3
                ),
            })
        })
        .collect()
}

/// The live runs and the recommendation as Markdown.
pub fn md(r: &LiveReport) -> String {
    let mut s = format!("## On a surface that moves\n\n{}\n\n", r.conditions);
    s.push_str("Default method per one-way delay:\n\n");
    for x in &r.recommendation {
        let _ = writeln!(
            s,
            "- {} ms: **{}** (summed error vs ideal {:.3} N)",
            x.delay_ms,
            x.method.name(),
            x.summed_error_vs_ideal_n
        );
    }
    s.push_str(
        "\n| stroke | method | delay (ms) | jitter (ms) | loss | force error (N RMS) | vs ideal (N RMS) | peak (N) | energy added (mJ) | height (mm) | depth error (mm) | shape difference (mm) | committed | fades |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|\n",
    );
    for x in &r.runs {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.0} % | {:.3} | {:.3} | {:.2} | {:.3} | {:.2} | {:.3} | {:.3} | {} | {} |",
            x.sculpt.name(),
            x.method.name(),
            x.delay_ms,
            x.jitter_ms,
            x.loss * 100.0,
            x.force_error_rms_n,
            x.force_error_vs_ideal_rms_n,
            x.peak_force_n,
            x.energy_added_j * 1e3,
            x.height_m * 1e3,
            x.depth_error_m * 1e3,
            x.shape_difference_m * 1e3,
            if x.committed { "yes" } else { "NO" },
            x.watchdog_fades
        );
    }
    s
}

/// `live_runs.csv`: one line per live run.
pub fn csv(r: &LiveReport) -> String {
    let mut s = String::from(
        "sculpt,method,delay_ms,jitter_ms,loss,force_error_rms_n,force_error_vs_ideal_rms_n,\
         peak_force_n,energy_generated_j,energy_added_j,observer_min_j,pc_dissipated_j,height_m,\
         depth_error_m,shape_difference_m,committed,watchdog_fades,lost\n",
    );
    for x in &r.runs {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{:.6},{:.6},{:.4},{:.6e},{:.6e},{:.6e},{:.6e},{:.7},{:.7},{:.7},{},{},{}",
            x.sculpt.name(),
            x.method.name(),
            x.delay_ms,
            x.jitter_ms,
            x.loss,
            x.force_error_rms_n,
            x.force_error_vs_ideal_rms_n,
            x.peak_force_n,
            x.energy_generated_j,
            x.energy_added_j,
            x.observer_min_j,
            x.pc_dissipated_j,
            x.height_m,
            x.depth_error_m,
            x.shape_difference_m,
            x.committed,
            x.watchdog_fades,
            x.lost
        );
    }
    s
}

/// `live_error_vs_delay.png`: force error against the ideal vs delay, per stroke and method,
/// clean link (solid) and with loss or jitter (the worst of them, dashed markers).
pub fn plot(path: &Path, r: &LiveReport) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, (1200, 520)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let panels = root.split_evenly((1, 2));
    let dmax = r.runs.iter().map(|x| x.delay_ms).fold(1.0, f64::max) * 1.05;
    let emax = r
        .runs
        .iter()
        .map(|x| x.force_error_vs_ideal_rms_n)
        .fold(0.01, f64::max)
        * 1.15;
    for (panel, sculpt) in panels.iter().zip(Sculpt::ALL) {
        let mut c = ChartBuilder::on(panel)
            .caption(
                format!("{}: force error vs ideal", sculpt.name()),
                ("sans-serif", 20),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..dmax, 0.0..emax)
            .map_err(err)?;
        c.configure_mesh()
            .x_desc("one-way delay (ms)")
            .y_desc("RMS |F − F_ideal| (N)")
            .draw()
            .map_err(err)?;
        for m in Method::ALL {
            let col = super::plots::colour(m);
            let mine = |clean: bool| {
                r.runs.iter().filter(move |x| {
                    x.sculpt == sculpt
                        && x.method == m
                        && (x.jitter_ms == 0.0 && x.loss == 0.0) == clean
                })
            };
            let pts: Vec<(f64, f64)> = mine(true)
                .map(|x| (x.delay_ms, x.force_error_vs_ideal_rms_n))
                .collect();
            c.draw_series(LineSeries::new(pts.clone(), col.stroke_width(2)))
                .map_err(err)?
                .label(m.name())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2))
                });
            c.draw_series(pts.into_iter().map(|p| Circle::new(p, 4, col.filled())))
                .map_err(err)?;
            c.draw_series(
                mine(false).map(|x| Cross::new((x.delay_ms, x.force_error_vs_ideal_rms_n), 4, col)),
            )
            .map_err(err)?;
        }
        c.configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}
