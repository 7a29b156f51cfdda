//! The figures of docs/BENCHMARKS.md § Haptic rendering. Ignored by default (they write files):
//! `cargo test --release -p sim-core --test haptics -- --ignored plots`. Font: DejaVu Sans or
//! `PLOT_FONT=/path/to/font.ttf`.

use glam::DVec3;
use plotters::prelude::*;
use sim_core::bspline_surface::{BicubicPatch, MeshParams, ProbeSculptor};
use sim_core::haptic::fixtures::{AnalyticField, force_errors};
use sim_core::probe::fixtures::{edge, fig4_force, sheet, thin_wall};
use sim_core::probe::{
    ContactParams, DirectionMethod, MagnitudeMethod, Probe, ProbePose, ProbeRenderer, SampleGrid,
};

use crate::plot_setup::{docs_plot, register_font};

type Res = Result<(), Box<dyn std::error::Error>>;
/// One curve: legend, colour, points, drawn as dots (else a line).
type Series<'a> = (&'a str, RGBColor, Vec<(f64, f64)>, bool);

const R: f64 = 0.02;
const KS: f64 = 1.0e6;

fn renderer(method: DirectionMethod) -> ProbeRenderer {
    ProbeRenderer::new(
        ContactParams {
            surface_stiffness: KS,
            surface_damping: 0.0,
            method,
            magnitude: MagnitudeMethod::SpringSum,
        },
        8192,
    )
    .unwrap()
}

fn line_chart(
    path: &str,
    title: &str,
    x: (&str, f64, f64),
    y: (&str, f64, f64),
    series: &[Series<'_>],
) -> Res {
    let root = BitMapBackend::new(path, (900, 560)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(65)
        .build_cartesian_2d(x.1..x.2, y.1..y.2)?;
    chart.configure_mesh().x_desc(x.0).y_desc(y.0).draw()?;
    for (index, (name, color, pts, dots)) in series.iter().enumerate() {
        let c = *color;
        // Earlier curves drawn wider so coinciding later ones do not hide them.
        let width = 2 + 2 * (series.len() - 1 - index) as u32;
        if *dots {
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 3, c.filled())))?
                .label(*name)
                .legend(move |(x, y)| Circle::new((x + 10, y), 3, c.filled()));
        } else {
            chart
                .draw_series(LineSeries::new(pts.clone(), c.stroke_width(width)))?
                .label(*name)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2))
                });
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

