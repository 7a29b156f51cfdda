//! Text formats: OFF (with NOFF normals and COFF colours), OBJ (`v` with optional colours,
//! `vn`, `f`) and XYZ/PWN (`x y z` or `x y z nx ny nz` per line).

use std::io::Write;

use glam::DVec3;

use super::{IoError, Loaded, data_lines, parse_f64, push_polygon};
use crate::mesh::TriMesh;
use crate::pointset::PointSet;

fn utf8(bytes: &[u8]) -> Result<&str, IoError> {
    std::str::from_utf8(bytes).map_err(|e| IoError::Line {
        line: 0,
        reason: format!("not UTF-8 text: {e}"),
    })
}

fn vec3<'a>(
    t: &mut impl Iterator<Item = &'a str>,
    line: usize,
    what: [&str; 3],
) -> Result<DVec3, IoError> {
    Ok(DVec3::new(
        parse_f64(t.next(), line, what[0])?,
        parse_f64(t.next(), line, what[1])?,
        parse_f64(t.next(), line, what[2])?,
    ))
}

/// Parse `x y z` or `x y z nx ny nz` lines (`#` comments allowed).
pub fn read_xyz(bytes: &[u8]) -> Result<Loaded, IoError> {
    let mut pos = Vec::new();
    let mut nor = Vec::new();
    let mut with_normals = None;
    for (line, l) in data_lines(utf8(bytes)?) {
        let fields = l.split_whitespace().count();
        let has_n = fields >= 6;
        if fields != 3 && fields != 6 {
            return Err(IoError::Line {
                line,
                reason: format!("expected 3 or 6 numbers, found {fields}"),
            });
        }
        if *with_normals.get_or_insert(has_n) != has_n {
            return Err(IoError::Line {
                line,
                reason: "mixes lines with and without normals".into(),
            });
        }
        let mut t = l.split_whitespace();
        pos.push(vec3(&mut t, line, ["x", "y", "z"])?);
        if has_n {
            nor.push(vec3(&mut t, line, ["nx", "ny", "nz"])?);
        }
    }
    let normals = (with_normals == Some(true)).then_some(nor);
    Ok(Loaded {
        points: PointSet {
            positions: pos,
            normals,
            colors: None,
        },
        mesh: None,
    })
}

/// Parse OFF / NOFF / COFF / CNOFF.
pub fn read_off(bytes: &[u8]) -> Result<Loaded, IoError> {
    let mut lines = data_lines(utf8(bytes)?);
    let (hl, head) = lines.next().ok_or(IoError::Header {
        line: 1,
        reason: "empty file".into(),
    })?;
    let mut t = head.split_whitespace();
    let kw = t.next().unwrap_or("");
    if !kw.ends_with("OFF") {
        return Err(IoError::Header {
            line: hl,
            reason: format!("expected OFF, found {kw:?}"),
        });
    }
    let (has_c, has_n) = (kw.contains('C'), kw.contains('N'));
    // Counts may follow on the same line or on the next.
    let rest: Vec<&str> = t.collect();
    let (cl, counts) = if rest.is_empty() {
        let (l, s) = lines.next().ok_or(IoError::Header {
            line: hl + 1,
            reason: "missing counts".into(),
        })?;
        (l, s.split_whitespace().collect())
    } else {
        (hl, rest)
    };
    let count = |i: usize| -> Result<usize, IoError> {
        counts
            .get(i)
            .and_then(|c| c.parse().ok())
            .ok_or(IoError::Header {
                line: cl,
                reason: "vertex/face counts are not integers".into(),
            })
    };
    let (nv, nf) = (count(0)?, count(1)?);
    let (mut pos, mut nor, mut col) = (Vec::with_capacity(nv.min(1 << 20)), Vec::new(), Vec::new());
    for _ in 0..nv {
        let (line, l) = lines.next().ok_or(IoError::Line {
            line: 0,
            reason: format!("file ends before {nv} vertices"),
        })?;
        let mut t = l.split_whitespace();
        pos.push(vec3(&mut t, line, ["x", "y", "z"])?);
        if has_n {
            nor.push(vec3(&mut t, line, ["nx", "ny", "nz"])?);
        }
        if has_c {
            let c = vec3(&mut t, line, ["red", "green", "blue"])?;
            let scale = if c.max_element() <= 1.0 { 255.0 } else { 1.0 };
            col.push(
                (c * scale)
                    .round()
                    .clamp(DVec3::ZERO, DVec3::splat(255.0))
                    .to_array()
                    .map(|v| v as u8),
            );
        }
    }
    let mut tris = Vec::new();
    for _ in 0..nf {
        let Some((line, l)) = lines.next() else { break };
        let mut t = l.split_whitespace();
        let n: usize = t.next().and_then(|s| s.parse().ok()).ok_or(IoError::Line {
            line,
            reason: "face vertex count is not an integer".into(),
        })?;
        let poly: Option<Vec<u32>> = t.by_ref().take(n).map(|s| s.parse().ok()).collect();
        let poly = poly.filter(|p| p.len() == n).ok_or(IoError::Line {
            line,
            reason: format!("face needs {n} integer indices"),
        })?;
        push_polygon(&mut tris, &poly, nv, |reason| IoError::Line {
            line,
            reason,
        })?;
    }
    let points = PointSet {
        positions: pos,
        normals: has_n.then_some(nor),
        colors: has_c.then_some(col),
    };
    let mesh = (!tris.is_empty()).then(|| TriMesh {
        vertices: points.positions.clone(),
        normals: Vec::new(),
        triangles: tris,
    });
    Ok(Loaded { points, mesh })
}

