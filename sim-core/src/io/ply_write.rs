//! PLY writers: points (double positions, float normals, uchar colours) in binary
//! little-endian or ASCII, and meshes in binary little-endian.

use std::io::Write;

use super::IoError;
use crate::mesh::TriMesh;
use crate::pointset::PointSet;

/// Write points as binary little-endian PLY: `double x y z`, `float nx ny nz` and
/// `uchar red green blue` when present. `ascii` writes the same as text.
pub fn write_points_ply(mut w: impl Write, points: &PointSet, ascii: bool) -> Result<(), IoError> {
    let enc = if ascii {
        "ascii"
    } else {
        "binary_little_endian"
    };
    writeln!(
        w,
        "ply\nformat {enc} 1.0\ncomment written by sim-core\nelement vertex {}",
        points.len()
    )?;
    writeln!(w, "property double x\nproperty double y\nproperty double z")?;
    if points.normals.is_some() {
        writeln!(w, "property float nx\nproperty float ny\nproperty float nz")?;
    }
    if points.colors.is_some() {
        writeln!(
            w,
            "property uchar red\nproperty uchar green\nproperty uchar blue"
        )?;
    }
    writeln!(w, "end_header")?;
    for (i, p) in points.positions.iter().enumerate() {
        let n = points.normals.as_ref().map(|n| n[i].as_vec3());
        let c = points.colors.as_ref().map(|c| c[i]);
        if ascii {
            write!(w, "{} {} {}", p.x, p.y, p.z)?;
            if let Some(n) = n {
                write!(w, " {} {} {}", n.x, n.y, n.z)?;
            }
            if let Some(c) = c {
                write!(w, " {} {} {}", c[0], c[1], c[2])?;
            }
            writeln!(w)?;
        } else {
            for v in p.to_array() {
                w.write_all(&v.to_le_bytes())?;
            }
            if let Some(n) = n {
                for v in n.to_array() {
                    w.write_all(&v.to_le_bytes())?;
                }
            }
            if let Some(c) = c {
                w.write_all(&c)?;
            }
        }
    }
    Ok(())
}

/// Write a mesh as binary little-endian PLY (float positions and normals, int index lists).
pub fn write_mesh_ply(mut w: impl Write, mesh: &TriMesh) -> Result<(), IoError> {
    let has_n = mesh.normals.len() == mesh.vertices.len() && !mesh.vertices.is_empty();
    writeln!(
        w,
        "ply\nformat binary_little_endian 1.0\ncomment written by sim-core"
    )?;
    writeln!(
        w,
        "element vertex {}\nproperty float x\nproperty float y\nproperty float z",
        mesh.vertices.len()
    )?;
    if has_n {
        writeln!(w, "property float nx\nproperty float ny\nproperty float nz")?;
    }
    writeln!(
        w,
        "element face {}\nproperty list uchar int vertex_indices\nend_header",
        mesh.triangles.len()
    )?;
    let mut buf = Vec::with_capacity(mesh.vertices.len() * 24 + mesh.triangles.len() * 13);
    for (i, v) in mesh.vertices.iter().enumerate() {
        for x in v.as_vec3().to_array() {
            buf.extend_from_slice(&x.to_le_bytes());
        }
        if has_n {
            for x in mesh.normals[i].as_vec3().to_array() {
                buf.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    for t in &mesh.triangles {
        buf.push(3);
        for i in t {
            buf.extend_from_slice(&(*i as i32).to_le_bytes());
        }
    }
    w.write_all(&buf)?;
    Ok(())
}
