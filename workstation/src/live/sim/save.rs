//! Saving the model: the visible objects' points and their meshed zero set.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use glam::DVec3;
use serde::Serialize;
use sim_core::io::{self, Format};
use sim_core::mesh::{TriMesh, extract_zero_set};

use super::SimCore;

/// What [`save`] wrote.
#[derive(Debug, Clone, Serialize)]
pub struct Saved {
    /// Points written.
    pub points: usize,
    /// Triangles of the meshed zero set.
    pub triangles: usize,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// Save the visible objects: `final.ply` (points, normals, colours) and the meshed zero set as
/// `final_mesh.ply`, `final_mesh.obj` and `final_mesh.stl`.
pub fn save(core: &SimCore, out: &Path, resolution: usize) -> anyhow::Result<Saved> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut points = sim_core::PointSet {
        positions: Vec::new(),
        normals: Some(Vec::new()),
        colors: Some(Vec::new()),
    };
    let mut mesh = TriMesh {
        vertices: Vec::new(),
        normals: Vec::new(),
        triangles: Vec::new(),
    };
    for o in core.visible() {
        points.positions.extend_from_slice(&o.positions);
        if let Some(n) = &mut points.normals {
            n.extend_from_slice(&o.normals);
        }
        if let Some(c) = &mut points.colors {
            c.extend_from_slice(&o.colors);
        }
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in &o.positions {
            (lo, hi) = (lo.min(*p), hi.max(*p));
        }
        let pad = DVec3::splat((hi - lo).max_element() * 0.05 + 1e-6);
        let mut m = extract_zero_set(&o.field, (lo - pad, hi + pad), resolution);
        crate::fit::cut_unsupported_pieces(&mut m, &o.positions);
        let base = mesh.vertices.len() as u32;
        mesh.vertices.extend_from_slice(&m.vertices);
        mesh.normals.extend_from_slice(&m.normals);
        mesh.triangles
            .extend(m.triangles.iter().map(|t| t.map(|i| i + base)));
    }
    let mut files = Vec::new();
    let ply = out.join("final.ply");
    let f = std::fs::File::create(&ply).with_context(|| format!("creating {}", ply.display()))?;
    io::write_points_ply(std::io::BufWriter::new(f), &points, false)?;
    files.push(ply);
    for (name, format) in [
        ("final_mesh.ply", Format::Ply),
        ("final_mesh.obj", Format::Obj),
        ("final_mesh.stl", Format::Stl),
    ] {
        let path = out.join(name);
        let f =
            std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?;
        io::write_mesh(std::io::BufWriter::new(f), &mesh, format)?;
        files.push(path);
    }
    Ok(Saved {
        points: points.positions.len(),
        triangles: mesh.triangles.len(),
        files,
    })
}
