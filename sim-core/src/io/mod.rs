//! Point and mesh file formats: PLY (ASCII and binary, with normals and colours), OFF, OBJ,
//! XYZ/PWN and STL. Readers parse from any [`std::io::Read`]; writers write to any
//! [`std::io::Write`]; opening files is the caller's business (sim-core does no file I/O).
//!
//! Contract: a malformed file gives an [`IoError`] naming the line (text) or record (binary) and
//! the reason, never a panic; counts in headers are not trusted for allocation; every returned
//! coordinate is finite.

mod ply;
mod ply_write;
mod stl;
mod text;

use std::io::{Read, Write};

pub use ply::read_ply;
pub use ply_write::{write_mesh_ply, write_points_ply};
pub use stl::{read_stl, write_stl};
pub use text::{read_obj, read_off, read_xyz, write_obj};

use crate::mesh::TriMesh;
use crate::pointset::PointSet;

/// A file format, usually chosen from the file extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Stanford polygon format.
    Ply,
    /// Object File Format (OFF, NOFF, COFF).
    Off,
    /// Wavefront OBJ.
    Obj,
    /// Whitespace-separated `x y z [nx ny nz]` lines.
    Xyz,
    /// Stereolithography (binary or ASCII), triangles only.
    Stl,
}

impl Format {
    /// The format for a file extension (case-insensitive): ply, off, obj, xyz, pwn, txt, stl.
    pub fn from_extension(ext: &str) -> Option<Self> {
        match ext.to_ascii_lowercase().as_str() {
            "ply" => Some(Self::Ply),
            "off" => Some(Self::Off),
            "obj" => Some(Self::Obj),
            "xyz" | "pwn" | "txt" | "pts" => Some(Self::Xyz),
            "stl" => Some(Self::Stl),
            _ => None,
        }
    }
}

/// What a reader found: the points (vertices) and, when the file has faces, the mesh.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Loaded {
    /// Vertices with any normals and colours.
    pub points: PointSet,
    /// Triangulated faces over the same vertices, if the file had any.
    pub mesh: Option<TriMesh>,
}

impl Loaded {
    /// Give the points their mesh's area-weighted vertex normals when the file had faces but
    /// no normals (an STL, most OBJ and OFF files): the winding says which way is out, more
    /// reliably than estimated normals' orientation on thin parts. A vertex no triangle uses
    /// gets a zero normal, which [`PointSet`] reads as "unknown, estimate it". Nothing changes
    /// for a file with normals or without faces.
    pub fn normals_from_winding(&mut self) {
        if self.points.normals.is_none()
            && let Some(mesh) = &self.mesh
            && mesh.vertices.len() == self.points.len()
        {
            self.points.normals = Some(mesh.vertex_normals());
        }
    }
}

/// Why a file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The underlying reader or writer failed.
    #[error("i/o: {0}")]
    Io(#[from] std::io::Error),
    /// A header line or field is malformed.
    #[error("header line {line}: {reason}")]
    Header {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// A text data line is malformed.
    #[error("line {line}: {reason}")]
    Line {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// A binary record is malformed or truncated.
    #[error("{element} record {index}: {reason}")]
    Record {
        /// Element name (vertex, face, triangle).
        element: String,
        /// 0-based record index.
        index: usize,
        /// What is wrong.
        reason: String,
    },
    /// The file holds no points.
    #[error("the file has no vertices")]
    Empty,
}

/// Read a file of the given format.
pub fn read(mut reader: impl Read, format: Format) -> Result<Loaded, IoError> {
    let mut bytes = Vec::new();
    reader.read_to_end(&mut bytes)?;
    let loaded = match format {
        Format::Ply => read_ply(&bytes)?,
        Format::Off => read_off(&bytes)?,
        Format::Obj => read_obj(&bytes)?,
        Format::Xyz => read_xyz(&bytes)?,
        Format::Stl => read_stl(&bytes)?,
    };
    if loaded.points.is_empty() {
        return Err(IoError::Empty);
    }
    Ok(loaded)
}

/// Write a mesh as PLY (binary little-endian), OBJ or binary STL.
pub fn write_mesh(writer: impl Write, mesh: &TriMesh, format: Format) -> Result<(), IoError> {
    match format {
        Format::Obj => write_obj(writer, mesh),
        Format::Stl => write_stl(writer, mesh),
        _ => write_mesh_ply(writer, mesh),
    }
}

/// Split `text` into 1-based numbered lines with comments (`#`) and blank lines removed.
fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines().enumerate().filter_map(|(i, l)| {
        let l = l.split('#').next().unwrap_or("").trim();
        (!l.is_empty()).then_some((i + 1, l))
    })
}

/// Parse a finite float field, naming the line and field on failure.
fn parse_f64(tok: Option<&str>, line: usize, what: &str) -> Result<f64, IoError> {
    let tok = tok.ok_or_else(|| IoError::Line {
        line,
        reason: format!("missing {what}"),
    })?;
    match tok.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(IoError::Line {
            line,
            reason: format!("{what} is not finite: {tok:?}"),
        }),
        Err(_) => Err(IoError::Line {
            line,
            reason: format!("{what} is not a number: {tok:?}"),
        }),
    }
}

/// Fan-triangulate a polygon, checking indices against the vertex count.
fn push_polygon(
    tris: &mut Vec<[u32; 3]>,
    poly: &[u32],
    vertices: usize,
    mut err: impl FnMut(String) -> IoError,
) -> Result<(), IoError> {
    if let Some(bad) = poly.iter().find(|&&i| i as usize >= vertices) {
        return Err(err(format!(
            "vertex index {bad} out of range (0..{vertices})"
        )));
    }
    for k in 1..poly.len().saturating_sub(1) {
        tris.push([poly[0], poly[k], poly[k + 1]]);
    }
    Ok(())
}
