//! Speed against error for docs/BENCHMARKS.md: fit spheres and tori of 1k–200k points for several
//! `(k, size)` choices; report construction time (wall, with min–max over repeats, and CPU time
//! summed over threads) beside the zero-set RMS and max error of 10,000 projected points.
//!
//! `cargo run --release -p sim-core --example fit_sweep -- [--quick] [--out docs/plots]`
//! writes `fit_sweep.csv` and `construction_speed_vs_error.png` into the output folder and
//! prints a Markdown table. Plots need a TrueType font: DejaVuSans (Debian `fonts-dejavu-core`),
//! or set `PLOT_FONT=/path/to/font.ttf`.

use std::fmt::Write as _;
use std::time::Instant;

use plotters::prelude::*;

#[path = "../tests/support/plot_setup.rs"]
mod plot_setup;
use sim_core::accuracy::zero_set_error;
use sim_core::reconstruct::{IgnoreStages, NormalPolicy, reconstruct};
use sim_core::sampling::Shape;
use sim_core::{FitParams, NoProgress};

/// CPU time of this process so far (all threads), from `/proc/self/task/*/schedstat`, in seconds.
fn cpu_seconds() -> f64 {
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
        return f64::NAN;
    };
    tasks
        .filter_map(|t| std::fs::read_to_string(t.ok()?.path().join("schedstat")).ok())
        .filter_map(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .sum::<f64>()
        * 1e-9
}

struct Row {
    shape: &'static str,
    n: usize,
    k: usize,
    size: usize,
    wall: [f64; 3], // median, min, max
    cpu: f64,
    rms: f64,
    max: f64,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let quick = args.iter().any(|a| a == "--quick");
    let out = args
        .iter()
        .position(|a| a == "--out")
        .and_then(|i| args.get(i + 1))
        .map_or("docs/plots", String::as_str);
    std::fs::create_dir_all(out)?;
    let shapes = [
        ("sphere", Shape::Sphere { radius: 1.0 }),
        (
            "torus",
            Shape::Torus {
                major: 1.0,
                minor: 0.4,
            },
        ),
    ];
    let sizes: &[usize] = if quick {
        &[1000, 10_000]
    } else {
        &[1000, 10_000, 67_038, 200_000]
    };
    let configs = [(12, 3), (20, 3), (30, 3), (30, 4)];
    let load = || std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    let load_before = load();
    let mut rows = Vec::new();
    for (name, shape) in shapes {
        for &n in sizes {
            let points = shape.sample(n, 1);
            for (k, size) in configs {
                let params = FitParams {
                    k,
                    size,
                    ..FitParams::default()
                };
                let reps = match n {
                    0..=10_000 => 7,
                    10_001..=70_000 => 5,
                    _ => 3,
                };
                let mut walls = Vec::new();
                let mut cpu = 0.0;
                let mut field = None;
                for _ in 0..reps {
                    let (c0, t0) = (cpu_seconds(), Instant::now());
                    let rec = reconstruct(
                        &points,
                        &params,
                        NormalPolicy::Keep,
                        &mut IgnoreStages,
                        &NoProgress,
                    )?;
                    walls.push(t0.elapsed().as_secs_f64());
                    cpu += cpu_seconds() - c0;
                    field = Some(rec.field);
                }
                walls.sort_by(f64::total_cmp);
                let field = field.expect("at least one repeat");
                let e = zero_set_error(&field, &shape, 10_000, 0.5, 7);
                let row = Row {
                    shape: name,
                    n,
                    k,
                    size,
                    wall: [walls[walls.len() / 2], walls[0], walls[walls.len() - 1]],
                    cpu: cpu / reps as f64,
                    rms: e.rms_relative(),
                    max: e.max_relative(),
                };
                eprintln!(
                    "{name} n={n} k={k} size={size}: {:.4} s ({:.4}–{:.4}), cpu {:.4} s, rms {:.2e}, max {:.2e}",
                    row.wall[0], row.wall[1], row.wall[2], row.cpu, row.rms, row.max
                );
                rows.push(row);
            }
        }
    }
    let mut csv = String::from(
        "shape,points,k,size,wall_median_s,wall_min_s,wall_max_s,cpu_s,rms_rel,max_rel\n",
    );
    let mut md = String::from(
        "| shape | points | k | size | construction s (median, min–max) | CPU s | RMS / size | max / size |\n|---|---:|---:|---:|---|---:|---:|---:|\n",
    );
    for r in &rows {
        writeln!(
            csv,
            "{},{},{},{},{:.6},{:.6},{:.6},{:.6},{:.3e},{:.3e}",
            r.shape, r.n, r.k, r.size, r.wall[0], r.wall[1], r.wall[2], r.cpu, r.rms, r.max
        )?;
        writeln!(
            md,
            "| {} | {} | {} | {}³ | {:.4} ({:.4}–{:.4}) | {:.4} | {:.1e} | {:.1e} |",
            r.shape, r.n, r.k, r.size, r.wall[0], r.wall[1], r.wall[2], r.cpu, r.rms, r.max
        )?;
    }
    std::fs::write(format!("{out}/fit_sweep.csv"), csv)?;
    println!("{md}");
    println!(
        "load average (1, 5, 15 min) before: {}after: {}",
        load_before,
        load()
    );
    plot(&rows, &format!("{out}/construction_speed_vs_error.png"))?;
    Ok(())
}