/// Parse OBJ vertices (`v x y z [r g b]`), normals (`vn`, used when one per vertex) and faces.
pub fn read_obj(bytes: &[u8]) -> Result<Loaded, IoError> {
    let (mut pos, mut nor, mut col) = (Vec::new(), Vec::new(), Vec::new());
    let mut faces: Vec<(usize, Vec<i64>)> = Vec::new();
    for (line, l) in data_lines(utf8(bytes)?) {
        let mut t = l.split_whitespace();
        match t.next() {
            Some("v") => {
                pos.push(vec3(&mut t, line, ["x", "y", "z"])?);
                let rest: Vec<&str> = t.collect();
                if rest.len() >= 3 {
                    let mut r = rest.into_iter();
                    let c = vec3(&mut r, line, ["red", "green", "blue"])?;
                    col.push(
                        (c * 255.0)
                            .round()
                            .clamp(DVec3::ZERO, DVec3::splat(255.0))
                            .to_array()
                            .map(|v| v as u8),
                    );
                }
            }
            Some("vn") => nor.push(vec3(&mut t, line, ["nx", "ny", "nz"])?),
            Some("f") => {
                let idx: Option<Vec<i64>> = t
                    .map(|s| s.split('/').next().and_then(|i| i.parse().ok()))
                    .collect();
                faces.push((
                    line,
                    idx.ok_or(IoError::Line {
                        line,
                        reason: "face index is not an integer".into(),
                    })?,
                ));
            }
            _ => {}
        }
    }
    let nv = pos.len();
    let mut tris = Vec::new();
    for (line, f) in faces {
        let mut poly = Vec::with_capacity(f.len());
        for i in f {
            // 1-based, negative = relative to the end.
            let abs = if i < 0 { nv as i64 + i } else { i - 1 };
            if abs < 0 || abs >= nv as i64 {
                return Err(IoError::Line {
                    line,
                    reason: format!("vertex index {i} out of range for {nv} vertices"),
                });
            }
            poly.push(abs as u32);
        }
        push_polygon(&mut tris, &poly, nv, |reason| IoError::Line {
            line,
            reason,
        })?;
    }
    let normals = (nor.len() == nv && nv > 0).then_some(nor);
    let colors = (col.len() == nv && nv > 0).then_some(col);
    let points = PointSet {
        positions: pos,
        normals,
        colors,
    };
    let mesh = (!tris.is_empty()).then(|| TriMesh {
        vertices: points.positions.clone(),
        normals: Vec::new(),
        triangles: tris,
    });
    Ok(Loaded { points, mesh })
}

/// Write a mesh as OBJ with per-vertex normals when present.
pub fn write_obj(w: impl Write, mesh: &TriMesh) -> Result<(), IoError> {
    let mut w = std::io::BufWriter::new(w);
    let has_n = mesh.normals.len() == mesh.vertices.len() && !mesh.vertices.is_empty();
    writeln!(
        w,
        "# written by sim-core: {} vertices, {} triangles",
        mesh.vertices.len(),
        mesh.triangles.len()
    )?;
    for v in &mesh.vertices {
        writeln!(w, "v {} {} {}", v.x, v.y, v.z)?;
    }
    if has_n {
        for n in &mesh.normals {
            writeln!(w, "vn {} {} {}", n.x as f32, n.y as f32, n.z as f32)?;
        }
    }
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| i + 1);
        if has_n {
            writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?;
        } else {
            writeln!(w, "f {a} {b} {c}")?;
        }
    }
    w.flush()?;
    Ok(())
}