#[test]
#[ignore = "writes docs/plots; run with --ignored"]
fn plots() -> Res {
    register_font().expect("plot font");
    // Seed 004 Fig. 4: force vs intrusion depth of a sphere probe through a sampled plane.
    let grid = SampleGrid::new(&sheet(1.2 * R, R / 50.0), R / 4.0)?;
    let mut r = renderer(DirectionMethod::SurfaceNormal);
    let (mut measured, mut exact) = (Vec::new(), Vec::new());
    for k in 0..=80 {
        let h = R - 2.0 * R * k as f64 / 80.0;
        let f = r.query(
            &Probe::sphere(R)?.posed(ProbePose::at(DVec3::new(0.0, 0.0, h)))?,
            &grid,
            DVec3::ZERO,
        );
        measured.push(((R - h) * 1e3, f.force.length()));
    }
    for k in 0..=400 {
        let h = R - 2.0 * R * k as f64 / 400.0;
        exact.push(((R - h) * 1e3, fig4_force(R, h, KS)));
    }
    let peak = fig4_force(R, 0.0, KS) * 1.1;
    line_chart(
        &docs_plot("haptics_fig4.png"),
        "Sphere probe (R = 20 mm) through a plane (seed 004 Fig. 4)",
        ("intrusion depth (mm)", 0.0, 40.0),
        ("force (N)", 0.0, peak),
        &[
            ("closed form", BLUE, exact, false),
            ("distributed springs, R/50 samples", RED, measured, true),
        ],
    )?;

    // Continuity: through a sheet and a 2 mm wall (F_z), across an edge (force angle from +z),
    // for each direction method with the seed's spring sum (solid colours) and the vector sum.
    let sheet_grid = SampleGrid::new(&sheet(1.5 * R, R / 25.0), R / 3.0)?;
    let wall_grid = SampleGrid::new(&thin_wall(1.5 * R, R / 25.0, 0.002), R / 3.0)?;
    let edge_grid = SampleGrid::new(&edge(3.0 * R, R / 25.0), R / 3.0)?;
    let (mut through, mut wall, mut across) = (Vec::new(), Vec::new(), Vec::new());
    let combos = [
        (
            "surface normal",
            DirectionMethod::SurfaceNormal,
            MagnitudeMethod::SpringSum,
            BLUE,
        ),
        (
            "probe normal",
            DirectionMethod::ProbeNormal,
            MagnitudeMethod::SpringSum,
            RED,
        ),
        (
            "surface normal, vector sum",
            DirectionMethod::SurfaceNormal,
            MagnitudeMethod::VectorSum,
            CYAN,
        ),
        (
            "probe normal, vector sum",
            DirectionMethod::ProbeNormal,
            MagnitudeMethod::VectorSum,
            MAGENTA,
        ),
    ];
    for (name, m, magnitude, color) in combos {
        let mut rr = renderer(m);
        rr.set_params(ContactParams {
            magnitude,
            ..*rr.params()
        })?;
        let (mut a, mut w, mut b) = (Vec::new(), Vec::new(), Vec::new());
        let at =
            |x: f64, y: f64, z: f64| Probe::sphere(R)?.posed(ProbePose::at(DVec3::new(x, y, z)));
        for k in 0..=440 {
            let z = 1.1 * R - 2.2 * R * k as f64 / 440.0;
            a.push((
                z * 1e3,
                rr.query(&at(0.003, 0.002, z)?, &sheet_grid, DVec3::ZERO)
                    .force
                    .z,
            ));
            let zw = z - 0.001 * (k as f64 / 440.0) * 2.0;
            w.push((
                zw * 1e3,
                rr.query(&at(0.003, 0.002, zw)?, &wall_grid, DVec3::ZERO)
                    .force
                    .z,
            ));
        }
        for k in 0..=540 {
            let x = -1.5 * R + 2.7 * R * k as f64 / 540.0;
            let f = rr
                .query(&at(x, 0.0, 0.9 * R)?, &edge_grid, DVec3::ZERO)
                .force;
            if f.length() > 0.0 {
                b.push((x * 1e3, f.x.atan2(f.z).to_degrees()));
            }
        }
        through.push((name, color, a, false));
        wall.push((name, color, w, false));
        if magnitude == MagnitudeMethod::SpringSum {
            // The direction does not depend on the magnitude method.
            across.push((name, color, b, false));
        }
    }
    let fmax = peak;
    line_chart(
        &docs_plot("haptics_through_sheet.png"),
        "Probe centre passing through a sheet: normal force",
        ("probe centre height above the sheet (mm)", -22.0, 22.0),
        ("F_z (N)", -fmax, fmax),
        &through,
    )?;
    line_chart(
        &docs_plot("haptics_thin_wall.png"),
        "Probe centre passing through a 2 mm two-faced wall: normal force",
        ("probe centre height above the front face (mm)", -24.0, 22.0),
        ("F_z (N)", -2.0 * fmax, 2.0 * fmax),
        &wall,
    )?;
    line_chart(
        &docs_plot("haptics_edge.png"),
        "Probe sliding over a 90° edge (2 mm deep): force direction",
        ("probe centre x (edge at 0, mm)", -30.0, 24.0),
        ("angle of F from +z toward +x (°)", -5.0, 95.0),
        &across,
    )?;

    // Field-force convergence.
    let params = sim_core::haptic::FieldContactParams {
        stiffness: 500.0,
        damping: 0.0,
        friction: 0.0,
        max_search: R,
        approach_margin: 0.0,
        validity_radius: 0.002,
        lifetime_s: 0.05,
    };
    let mut conv = Vec::new();
    for (field, color) in [
        (AnalyticField::Sphere { size: R }, BLUE),
        (AnalyticField::Torus { size: R }, RED),
    ] {
        let pts: Vec<(f64, f64)> = [5.0, 10.0, 20.0, 40.0]
            .iter()
            .map(|c: &f64| {
                (
                    (1.0 / c).log10(),
                    force_errors(&field, &field.grid(R / c), &params, 500, 3, (0.1, 0.3))
                        .rel_vector
                        .log10(),
                )
            })
            .collect();
        conv.push((field.name(), color, pts, false));
    }
    conv.push(("slope 2", BLACK, vec![(-1.6, -3.6), (-0.7, -1.8)], false));
    line_chart(
        &docs_plot("haptics_convergence.png"),
        "Field force: max relative error vs grid spacing (depth 0.1–0.3 R)",
        ("log10(h / R)", -1.7, -0.6),
        ("log10(max |F − F_ref| / |F_ref|)", -4.0, -0.5),
        &conv,
    )?;

    // B-spline dual: bulge profile of a light and a 100× heavier mesh after the same press.
    let mut prof = Vec::new();
    for (name, mass, color) in [("light (0.01 kg)", 0.01, RED), ("heavy (1 kg)", 1.0, BLUE)] {
        let mesh = MeshParams {
            total_mass: mass,
            ..MeshParams::REFERENCE
        };
        let contact = ContactParams {
            surface_stiffness: 5.0e6,
            surface_damping: 0.0,
            method: DirectionMethod::SurfaceNormal,
            magnitude: MagnitudeMethod::SpringSum,
        };
        let n = 31;
        let mut s = ProbeSculptor::new(BicubicPatch::flat(n, 0.05)?, mesh, contact, 0.005, 0.01)?;
        let mut probe = Probe::sphere(0.008)?;
        for t in 0..150 {
            let z = 0.010 - 0.008 * (t as f64 / 50.0).min(1.0);
            probe.set_pose(ProbePose::at(DVec3::new(0.0, 0.0, z)))?;
            s.tick(&probe, DVec3::ZERO, true, 0.001)?;
        }
        let pts = (0..n)
            .map(|i| {
                let p = s.mesh().positions()[i * n + n / 2];
                (p.x * 1e3, p.z * 1e3)
            })
            .collect();
        prof.push((name, color, pts, false));
    }
    line_chart(
        &docs_plot("haptics_bspline_locality.png"),
        "31×31 dual pressed 6 mm by an 8 mm sphere for 150 ms",
        ("x along the centre row (mm)", -50.0, 50.0),
        ("z (mm)", -7.0, 1.0),
        &prof,
    )?;

    // Sculpting reaction: direct (−Σ tool forces) vs Hua–Qin (Σ s_j F_int,j) over a press.
    let mesh = MeshParams::REFERENCE;
    let contact = ContactParams {
        surface_stiffness: 5.0e6,
        surface_damping: 1.5e4,
        method: DirectionMethod::SurfaceNormal,
        magnitude: MagnitudeMethod::SpringSum,
    };
    let mut s = ProbeSculptor::new(BicubicPatch::flat(21, 0.05)?, mesh, contact, 0.005, 0.01)?;
    let mut probe = Probe::sphere(0.008)?;
    let (mut direct, mut hq) = (Vec::new(), Vec::new());
    for t in 0..500 {
        let z = 0.008 - 0.006 * (t as f64 / 100.0).min(1.0);
        probe.set_pose(ProbePose::at(DVec3::new(0.0, 0.0, z)))?;
        let tick = s.tick(&probe, DVec3::ZERO, t < 400, 0.001)?;
        if t < 400 {
            direct.push((t as f64, tick.output.force.z * 1e3));
            hq.push((t as f64, tick.hua_qin.z * 1e3));
        }
    }
    let top = direct.iter().chain(&hq).fold(0.0f64, |m, p| m.max(p.1)) * 1.1;
    line_chart(
        &docs_plot("haptics_reaction.png"),
        "Pressing a 21×21 dual 6 mm (contact damping 1.5e4 N·s/m³): felt reaction (z)",
        ("time (ms; press ramps 0–100, holds to 400)", 0.0, 400.0),
        ("force (mN)", 0.0, top),
        &[
            ("direct: −Σ tool forces", BLUE, direct, false),
            ("Hua–Qin: Σ s_j F_int,j", RED, hq, false),
        ],
    )?;
    Ok(())
}
