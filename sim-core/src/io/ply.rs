//! PLY: ASCII, binary little- and big-endian. Vertex properties `x y z`, optional `nx ny nz`
//! and `red green blue` (integer 0–255 or float 0–1); faces from `vertex_indices` /
//! `vertex_index` lists, fan-triangulated. Other elements and properties are skipped.

use glam::DVec3;

use super::{IoError, Loaded, push_polygon};
use crate::mesh::TriMesh;
use crate::pointset::PointSet;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Encoding {
    Ascii,
    Little,
    Big,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }
    fn is_int(self) -> bool {
        !matches!(self, Self::F32 | Self::F64)
    }
}

#[derive(Debug, Clone)]
struct Property {
    name: String,
    /// For a list: the count type; the item type is `ty`.
    list: Option<Scalar>,
    ty: Scalar,
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

/// A cursor over the data section, yielding scalars as `f64`.
struct Data<'a> {
    enc: Encoding,
    bytes: &'a [u8],
    pos: usize,
    /// ASCII: the tokens of the current record, and its line number.
    tokens: Vec<&'a str>,
    tok: usize,
    line: usize,
    lines: std::iter::Peekable<std::iter::Enumerate<std::str::Lines<'a>>>,
}

impl<'a> Data<'a> {
    fn begin_record(&mut self) -> Result<(), String> {
        if self.enc != Encoding::Ascii {
            return Ok(());
        }
        for (i, l) in self.lines.by_ref() {
            let l = l.trim();
            if !l.is_empty() {
                self.tokens.clear();
                self.tokens.extend(l.split_whitespace());
                self.tok = 0;
                self.line = i + 1;
                return Ok(());
            }
        }
        Err("unexpected end of file".into())
    }

    fn scalar(&mut self, ty: Scalar) -> Result<f64, String> {
        if self.enc == Encoding::Ascii {
            let t = self.tokens.get(self.tok).ok_or("too few values")?;
            self.tok += 1;
            return t.parse::<f64>().map_err(|_| format!("not a number: {t:?}"));
        }
        let n = ty.size();
        let b = self
            .bytes
            .get(self.pos..self.pos + n)
            .ok_or("truncated binary data")?;
        self.pos += n;
        let mut a = [0u8; 8];
        a[..n].copy_from_slice(b);
        if self.enc == Encoding::Big {
            a[..n].reverse();
        }
        Ok(match ty {
            Scalar::I8 => a[0] as i8 as f64,
            Scalar::U8 => a[0] as f64,
            Scalar::I16 => i16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::U16 => u16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::I32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::U32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F32 => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F64 => f64::from_le_bytes(a),
        })
    }
}

/// Parse a PLY file.
pub fn read_ply(bytes: &[u8]) -> Result<Loaded, IoError> {
    let (enc, elements, data_start) = header(bytes)?;
    let body = &bytes[data_start..];
    let text = if enc == Encoding::Ascii {
        std::str::from_utf8(body).map_err(|e| IoError::Line {
            line: 0,
            reason: e.to_string(),
        })?
    } else {
        ""
    };
    let header_lines = bytes[..data_start].iter().filter(|&&b| b == b'\n').count();
    let mut d = Data {
        enc,
        bytes: body,
        pos: 0,
        tokens: Vec::new(),
        tok: 0,
        line: 0,
        lines: text.lines().enumerate().peekable(),
    };
    let mut out = Loaded::default();
    let mut tris = Vec::new();
    let mut faces_seen = false;
    for el in &elements {
        let is_vertex = el.name == "vertex";
        let is_face = el.name == "face";
        let find = |n: &[&str]| el.props.iter().position(|p| n.contains(&p.name.as_str()));
        let xyz = [find(&["x"]), find(&["y"]), find(&["z"])];
        let nrm = [find(&["nx"]), find(&["ny"]), find(&["nz"])];
        let rgb = [
            find(&["red", "r", "diffuse_red"]),
            find(&["green", "g", "diffuse_green"]),
            find(&["blue", "b", "diffuse_blue"]),
        ];
        let has_n = is_vertex && nrm.iter().all(Option::is_some);
        let has_c = is_vertex && rgb.iter().all(Option::is_some);
        if is_vertex && xyz.iter().any(Option::is_none) {
            return Err(IoError::Header {
                line: 0,
                reason: "vertex element lacks x, y or z".into(),
            });
        }
        let list_prop = find(&["vertex_indices", "vertex_index"]);
        faces_seen |= is_face && list_prop.is_some();
        let cap = el.count.min(1 << 20);
        let (mut pos, mut nor, mut col) = (
            Vec::with_capacity(if is_vertex { cap } else { 0 }),
            Vec::new(),
            Vec::new(),
        );
        let mut vals = vec![0.0; el.props.len()];
        let mut poly: Vec<u32> = Vec::new();
        // Binary records are read byte by byte, so the header's count is only trusted as far as
        // the data can hold it: a record takes at least the bytes of its scalars and list
        // counts, and an element without properties has nothing to read (otherwise a count of
        // 10¹² would loop for hours over an empty record).
        let mut records = el.count;
        if enc != Encoding::Ascii {
            let min_record: usize = el.props.iter().map(|p| p.list.unwrap_or(p.ty).size()).sum();
            if min_record == 0 {
                records = 0;
            } else if el.count > (d.bytes.len() - d.pos) / min_record {
                return Err(IoError::Record {
                    element: el.name.clone(),
                    index: (d.bytes.len() - d.pos) / min_record,
                    reason: format!(
                        "the header claims {} records but only {} bytes of data remain",
                        el.count,
                        d.bytes.len() - d.pos
                    ),
                });
            }
        }
        for index in 0..records {
            let err = |reason: String, d: &Data<'_>| match enc {
                Encoding::Ascii => IoError::Line {
                    line: header_lines + d.line,
                    reason: format!("{} {index}: {reason}", el.name),
                },
                _ => IoError::Record {
                    element: el.name.clone(),
                    index,
                    reason,
                },
            };
            d.begin_record().map_err(|r| err(r, &d))?;
            for (pi, p) in el.props.iter().enumerate() {
                match p.list {
                    None => vals[pi] = d.scalar(p.ty).map_err(|r| err(r, &d))?,
                    Some(ct) => {
                        let n = d.scalar(ct).map_err(|r| err(r, &d))?;
                        if !((0.0..=1e6).contains(&n) && n.fract() == 0.0) {
                            return Err(err(format!("bad list length {n}"), &d));
                        }
                        let keep = Some(pi) == list_prop && is_face;
                        poly.clear();
                        for _ in 0..n as usize {
                            let v = d.scalar(p.ty).map_err(|r| err(r, &d))?;
                            if keep {
                                if !(v >= 0.0 && v < u32::MAX as f64 && v.fract() == 0.0) {
                                    return Err(err(format!("bad vertex index {v}"), &d));
                                }
                                poly.push(v as u32);
                            }
                        }
                        if keep {
                            let nv = out.points.positions.len();
                            push_polygon(&mut tris, &poly, nv, |r| err(r, &d))?;
                        }
                    }
                }
            }
            if is_vertex {
                let g = |k: Option<usize>| vals[k.unwrap_or(0)];
                let p = DVec3::new(g(xyz[0]), g(xyz[1]), g(xyz[2]));
                if !p.is_finite() {
                    return Err(err("non-finite coordinate".into(), &d));
                }
                pos.push(p);
                if has_n {
                    let n = DVec3::new(g(nrm[0]), g(nrm[1]), g(nrm[2]));
                    nor.push(if n.is_finite() { n } else { DVec3::ZERO });
                }
                if has_c {
                    let c = rgb.map(|k| {
                        let ty = el.props[k.unwrap_or(0)].ty;
                        let v = if ty.is_int() { g(k) } else { g(k) * 255.0 };
                        v.round().clamp(0.0, 255.0) as u8
                    });
                    col.push(c);
                }
            }
        }
        if is_vertex {
            out.points = PointSet {
                positions: pos,
                normals: has_n.then_some(nor),
                colors: has_c.then_some(col),
            };
        }
    }
    if faces_seen && !tris.is_empty() {
        out.mesh = Some(TriMesh {
            vertices: out.points.positions.clone(),
            normals: Vec::new(),
            triangles: tris,
        });
    }
    Ok(out)
}

