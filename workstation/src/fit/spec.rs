//! Parsing of `workstation fit` inputs and references: analytic generators (`gen:sphere:R:N`)
//! and references (`sphere:R`, `torus:R,r`, `mesh:FILE`). Pure: no file access.

use std::path::PathBuf;

use anyhow::{Context, bail, ensure};
use glam::DVec3;
use sim_core::sampling::Shape;

use crate::limits::MAX_GEN_POINTS;

/// Where the points come from.
#[derive(Debug, Clone, PartialEq)]
pub enum InputSpec {
    /// A point or mesh file.
    File(PathBuf),
    /// `n` points sampled from a mesh file's triangles (`sample:FILE:N`), normals interpolated
    /// from its vertex normals, in spatial order: a dense scan stand-in (issue 19).
    SampledMesh {
        /// The mesh file.
        path: PathBuf,
        /// Point count.
        n: usize,
    },
    /// `n` points sampled from an analytic shape.
    Generated {
        /// The shape.
        shape: Shape,
        /// Point count.
        n: usize,
    },
}

/// What the zero set is measured against.
#[derive(Debug, Clone, PartialEq)]
pub enum ReferenceSpec {
    /// No measurement.
    None,
    /// An analytic shape at the origin.
    Shape(Shape),
    /// A triangle mesh file.
    Mesh(PathBuf),
}

fn numbers(s: &str, sep: char, what: &str) -> anyhow::Result<Vec<f64>> {
    s.split(sep)
        .map(|t| {
            let v: f64 = t
                .trim()
                .parse()
                .with_context(|| format!("{what}: {t:?} is not a number"))?;
            ensure!(
                v.is_finite() && v > 0.0,
                "{what}: {t:?} must be positive and finite"
            );
            Ok(v)
        })
        .collect()
}

/// Build a shape from its name and positive parameters.
pub fn shape(name: &str, p: &[f64]) -> anyhow::Result<Shape> {
    let want = |n: usize| -> anyhow::Result<()> {
        ensure!(
            p.len() == n,
            "{name} takes {n} parameter(s), got {}",
            p.len()
        );
        Ok(())
    };
    Ok(match name {
        "sphere" => {
            want(1)?;
            Shape::Sphere { radius: p[0] }
        }
        "torus" => {
            want(2)?;
            ensure!(
                p[1] < p[0],
                "torus: the tube radius r must be smaller than R"
            );
            Shape::Torus {
                major: p[0],
                minor: p[1],
            }
        }
        "ellipsoid" => {
            want(3)?;
            Shape::Ellipsoid {
                radii: DVec3::new(p[0], p[1], p[2]),
            }
        }
        "box" => {
            want(4)?;
            let half = DVec3::new(p[0], p[1], p[2]);
            ensure!(
                p[3] <= half.min_element(),
                "box: the rounding radius exceeds a half extent"
            );
            Shape::RoundedBox { half, radius: p[3] }
        }
        "cylinder" => {
            want(2)?;
            Shape::Cylinder {
                radius: p[0],
                half_height: p[1] / 2.0,
            }
        }
        "plate" => {
            want(2)?;
            Shape::Plate {
                half_size: p[0] / 2.0,
                thickness: p[1],
            }
        }
        "carved" => {
            want(3)?;
            ensure!(
                (p[0] - p[1]).abs() < p[2] && p[2] < p[0] + p[1],
                "carved: the cutter (radius r at distance d) must cut the sphere's rim: |R − r| < d < R + r"
            );
            Shape::Carved {
                radius: p[0],
                cutter: p[1],
                offset: p[2],
            }
        }
        other => bail!(
            "unknown shape {other:?} (sphere, torus, ellipsoid, box, cylinder, plate, carved)"
        ),
    })
}

