//! The study's PNG plots (plotters, the embedded font).

use std::path::Path;

use plotters::prelude::*;

use super::report::{DelayStudyReport, RunRow};
use super::sim::{Method, Trace};

const SIZE: (u32, u32) = (900, 560);

pub(super) fn colour(m: Method) -> RGBColor {
    match m {
        Method::Zoh => RGBColor(214, 39, 40),
        Method::Ewma => RGBColor(255, 127, 14),
        Method::LocalModel => RGBColor(31, 119, 180),
        Method::LocalModelPassivity => RGBColor(44, 160, 44),
    }
}

pub(super) fn err(e: impl std::fmt::Display) -> anyhow::Error {
    anyhow::anyhow!("plot: {e}")
}

/// Every plot into `dir`.
pub fn all(dir: &Path, r: &DelayStudyReport, rows: &[(RunRow, Trace)]) -> anyhow::Result<()> {
    crate::plot::register_font().map_err(err)?;
    error_vs_delay(&dir.join("error_vs_delay.png"), r)?;
    energy_vs_delay(&dir.join("energy_vs_delay.png"), r)?;
    for d in [20.0, 100.0] {
        traces(&dir.join(format!("traces_{d}ms.png")), rows, d)?;
    }
    deadband(&dir.join("deadband.png"), r)?;
    Ok(())
}

fn no_loss(r: &DelayStudyReport, m: Method) -> Vec<(f64, &RunRow)> {
    r.runs
        .iter()
        .filter(|x| x.method == m && x.loss == 0.0)
        .map(|x| (x.delay_ms, x))
        .collect()
}

fn max_delay(r: &DelayStudyReport) -> f64 {
    r.runs.iter().map(|x| x.delay_ms).fold(1.0, f64::max)
}

fn error_vs_delay(path: &Path, r: &DelayStudyReport) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let mut c = ChartBuilder::on(&root)
        .caption(
            "RMS force error vs one-way delay (press and slide, no loss)",
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..max_delay(r) * 1.05, (1e-4..10.0).log_scale())
        .map_err(err)?;
    c.configure_mesh()
        .x_desc("one-way delay (ms), both directions")
        .y_desc("RMS |F − F(same method, 0 ms)| (N)")
        .draw()
        .map_err(err)?;
    for m in Method::ALL {
        let pts: Vec<(f64, f64)> = no_loss(r, m)
            .into_iter()
            .map(|(d, x)| (d, x.force_error_rms_n.max(1e-4)))
            .collect();
        let col = colour(m);
        c.draw_series(LineSeries::new(pts.clone(), col.stroke_width(2)))
            .map_err(err)?
            .label(m.name())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
        c.draw_series(pts.into_iter().map(|p| Circle::new(p, 4, col.filled())))
            .map_err(err)?;
    }
    c.configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

/// Signed log scale for energies spanning µJ to J: `sign · log10(1 + |E| / 1 µJ)`.
fn slog(e_j: f64) -> f64 {
    e_j.signum() * (1.0 + e_j.abs() / 1e-6).log10()
}