fn header(bytes: &[u8]) -> Result<(Encoding, Vec<Element>, usize), IoError> {
    let herr = |line: usize, reason: &str| IoError::Header {
        line,
        reason: reason.to_string(),
    };
    let mut pos = 0;
    let mut enc = None;
    let mut elements: Vec<Element> = Vec::new();
    for line_no in 1.. {
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .ok_or_else(|| herr(line_no, "no end_header"))?;
        let line = std::str::from_utf8(&bytes[pos..pos + end])
            .map_err(|_| herr(line_no, "header is not text"))?;
        pos += end + 1;
        let mut t = line.split_whitespace();
        match (line_no, t.next()) {
            (1, Some("ply")) => {}
            (1, _) => return Err(herr(1, "not a PLY file (first line must be `ply`)")),
            (_, Some("format")) => {
                enc = Some(match t.next() {
                    Some("ascii") => Encoding::Ascii,
                    Some("binary_little_endian") => Encoding::Little,
                    Some("binary_big_endian") => Encoding::Big,
                    _ => return Err(herr(line_no, "unknown format")),
                });
            }
            (_, Some("comment" | "obj_info") | None) => {}
            (_, Some("element")) => {
                let name = t
                    .next()
                    .ok_or_else(|| herr(line_no, "element without a name"))?;
                let count = t
                    .next()
                    .and_then(|c| c.parse().ok())
                    .ok_or_else(|| herr(line_no, "element count is not a number"))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            (_, Some("property")) => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| herr(line_no, "property before any element"))?;
                let ty = t
                    .next()
                    .ok_or_else(|| herr(line_no, "property without a type"))?;
                let prop = if ty == "list" {
                    let ct = t
                        .next()
                        .and_then(Scalar::parse)
                        .ok_or_else(|| herr(line_no, "bad list count type"))?;
                    let it = t
                        .next()
                        .and_then(Scalar::parse)
                        .ok_or_else(|| herr(line_no, "bad list item type"))?;
                    Property {
                        name: t.next().unwrap_or("").to_string(),
                        list: Some(ct),
                        ty: it,
                    }
                } else {
                    let ty = Scalar::parse(ty)
                        .ok_or_else(|| herr(line_no, &format!("unknown type {ty:?}")))?;
                    Property {
                        name: t.next().unwrap_or("").to_string(),
                        list: None,
                        ty,
                    }
                };
                el.props.push(prop);
            }
            (_, Some("end_header")) => {
                let enc = enc.ok_or_else(|| herr(line_no, "no format line"))?;
                return Ok((enc, elements, pos));
            }
            (_, Some(other)) => return Err(herr(line_no, &format!("unknown keyword {other:?}"))),
        }
    }
    unreachable!("the header loop returns")
}