/// Parse INPUT: `gen:SHAPE:P1:...:N` or a file path.
///
/// Generators: `gen:sphere:R:N`, `gen:torus:R:r:N`, `gen:ellipsoid:a:b:c:N`,
/// `gen:box:hx:hy:hz:rounding:N`, `gen:cylinder:radius:height:N`, `gen:plate:side:thickness:N`,
/// `gen:carved:R:r:d:N` (a sphere minus a sphere: a CSG difference with a sharp crease).
pub fn parse_input(s: &str) -> anyhow::Result<InputSpec> {
    if let Some(rest) = s.strip_prefix("sample:") {
        let (path, n_str) = rest
            .rsplit_once(':')
            .with_context(|| format!("generator {s:?}: expected sample:MESH_FILE:N"))?;
        let n: usize = n_str
            .parse()
            .with_context(|| format!("generator {s:?}: point count {n_str:?}"))?;
        ensure!(n >= 1, "generator {s:?}: needs at least one point");
        ensure!(!path.is_empty(), "generator {s:?}: missing mesh file");
        crate::cap!(format!("generator {s:?}: N"), n, MAX_GEN_POINTS, "points")?;
        return Ok(InputSpec::SampledMesh {
            path: PathBuf::from(path),
            n,
        });
    }
    let Some(rest) = s.strip_prefix("gen:") else {
        return Ok(InputSpec::File(PathBuf::from(s)));
    };
    let mut parts: Vec<&str> = rest.split(':').collect();
    ensure!(
        parts.len() >= 3,
        "generator {s:?}: expected gen:SHAPE:PARAMS...:N"
    );
    let n_str = parts.pop().unwrap_or_default();
    let n: usize = n_str
        .parse()
        .with_context(|| format!("generator {s:?}: point count {n_str:?}"))?;
    ensure!(n >= 1, "generator {s:?}: needs at least one point");
    crate::cap!(format!("generator {s:?}: N"), n, MAX_GEN_POINTS, "points")?;
    let params = numbers(&parts[1..].join(":"), ':', s)?;
    Ok(InputSpec::Generated {
        shape: shape(parts[0], &params)?,
        n,
    })
}

/// Parse `--reference`: `sphere:R`, `torus:R,r`, `ellipsoid:a,b,c`, `box:hx,hy,hz,r`,
/// `cylinder:r,h`, `plate:side,t`, `mesh:FILE` or `none`.
pub fn parse_reference(s: &str) -> anyhow::Result<ReferenceSpec> {
    if s == "none" {
        return Ok(ReferenceSpec::None);
    }
    let (kind, rest) = s
        .split_once(':')
        .with_context(|| format!("reference {s:?}: expected KIND:PARAMS"))?;
    if kind == "mesh" {
        ensure!(!rest.is_empty(), "reference {s:?}: missing mesh file");
        return Ok(ReferenceSpec::Mesh(PathBuf::from(rest)));
    }
    Ok(ReferenceSpec::Shape(shape(kind, &numbers(rest, ',', s)?)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generators_and_references_parse() {
        assert_eq!(
            parse_input("gen:sphere:2:1000").unwrap(),
            InputSpec::Generated {
                shape: Shape::Sphere { radius: 2.0 },
                n: 1000
            }
        );
        assert_eq!(
            parse_input("gen:torus:1:0.25:500").unwrap(),
            InputSpec::Generated {
                shape: Shape::Torus {
                    major: 1.0,
                    minor: 0.25
                },
                n: 500
            }
        );
        assert_eq!(
            parse_input("scan.ply").unwrap(),
            InputSpec::File("scan.ply".into())
        );
        assert_eq!(
            parse_reference("torus:1,0.3").unwrap(),
            ReferenceSpec::Shape(Shape::Torus {
                major: 1.0,
                minor: 0.3
            })
        );
        assert_eq!(
            parse_reference("mesh:a.stl").unwrap(),
            ReferenceSpec::Mesh("a.stl".into())
        );
        assert_eq!(parse_reference("none").unwrap(), ReferenceSpec::None);
        assert_eq!(
            parse_reference("carved:1,0.6,0.8").unwrap(),
            ReferenceSpec::Shape(Shape::Carved {
                radius: 1.0,
                cutter: 0.6,
                offset: 0.8
            })
        );
    }

    #[test]
    fn bad_specs_are_errors() {
        for s in [
            "gen:sphere:1",
            "gen:sphere:-1:10",
            "gen:cube:1:10",
            "gen:torus:1:2:10",
            "gen:sphere:1:0",
            "gen:carved:1:0.5:2:10",
        ] {
            assert!(parse_input(s).is_err(), "{s}");
        }
        let e = parse_input("gen:sphere:1:1000000000000")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "generator \"gen:sphere:1:1000000000000\": N = 1000000000000 is over the limit of 20000000 points (MAX_GEN_POINTS)"
        );
        assert!(parse_input(&format!("gen:sphere:1:{MAX_GEN_POINTS}")).is_ok());
        for s in ["sphere", "sphere:x", "torus:1", "mesh:", "sphere:nan"] {
            assert!(parse_reference(s).is_err(), "{s}");
        }
    }
}