fn plot(rows: &[Row], path: &str) -> Result<(), Box<dyn std::error::Error>> {
    plot_setup::register_font()?;
    let root = BitMapBackend::new(path, (1400, 600)).into_drawing_area();
    root.fill(&WHITE)?;
    let panels = root.split_evenly((1, 2));
    let t_range = rows
        .iter()
        .map(|r| r.cpu)
        .fold((f64::MAX, 0.0f64), |(lo, hi), t| (lo.min(t), hi.max(t)));
    for (panel, (metric, label)) in panels
        .iter()
        .zip([(0, "RMS error / size"), (1, "max error / size")])
    {
        let value = |r: &Row| if metric == 0 { r.rms } else { r.max };
        let (lo, hi) = rows
            .iter()
            .map(value)
            .fold((f64::MAX, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
        let mut chart = ChartBuilder::on(panel)
            .caption(
                format!("{label} vs construction CPU time"),
                ("sans-serif", 22),
            )
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(
                (t_range.0 * 0.7..t_range.1 * 1.5).log_scale(),
                (lo * 0.5..hi * 2.0).log_scale(),
            )?;
        chart
            .configure_mesh()
            .x_desc(
                "construction CPU time, s (all threads; about 2x the wall time on 2 idle cores)",
            )
            .y_desc(label)
            .x_label_formatter(&|x| format!("{x:.3}"))
            .y_label_formatter(&|y| format!("{y:.0e}"))
            .draw()?;
        let mut series = 0;
        for shape in ["sphere", "torus"] {
            for (k, size) in [(12, 3), (20, 3), (30, 3), (30, 4)] {
                let pts: Vec<(f64, f64)> = rows
                    .iter()
                    .filter(|r| r.shape == shape && r.k == k && r.size == size)
                    .map(|r| (r.cpu, value(r)))
                    .collect();
                let color = Palette99::pick(series).to_rgba();
                series += 1;
                let dashed = shape == "torus";
                chart
                    .draw_series(LineSeries::new(
                        pts.clone(),
                        color.stroke_width(if dashed { 1 } else { 2 }),
                    ))?
                    .label(format!("{shape} k={k} {size}³"))
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                    });
                if dashed {
                    chart.draw_series(
                        pts.iter()
                            .map(|&p| TriangleMarker::new(p, 5, color.filled())),
                    )?;
                } else {
                    chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
                }
            }
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .label_font(("sans-serif", 13))
            .draw()?;
    }
    root.present()?;
    Ok(())
}
