//! STL: binary and ASCII reading, binary writing.
//!
//! STL stores every triangle corner on its own: a vertex shared by six triangles comes six
//! times. Reading welds corners at exactly one position into one vertex (first occurrence
//! first), so the points are the surface's samples once each and the mesh is connected; read
//! unwelded, every point had five twins at distance 0, and its normal was one facet's.

use std::collections::HashMap;
use std::io::Write;

use glam::{DVec3, Vec3};

use super::{IoError, Loaded, parse_f64};
use crate::mesh::TriMesh;
use crate::pointset::{PointSet, position_key};

/// Parse binary or ASCII STL.
pub fn read_stl(bytes: &[u8]) -> Result<Loaded, IoError> {
    let binary_len = bytes
        .get(80..84)
        .map(|b| 84 + 50 * u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
    let mut vertices = Vec::new();
    if binary_len == Some(bytes.len()) {
        for (index, rec) in bytes[84..].chunks_exact(50).enumerate() {
            for k in 0..3 {
                let o = 12 + 12 * k;
                let f = |j: usize| {
                    f32::from_le_bytes(rec[o + 4 * j..o + 4 * j + 4].try_into().expect("4 bytes"))
                        as f64
                };
                let p = DVec3::new(f(0), f(1), f(2));
                if !p.is_finite() {
                    return Err(IoError::Record {
                        element: "triangle".into(),
                        index,
                        reason: "non-finite vertex".into(),
                    });
                }
                vertices.push(p);
            }
        }
    } else {
        let text = std::str::from_utf8(bytes).map_err(|_| IoError::Header {
            line: 1,
            reason: "neither binary STL (size mismatch) nor text".into(),
        })?;
        if !text.trim_start().starts_with("solid") {
            return Err(IoError::Header {
                line: 1,
                reason: "ASCII STL must start with `solid`".into(),
            });
        }
        for (i, l) in text.lines().enumerate() {
            let mut t = l.split_whitespace();
            if t.next() == Some("vertex") {
                let line = i + 1;
                vertices.push(DVec3::new(
                    parse_f64(t.next(), line, "x")?,
                    parse_f64(t.next(), line, "y")?,
                    parse_f64(t.next(), line, "z")?,
                ));
            }
        }
        if vertices.len() % 3 != 0 {
            return Err(IoError::Line {
                line: text.lines().count(),
                reason: "vertex count is not a multiple of 3".into(),
            });
        }
    }
    let mesh = weld(&vertices);
    Ok(Loaded {
        points: PointSet::from_positions(mesh.vertices.clone()),
        mesh: Some(mesh),
    })
}

/// The mesh of triangles `corners[3t..3t + 3]`, with corners at one position (bit for bit, +0
/// and −0 alike) made one vertex.
fn weld(corners: &[DVec3]) -> TriMesh {
    let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(corners.len() / 4);
    let mut vertices = Vec::new();
    let index: Vec<u32> = corners
        .iter()
        .map(|&p| {
            *first.entry(position_key(p)).or_insert_with(|| {
                vertices.push(p);
                vertices.len() as u32 - 1
            })
        })
        .collect();
    TriMesh {
        vertices,
        normals: Vec::new(),
        triangles: index.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
    }
}

/// Write a mesh as binary STL (facet normals from the winding).
pub fn write_stl(mut w: impl Write, mesh: &TriMesh) -> Result<(), IoError> {
    let mut header = [b' '; 80];
    header[..22].copy_from_slice(b"binary STL by sim-core");
    let mut buf = Vec::with_capacity(84 + 50 * mesh.triangles.len());
    buf.extend_from_slice(&header);
    buf.extend_from_slice(&(mesh.triangles.len() as u32).to_le_bytes());
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
        let n = (b - a).cross(c - a).try_normalize().unwrap_or(DVec3::ZERO);
        for v in [n, a, b, c] {
            let v: Vec3 = v.as_vec3();
            for x in v.to_array() {
                buf.extend_from_slice(&x.to_le_bytes());
            }
        }
        buf.extend_from_slice(&[0, 0]);
    }
    w.write_all(&buf)?;
    Ok(())
}
