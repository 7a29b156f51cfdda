//! The figures of docs/BENCHMARKS.md § Dynamic sculpting. Ignored by default (they write files):
//! `cargo test --release -p sim-core --test dynamics -- --ignored plots`. Font: DejaVu Sans or
//! `PLOT_FONT=/path/to/font.ttf`.

use glam::DVec3;
use plotters::prelude::*;
use sim_core::dynamics::stability::predicted_limits;
use sim_core::dynamics::{Integrator, NodeParams, Stepper};
use sim_core::tools::Profile;

use crate::common::{perturb, small_model};
use crate::rope::{PEAK, R0, expected_height, pulled_sphere};

use crate::plot_setup::{docs_plot, register_font};

type Res = Result<(), Box<dyn std::error::Error>>;

#[test]
#[ignore = "writes docs/plots/sculpt_bump_profile.png"]
fn plots_bump_profile() -> Res {
    register_font().expect("plot font");
    let path = docs_plot("sculpt_bump_profile.png");
    let root = BitMapBackend::new(&path, (900, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Rope pull on a fitted sphere: point heights vs the profile",
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..0.2f64, -0.5..11.0f64)?;
    chart
        .configure_mesh()
        .x_desc("distance from the rope anchor (m)")
        .y_desc("surface raised (mm)")
        .draw()?;
    let c = DVec3::new(0.0, 0.0, R0);
    for (profile, colour, name) in [
        (Profile::Gaussian, BLUE, "Gaussian"),
        (Profile::Spherical, RED, "spherical"),
    ] {
        let (scene, before) = pulled_sphere(profile.clone());
        let after = &scene.objects()[0].positions;
        let dots: Vec<(f64, f64)> = before
            .iter()
            .zip(after)
            .filter(|(p0, _)| p0.distance(c) < 0.2)
            .map(|(p0, p1)| (p0.distance(c), (p1.length() - p0.length()) * 1e3))
            .collect();
        chart
            .draw_series(
                dots.iter()
                    .map(|&(x, y)| Circle::new((x, y), 2, colour.mix(0.5).filled())),
            )?
            .label(format!("{name}: points"))
            .legend(move |(x, y)| Circle::new((x, y), 3, colour.filled()));
        let line: Vec<(f64, f64)> = (0..200)
            .map(|k| {
                let d = 0.2 * k as f64 / 199.0;
                let a = 2.0 * (d / (2.0 * R0)).asin();
                let p = R0 * DVec3::new(a.sin(), 0.0, a.cos());
                (d, expected_height(&profile, p) * 1e3)
            })
            .collect();
        chart
            .draw_series(LineSeries::new(line, colour.stroke_width(2)))?
            .label(format!("{name}: profile × {:.0} mm", PEAK * 1e3))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

#[test]
#[ignore = "writes docs/plots/sculpt_energy.png"]
fn plots_energy_past_the_limit() -> Res {
    register_font().expect("plot font");
    let mut base = small_model(6, NodeParams::default());
    perturb(&mut base, 1e-3);
    let (fe_limit, se_limit) = predicted_limits(&base);
    let e0 = base.energy();
    let mut a = vec![0.0; base.active_len()];
    base.acceleration_into(&mut a);
    let a0 = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let dt = 10.0 * fe_limit;
    let runs = [
        (
            "forward Euler, halving at 2 max|a0|",
            Integrator::ForwardEuler {
                accel_threshold: 2.0 * a0,
                max_halvings: 10,
                relax_after: 1000,
            },
            BLUE,
        ),
        ("backward Euler (CG)", Integrator::backward_euler(), RED),
        (
            "symplectic Euler (no halving)",
            Integrator::SymplecticEuler,
            GREEN,
        ),
    ];
    let path = docs_plot("sculpt_energy.png");
    let root = BitMapBackend::new(&path, (900, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "Energy at Δt = 10× the explicit limit ({:.1} ms; symplectic limit {:.1} ms)",
                dt * 1e3,
                se_limit * 1e3
            ),
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(0..3000usize, (1e-20..1e4f64).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("step")
        .y_desc("E / E0 (clamped to [1e-20, 1e4])")
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .draw()?;
    for (name, integrator, colour) in runs {
        let mut m = base.clone();
        let mut st = Stepper::new(integrator);
        let mut series = Vec::new();
        for k in 0..3000 {
            if st.step(&mut m, dt).is_err() {
                break; // caught and rolled back: the curve ends here
            }
            series.push((k, (m.energy() / e0).clamp(1e-20, 1e4)));
        }
        chart
            .draw_series(LineSeries::new(series, colour.stroke_width(2)))?
            .label(name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}
