//! Render a triangle mesh (PLY, OBJ, STL) to a PNG with a z-buffer and Lambert shading, to look
//! at `workstation fit --mesh` output without a viewer.
//!
//! `cargo run --release -p sim-core --example render_mesh -- IN OUT.png [yaw_deg] [pitch_deg]`

use glam::{DMat3, DVec3};
use plotters::prelude::*;
use sim_core::io::{self, Format};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().collect();
    let (input, output) = (
        a.get(1).ok_or("IN missing")?,
        a.get(2).ok_or("OUT missing")?,
    );
    let yaw = a
        .get(3)
        .and_then(|s| s.parse::<f64>().ok())
        .unwrap_or(30.0)
        .to_radians();
    let pitch = a
        .get(4)
        .and_then(|s| s.parse::<f64>().ok())
        .unwrap_or(-20.0)
        .to_radians();
    let ext = std::path::Path::new(input)
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("");
    let format = Format::from_extension(ext).ok_or("unknown extension")?;
    let mesh = io::read(std::fs::File::open(input)?, format)?
        .mesh
        .ok_or("no faces")?;
    let rot = DMat3::from_rotation_x(pitch) * DMat3::from_rotation_y(yaw);
    let v: Vec<DVec3> = mesh.vertices.iter().map(|p| rot * *p).collect();
    let (lo, hi) = sim_core::pointset::bounds(&v).ok_or("empty")?;
    let (w, h) = (800usize, 800usize);
    let scale = 0.9 * w.min(h) as f64 / (hi - lo).truncate().max_element();
    let centre = (lo + hi) * 0.5;
    let to_px = |p: DVec3| {
        let q = (p - centre) * scale;
        (q.x + w as f64 / 2.0, h as f64 / 2.0 - q.y, q.z)
    };
    let mut depth = vec![f64::NEG_INFINITY; w * h];
    let mut shade = vec![0u8; w * h];
    let light = DVec3::new(0.3, 0.5, 1.0).normalize();
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| v[i as usize]);
        let n = (b - a).cross(c - a).normalize_or_zero();
        let lum = (40.0 + 215.0 * n.dot(light).max(0.0)) as u8;
        let [pa, pb, pc] = [to_px(a), to_px(b), to_px(c)];
        let (x0, x1) = (
            pa.0.min(pb.0).min(pc.0).max(0.0) as usize,
            pa.0.max(pb.0).max(pc.0).min(w as f64 - 1.0) as usize,
        );
        let (y0, y1) = (
            pa.1.min(pb.1).min(pc.1).max(0.0) as usize,
            pa.1.max(pb.1).max(pc.1).min(h as f64 - 1.0) as usize,
        );
        let area = (pb.0 - pa.0) * (pc.1 - pa.1) - (pc.0 - pa.0) * (pb.1 - pa.1);
        if area.abs() < 1e-12 {
            continue;
        }
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let w0 = ((pb.0 - px) * (pc.1 - py) - (pc.0 - px) * (pb.1 - py)) / area;
                let w1 = ((pc.0 - px) * (pa.1 - py) - (pa.0 - px) * (pc.1 - py)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * pa.2 + w1 * pb.2 + w2 * pc.2;
                if z > depth[y * w + x] {
                    depth[y * w + x] = z;
                    shade[y * w + x] = lum;
                }
            }
        }
    }
    let root = BitMapBackend::new(output, (w as u32, h as u32)).into_drawing_area();
    root.fill(&WHITE)?;
    for y in 0..h {
        for x in 0..w {
            if depth[y * w + x] > f64::NEG_INFINITY {
                let s = shade[y * w + x];
                root.draw_pixel(
                    (x as i32, y as i32),
                    &RGBColor(s, s, (s as u16 * 9 / 10 + 20).min(255) as u8),
                )?;
            }
        }
    }
    root.present()?;
    Ok(())
}
