//! The panel's live plots: the last seconds of loop rates, round trip, force and step time,
//! sampled once per window frame (so the force trace shows what the display rate can: the
//! force loop itself runs at 1 kHz; its rate is the first plot).

use std::collections::VecDeque;

use eframe::egui;
use egui_plot::{Legend, Line, Plot, PlotPoints};

/// One sample of the session's statistics.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Sample {
    /// Seconds since the window opened.
    pub t: f64,
    /// Force-mapping loop rate (Hz).
    pub force_hz: f64,
    /// The server's servo loop rate (Hz; 0 without a server).
    pub servo_hz: f64,
    /// Cursor → force round trip p50 measured by the server (µs).
    pub rtt_us: f64,
    /// Force sent to the device (N).
    pub force_n: f64,
    /// Simulation step p50 (µs).
    pub step_us: f64,
    /// Simulation rate (Hz).
    pub sim_hz: f64,
}

/// The last `window_s` seconds of samples.
#[derive(Debug)]
pub struct History {
    window_s: f64,
    samples: VecDeque<Sample>,
}

impl History {
    /// Keep `window_s` seconds.
    pub fn new(window_s: f64) -> Self {
        Self {
            window_s,
            samples: VecDeque::new(),
        }
    }

    /// Add a sample; drop those older than the window.
    pub fn push(&mut self, s: Sample) {
        self.samples.push_back(s);
        while self
            .samples
            .front()
            .is_some_and(|f| s.t - f.t > self.window_s)
        {
            self.samples.pop_front();
        }
    }

    /// The samples, oldest first.
    pub fn samples(&self) -> impl Iterator<Item = &Sample> {
        self.samples.iter()
    }

    /// The newest sample.
    pub fn last(&self) -> Option<&Sample> {
        self.samples.back()
    }

    fn line(&self, name: &str, f: impl Fn(&Sample) -> f64) -> Line<'static> {
        let points: PlotPoints<'static> = self.samples.iter().map(|s| [s.t, f(s)]).collect();
        Line::new(name.to_owned(), points)
    }

    /// Draw the plots into `ui`.
    pub fn show(&self, ui: &mut egui::Ui) {
        let plot = |id: &str, unit: &str| {
            Plot::new(id.to_owned())
                .height(80.0)
                .legend(Legend::default())
                .allow_drag(false)
                .allow_zoom(false)
                .allow_scroll(false)
                .y_axis_label(unit.to_owned())
                .include_y(0.0)
        };
        plot("rates", "Hz").show(ui, |p| {
            p.line(self.line("force loop", |s| s.force_hz));
            p.line(self.line("servo", |s| s.servo_hz));
            p.line(self.line("simulation", |s| s.sim_hz));
        });
        plot("rtt", "µs").show(ui, |p| {
            p.line(self.line("round trip p50", |s| s.rtt_us));
            p.line(self.line("sim step p50", |s| s.step_us));
        });
        plot("force", "N").show(ui, |p| {
            p.line(self.line("|force|", |s| s.force_n));
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn history_keeps_only_its_window() {
        let mut h = History::new(10.0);
        for k in 0..=300 {
            h.push(Sample {
                t: k as f64 * 0.1,
                ..Sample::default()
            });
        }
        let first = h.samples().next().unwrap().t;
        assert!((first - 20.0).abs() < 1e-9, "{first}");
        assert_eq!(h.last().unwrap().t, 30.0);
    }
}