fn energy_vs_delay(path: &Path, r: &DelayStudyReport) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let mut c = ChartBuilder::on(&root)
        .caption(
            "Energy the device delivered to the hand (> 0: generated), no loss",
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..max_delay(r) * 1.05, slog(-1.0)..slog(1.0))
        .map_err(err)?;
    c.configure_mesh()
        .x_desc("one-way delay (ms), both directions")
        .y_desc("energy (signed log scale)")
        .y_label_formatter(&|v| {
            let e = v.signum() * (10f64.powf(v.abs()) - 1.0) * 1e-6;
            if e.abs() < 1e-6 {
                "0".into()
            } else if e.abs() >= 1e-3 {
                format!("{:.0} mJ", e * 1e3)
            } else {
                format!("{:.0} µJ", e * 1e6)
            }
        })
        .draw()
        .map_err(err)?;
    c.draw_series(LineSeries::new(
        [(0.0, slog(5e-4)), (max_delay(r) * 1.05, slog(5e-4))],
        BLACK.mix(0.5).stroke_width(1),
    ))
    .map_err(err)?
    .label("passive tolerance (0.5 mJ)")
    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.5)));
    for m in Method::ALL {
        let pts: Vec<(f64, f64)> = no_loss(r, m)
            .into_iter()
            .map(|(d, x)| (d, slog(x.energy_generated_j)))
            .collect();
        let col = colour(m);
        c.draw_series(LineSeries::new(pts.clone(), col.stroke_width(2)))
            .map_err(err)?
            .label(m.name())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
        c.draw_series(pts.into_iter().map(|p| Circle::new(p, 4, col.filled())))
            .map_err(err)?;
    }
    c.configure_series_labels()
        .position(SeriesLabelPosition::MiddleRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

fn traces(path: &Path, rows: &[(RunRow, Trace)], delay_ms: f64) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let pick = |m: Method, d: f64| {
        rows.iter()
            .find(|(r, _)| r.method == m && r.delay_ms == d && r.loss == 0.0)
            .map(|(_, t)| t)
    };
    let secs = rows
        .first()
        .map_or(1.0, |(_, t)| t.force.len() as f64 * 1e-3);
    let mut c = ChartBuilder::on(&root)
        .caption(
            format!("Normal force (y) at {delay_ms} ms one way, no loss"),
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..secs, -0.5..3.6)
        .map_err(err)?;
    c.configure_mesh()
        .x_desc("time (s): press 0.7–1.7, hold, slide 2.2–4.2, lift 4.5–5.0")
        .y_desc("force y (N)")
        .draw()
        .map_err(err)?;
    if let Some(ideal) = pick(Method::LocalModel, 0.0) {
        let pts = ideal
            .force
            .iter()
            .enumerate()
            .map(|(i, f)| (i as f64 * 1e-3, f64::from(f.y)));
        c.draw_series(LineSeries::new(pts, BLACK.stroke_width(3)))
            .map_err(err)?
            .label("local_model at 0 ms (ideal)")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(3)));
    }
    for m in Method::ALL {
        let Some(t) = pick(m, delay_ms) else {
            continue;
        };
        let col = colour(m);
        let pts = t
            .force
            .iter()
            .enumerate()
            .map(|(i, f)| (i as f64 * 1e-3, f64::from(f.y)));
        c.draw_series(LineSeries::new(pts, col.stroke_width(1)))
            .map_err(err)?
            .label(m.name())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
    }
    c.configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

fn deadband(path: &Path, r: &DelayStudyReport) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let emax = r
        .deadband_sweep
        .iter()
        .map(|s| s.relative_force_error * 100.0)
        .fold(12.0, f64::max)
        .min(100.0);
    let mut c = ChartBuilder::on(&root)
        .caption(
            "Deadband: packets sent vs force error (no loss)",
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..105.0, 0.0..emax * 1.15)
        .map_err(err)?;
    c.configure_mesh()
        .x_desc("packets sent, % of K = 0 (cursor + force streams)")
        .y_desc("RMS force error, % of RMS force")
        .draw()
        .map_err(err)?;
    c.draw_series(LineSeries::new(
        [(0.0, 10.0), (105.0, 10.0)],
        BLACK.mix(0.4).stroke_width(1),
    ))
    .map_err(err)?;
    c.draw_series(LineSeries::new(
        [(20.0, 0.0), (20.0, emax * 1.15)],
        BLACK.mix(0.4).stroke_width(1),
    ))
    .map_err(err)?;
    for (m, d) in [(Method::LocalModel, 20.0), (Method::Zoh, 0.0)] {
        let rows: Vec<_> = r
            .deadband_sweep
            .iter()
            .filter(|s| s.method == m && s.delay_ms == d)
            .collect();
        let base = rows.first().map_or(1.0, |s| s.packets_sent.max(1) as f64);
        let pts: Vec<(f64, f64, f64)> = rows
            .iter()
            .map(|s| {
                (
                    s.packets_sent as f64 / base * 100.0,
                    (s.relative_force_error * 100.0).min(emax * 1.1),
                    s.deadband,
                )
            })
            .collect();
        let col = colour(m);
        c.draw_series(LineSeries::new(
            pts.iter().map(|p| (p.0, p.1)),
            col.stroke_width(2),
        ))
        .map_err(err)?
        .label(format!("{} at {d} ms one way", m.name()))
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
        c.draw_series(pts.iter().map(|&(x, y, k)| {
            EmptyElement::at((x, y))
                + Circle::new((0, 0), 5, col.filled())
                + Text::new(format!("K = {k}"), (8, -14), ("sans-serif", 15))
        }))
        .map_err(err)?;
    }
    c.configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}
