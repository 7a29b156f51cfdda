//! Frames per second of the headless renderers (GPU and software), readback included, and the
//! showcase PNG.
//!
//! ```sh
//! cargo run --release -p render --example bench -- --points 10000,100000,1000000 --frames 10
//! cargo run --release -p render --example bench -- --backend software --cull
//! cargo run --release -p render --example bench -- --png docs/plots/render_sphere.png --frames 0
//! ```
//!
//! Each size renders a sphere of splats with every overlay (probe, cursor, box, force arrow),
//! 3 warm-up frames, then `--frames` timed `render_into` calls (GPU: draw + submit + wait +
//! readback into a reused image; software: the whole frame on the CPU); prints the median
//! frame time, its p10–p90 spread and frames/s, on each `--backend` (`gpu`, `software` or
//! `both`), with both sides of the surface drawn (the default) and, with `--cull`, also with
//! back-facing splats culled.

use std::{f32::consts::PI, time::Instant};

use render::{BackendChoice, Camera, Ellipsoid, HeadlessRenderer, Image, Overlay, Splat, Style};

struct Args {
    points: Vec<usize>,
    frames: usize,
    width: u32,
    height: u32,
    png: Option<String>,
    backends: Vec<BackendChoice>,
    cull: bool,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        points: vec![10_000, 100_000, 1_000_000],
        frames: 10,
        width: 1280,
        height: 720,
        png: None,
        backends: vec![BackendChoice::Gpu, BackendChoice::Software],
        cull: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        let num = |s: String| s.parse::<usize>().map_err(|e| format!("{flag} {s}: {e}"));
        match flag.as_str() {
            "--points" => {
                args.points = value()?
                    .split(',')
                    .map(|s| num(s.to_string()))
                    .collect::<Result<_, _>>()?
            }
            "--frames" => args.frames = num(value()?)?,
            "--width" => args.width = num(value()?)? as u32,
            "--height" => args.height = num(value()?)? as u32,
            "--png" => args.png = Some(value()?),
            "--cull" => args.cull = true,
            "--backend" => {
                args.backends = match value()?.as_str() {
                    "both" => vec![BackendChoice::Gpu, BackendChoice::Software],
                    other => vec![other.parse().map_err(|e| format!("--backend: {e}"))?],
                }
            }
            "--help" | "-h" => {
                return Err(
                    "usage: bench [--points N,N..] [--frames N] [--width W] [--height H] \
                            [--png PATH] [--backend gpu|software|both] [--cull]"
                        .into(),
                );
            }
            other => return Err(format!("unknown argument {other} (see --help)")),
        }
    }
    Ok(args)
}

const RADIUS: f32 = 0.05;

/// `n` points on a sphere of radius [`RADIUS`] (a Fibonacci lattice: near-uniform spacing), with
/// outward normals, disks sized from the mean spacing, clay-coloured with a painted spiral stroke.
fn sphere_splats(n: usize) -> Vec<Splat> {
    let spacing = (4.0 * PI * RADIUS * RADIUS / n as f32).sqrt();
    let golden = PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f32;
            let normal = [r * phi.cos(), z, r * phi.sin()];
            let lon = normal[2].atan2(normal[0]);
            // A painted band winding twice around the sphere.
            let stroke = (normal[1] - 0.35 * (2.0 * lon).sin()).abs() < 0.12;
            let shade = 0.9 + 0.1 * (9.0 * lon).sin() * r;
            let clay = [214.0, 150.0, 112.0].map(|c: f32| (c * shade) as u8);
            let color = if stroke {
                [40, 150, 170, 255]
            } else {
                [clay[0], clay[1], clay[2], 255]
            };
            Splat::disk(normal.map(|c| c * RADIUS), normal, 0.8 * spacing, color)
        })
        .collect()
}

/// The sculpting scene around the sphere: a probe (tilted) resting on it with the cursor at its
/// centre, the region box around the contact and the contact force from the cursor.
fn scene() -> (Overlay, Camera) {
    use glam::{Quat, Vec3};
    let normal = Vec3::new(-0.72, 0.5, 0.48).normalize();
    let contact = normal * RADIUS;
    let semi = [0.005, 0.007, 0.012];
    let tilt = Quat::from_axis_angle(normal.any_orthonormal_vector(), 0.5);
    let rotation = tilt * Quat::from_rotation_arc(Vec3::Z, normal);
    let center = contact + normal * 0.011;
    let half = Vec3::splat(0.02);
    let overlay = Overlay {
        probe: Some(Ellipsoid {
            center: center.into(),
            rotation: rotation.to_array(),
            semi_axes: semi,
        }),
        cursor: Some(center.into()),
        region: Some(((contact - half).into(), (contact + half).into())),
        force: Some((center.into(), (normal * 0.035).into())),
        ..Default::default()
    };
    let camera = Camera::framing([-RADIUS; 3], [RADIUS; 3], [0.25, -0.2, -1.0]);
    (overlay, camera)
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

fn run(args: &Args) -> Result<(), Box<dyn std::error::Error>> {
    let (overlay, camera) = scene();
    println!("target: {}x{}, readback included", args.width, args.height);
    for &choice in &args.backends {
        let mut renderer = HeadlessRenderer::new(args.width, args.height, choice)?;
        println!("backend: {}", renderer.describe());
        if let Some(path) = &args.png {
            let image = renderer.render(&sphere_splats(10_000), &overlay, &camera)?;
            image.save_png(path)?;
            println!("wrote {path} (10,000 splats)");
        }
        if args.frames == 0 {
            continue;
        }
        println!(
            "{:>9}  {:>10}  {:>10}  {:>17}  {:>8}",
            "points", "splats", "median ms", "p10-p90 ms", "frames/s"
        );
        let mut image = Image::default();
        for &n in &args.points {
            let splats = sphere_splats(n);
            let culls: &[bool] = if args.cull { &[false, true] } else { &[false] };
            for &cull in culls {
                renderer.set_style(Style {
                    cull_back_facing: cull,
                    ..Style::default()
                });
                for _ in 0..3 {
                    renderer.render_into(&splats, &overlay, &camera, &mut image)?;
                }
                let mut times = Vec::with_capacity(args.frames);
                for _ in 0..args.frames {
                    let t = Instant::now();
                    renderer.render_into(&splats, &overlay, &camera, &mut image)?;
                    times.push(t.elapsed().as_secs_f64() * 1e3);
                }
                times.sort_by(f64::total_cmp);
                let median = percentile(&times, 0.5);
                println!(
                    "{n:>9}  {:>10}  {median:>10.2}  {:>8.2}-{:<8.2}  {:>8.1}",
                    if cull { "front only" } else { "both sides" },
                    percentile(&times, 0.1),
                    percentile(&times, 0.9),
                    1e3 / median
                );
            }
        }
    }
    Ok(())
}

fn main() -> std::process::ExitCode {
    let result = parse_args().map_err(Into::into).and_then(|args| run(&args));
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("bench: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
