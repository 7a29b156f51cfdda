//! The latency report's two PNG plots: the round-trip distributions (ours and the bare
//! ping-pong's, as fractions of their samples) and the round trip of every kept command over
//! time against the ping-pong's median. The plot font must be registered first
//! ([`crate::plot::register_font`]).

use std::path::Path;

use plotters::prelude::*;

use super::Measured;
use super::baseline::PingPong;
use super::report::Report;

/// The round-trip histogram of ours against the bare ping-pong, up to 1.2 × their p99.9.
pub fn histogram(path: &Path, m: &Measured, base: &PingPong) -> anyhow::Result<()> {
    let ours: Vec<f64> = m.samples.iter().map(|s| s.rtt_ns as f64 / 1e3).collect();
    let bare: Vec<f64> = base.rtt_ns.iter().map(|&r| r as f64 / 1e3).collect();
    let all_p999 = {
        let mut v: Vec<f64> = ours.iter().chain(&bare).copied().collect();
        v.sort_by(f64::total_cmp);
        v.get((v.len() as f64 * 0.999) as usize)
            .copied()
            .unwrap_or(1.0)
    };
    let hi = (all_p999 * 1.2).max(1.0);
    const BINS: usize = 120;
    let bins = |v: &[f64]| {
        let mut c = vec![0f64; BINS];
        for &x in v {
            if x < hi {
                c[((x / hi) * BINS as f64) as usize] += 1.0;
            }
        }
        let n = v.len().max(1) as f64;
        c.iter_mut().for_each(|x| *x /= n);
        c
    };
    let (co, cb) = (bins(&ours), bins(&bare));
    let ymax = co.iter().chain(&cb).copied().fold(0.0, f64::max).max(1e-6) * 1.1;
    let root = BitMapBackend::new(path, (900, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Round trip: cursor-to-force (ours) vs bare UDP ping-pong, same run",
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..hi, 0.0..ymax)?;
    chart
        .configure_mesh()
        .x_desc("round trip, µs")
        .y_desc("fraction of samples")
        .draw()?;
    let w = hi / BINS as f64;
    for (counts, color, label) in [
        (&co, RED, "cursor-to-force (ours)"),
        (&cb, BLUE, "bare UDP ping-pong"),
    ] {
        let pts: Vec<(f64, f64)> = counts
            .iter()
            .enumerate()
            .flat_map(|(i, &c)| [(i as f64 * w, c), ((i + 1) as f64 * w, c)])
            .collect();
        chart
            .draw_series(LineSeries::new(pts, color.stroke_width(2)))?
            .label(label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

/// Every kept command's round trip over the phase, with the ping-pong's median.
pub fn over_time(path: &Path, m: &Measured, r: &Report) -> anyhow::Result<()> {
    let pts: Vec<(f64, f64)> = m
        .samples
        .iter()
        .map(|s| (s.t_ns as f64 / 1e9, s.rtt_ns as f64 / 1e3))
        .collect();
    let tmax = pts.last().map_or(1.0, |p| p.0).max(1e-3);
    // Up to 1.5 × the 99.9th percentile: the rare outliers above would flatten the rest.
    let ymax = (r.rtt_us.p999.max(r.baseline_udp_rtt_us.p99) * 1.5).max(1.0);
    let above = pts.iter().filter(|p| p.1 > ymax).count();
    let root = BitMapBackend::new(path, (900, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "Cursor-to-force round trip over time ({}; {above} of {} above the plot)",
                r.transport,
                pts.len()
            ),
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..tmax, 0.0..ymax)?;
    chart
        .configure_mesh()
        .x_desc("time, s")
        .y_desc("round trip, µs")
        .draw()?;
    chart
        .draw_series(
            pts.iter()
                .filter(|p| p.1 <= ymax)
                .map(|&(t, v)| Circle::new((t, v), 1, RED.mix(0.5).filled())),
        )?
        .label("cursor-to-force (ours), each command")
        .legend(|(x, y)| Circle::new((x + 10, y), 3, RED.filled()));
    let b = r.baseline_udp_rtt_us.p50;
    chart
        .draw_series(LineSeries::new([(0.0, b), (tmax, b)], BLUE.stroke_width(2)))?
        .label("bare UDP ping-pong p50")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLUE.stroke_width(2)));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}
