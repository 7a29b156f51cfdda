//! The `workstation sculpt` script format (TOML). Documented field by field in
//! `examples/sculpt/README.md`; every example there parses in the tests.
//!
//! Parsing has two layers: serde rejects unknown fields, missing fields and wrong types (the
//! message names the field and its line); [`Script::validate`] then checks values and references
//! and names the offending field as `op[3].radius: must be positive and finite`.

use std::collections::HashSet;

use glam::DVec3;
use serde::Deserialize;
use sim_core::csg::CsgOp;
use sim_core::dynamics::NodeParams;
use sim_core::tools::emboss::Mapping;

/// A whole script.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Script {
    /// Objects to load or generate, in order.
    pub object: Vec<ObjectSpec>,
    /// The sculpting region (optional: scripts that only paint, emboss or combine need none).
    pub region: Option<RegionSpec>,
    /// Operations, run in order.
    #[serde(default)]
    pub op: Vec<Op>,
    /// Mesh the zero set of each object in the output (default true), at this many cells along
    /// the longest side.
    #[serde(default = "default_mesh_resolution")]
    pub mesh_resolution: usize,
}

fn default_mesh_resolution() -> usize {
    96
}

/// One object.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    /// Name used by operations and output files.
    pub name: String,
    /// A point file (PLY, OFF, OBJ, XYZ), relative to the script.
    pub file: Option<String>,
    /// Or an analytic shape to sample.
    pub generate: Option<Generate>,
    /// Translation applied after loading or generating (m).
    #[serde(default)]
    pub offset: [f64; 3],
}

/// A sampled analytic shape.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Generate {
    /// `sphere`, `torus`, `plate` or `box`.
    pub shape: String,
    /// Sphere radius, torus major radius, plate/box half size (m).
    pub size: f64,
    /// Torus minor radius, plate thickness, box rounding (m); unused for spheres.
    #[serde(default)]
    pub size2: f64,
    /// Number of samples.
    pub points: usize,
    /// RNG seed.
    #[serde(default)]
    pub seed: u64,
}

/// The sculpting region.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    /// Object sculpted.
    pub object: String,
    /// Box corners (m).
    pub min: [f64; 3],
    /// Box corners (m).
    pub max: [f64; 3],
    /// Grid spacing (m).
    pub spacing: f64,
    /// Band half-width (m).
    pub band: f64,
    /// `symplectic_euler`, `forward_euler` or `backward_euler`.
    #[serde(default = "default_integrator")]
    pub integrator: String,
    /// Forward Euler's halving threshold on |ü| (value units/s²).
    #[serde(default = "default_threshold")]
    pub accel_threshold: f64,
    /// Time step (s).
    #[serde(default = "default_dt")]
    pub dt: f64,
    /// Node parameters.
    #[serde(default)]
    pub node: Option<NodeParams>,
    /// Up-sample around moved points at each stroke end where gaps exceed this (m).
    #[serde(default)]
    pub auto_upsample: Option<f64>,
}

fn default_integrator() -> String {
    "symplectic_euler".into()
}
fn default_threshold() -> f64 {
    1e4
}
fn default_dt() -> f64 {
    1e-3
}

/// One operation.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Op {
    /// Pull with a rope for `steps` steps; the path moves linearly to `path_end` if given.
    Rope {
        /// Attachment point or polyline (m).
        path: Vec<[f64; 3]>,
        /// Where the path ends up after `steps` (same length as `path`).
        path_end: Option<Vec<[f64; 3]>>,
        /// Reach (m).
        radius: f64,
        /// Peak node force (N), positive pulls outward.
        strength: f64,
        /// `gaussian`, `constant`, `spherical` or `table`.
        profile: String,
        /// Values for `profile = "table"`.
        table: Option<Vec<f64>>,
        /// Picked sheet normal (thin shells).
        sheet: Option<[f64; 3]>,
        /// Steps to run.
        steps: usize,
    },
    /// Steps without tools.
    Relax {
        /// Steps to run.
        steps: usize,
    },
    /// End the stroke: refit moved points, make the shape the new rest state.
    EndStroke,
    /// Paint on an object.
    Paint {
        /// Object.
        object: String,
        /// Cursor (m).
        center: [f64; 3],
        /// Applied force (N).
        #[serde(default)]
        force: f64,
        /// sRGB colour.
        color: [u8; 3],
        /// Radius at zero force (m).
        radius: f64,
        /// Growth per newton (m/N).
        #[serde(default)]
        radius_per_newton: f64,
        /// Largest radius (m); defaults to `radius`.
        max_radius: Option<f64>,
        /// `gaussian`, `constant` or `spherical`.
        #[serde(default = "default_falloff")]
        falloff: String,
        /// Up-sample points straddling the rim first (default true).
        #[serde(default = "yes")]
        clean_edges: bool,
    },
    /// Emboss (depth > 0) or engrave (depth < 0) a PNG.
    Emboss {
        /// Object.
        object: String,
        /// PNG path relative to the script.
        image: String,
        /// Mapping (`kind` = planar / cylindrical / spherical with its vectors).
        mapping: Mapping,
        /// Displacement at white (m).
        depth: f64,
    },
    /// Boolean of two objects into a new one.
    Csg {
        /// `union`, `intersection` or `difference`.
        op: CsgOp,
        /// First operand.
        a: String,
        /// Second operand.
        b: String,
        /// Name of the result.
        result: String,
    },
    /// Up-sample an object where its largest empty circle exceeds `max_gap`.
    Upsample {
        /// Object.
        object: String,
        /// Gap threshold (m).
        max_gap: f64,
    },
    /// Merge an object's points closer than `min_distance`.
    Downsample {
        /// Object.
        object: String,
        /// Merge distance (m).
        min_distance: f64,
    },
}

fn default_falloff() -> String {
    "spherical".into()
}
fn yes() -> bool {
    true
}

/// A parse, value or reference error, naming the field (or the line, for syntax errors).
#[derive(Debug, Clone, PartialEq)]
pub struct ScriptError {
    /// Dotted path of the field, e.g. `op[2].radius`, or `line N`.
    pub field: String,
    /// What is wrong.
    pub reason: String,
}

impl std::fmt::Display for ScriptError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.field, self.reason)
    }
}

impl std::error::Error for ScriptError {}

fn err(field: impl Into<String>, reason: impl Into<String>) -> ScriptError {
    ScriptError {
        field: field.into(),
        reason: reason.into(),
    }
}

fn positive(field: String, x: f64) -> Result<(), ScriptError> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(err(field, format!("must be positive and finite (got {x})")))
    }
}

fn finite3(field: String, v: [f64; 3]) -> Result<DVec3, ScriptError> {
    let d = DVec3::from_array(v);
    if d.is_finite() {
        Ok(d)
    } else {
        Err(err(field, "must be finite"))
    }
}

impl Script {
    /// Parse TOML; serde errors name the field and line.
    pub fn parse(text: &str) -> Result<Self, ScriptError> {
        let script: Self = toml::from_str(text).map_err(|e| {
            let span = e.span().map(|s| {
                let line = text[..s.start.min(text.len())].matches('\n').count() + 1;
                format!("line {line}")
            });
            err(
                span.unwrap_or_else(|| "script".into()),
                e.message().to_string(),
            )
        })?;
        script.validate()?;
        Ok(script)
    }

    /// Check values and references.
    pub fn validate(&self) -> Result<(), ScriptError> {
        let mut names = HashSet::new();
        if self.object.is_empty() {
            return Err(err("object", "at least one [[object]] is required"));
        }
        for (i, o) in self.object.iter().enumerate() {
            let f = |x: &str| format!("object[{i}].{x}");
            if !names.insert(o.name.clone()) {
                return Err(err(
                    f("name"),
                    format!("duplicate object name `{}`", o.name),
                ));
            }
            finite3(f("offset"), o.offset)?;
            match (&o.file, &o.generate) {
                (Some(_), None) => {}
                (None, Some(g)) => {
                    if !["sphere", "torus", "plate", "box"].contains(&g.shape.as_str()) {
                        return Err(err(
                            f("generate.shape"),
                            "must be sphere, torus, plate or box",
                        ));
                    }
                    positive(f("generate.size"), g.size)?;
                    if g.shape != "sphere" {
                        positive(f("generate.size2"), g.size2)?;
                    }
                    if g.points < 50 {
                        return Err(err(f("generate.points"), "must be at least 50"));
                    }
                }
                _ => return Err(err(f("file"), "give exactly one of `file` and `generate`")),
            }
        }
        let known = |field: String, name: &str, names: &HashSet<String>| {
            if names.contains(name) {
                Ok(())
            } else {
                Err(err(field, format!("no object named `{name}`")))
            }
        };
        if let Some(r) = &self.region {
            known("region.object".into(), &r.object, &names)?;
            let (lo, hi) = (
                finite3("region.min".into(), r.min)?,
                finite3("region.max".into(), r.max)?,
            );
            if !hi.cmpgt(lo).all() {
                return Err(err("region.max", "must exceed region.min on every axis"));
            }
            positive("region.spacing".into(), r.spacing)?;
            positive("region.band".into(), r.band)?;
            positive("region.dt".into(), r.dt)?;
            positive("region.accel_threshold".into(), r.accel_threshold)?;
            if let Some(g) = r.auto_upsample {
                positive("region.auto_upsample".into(), g)?;
            }
            if !["symplectic_euler", "forward_euler", "backward_euler"]
                .contains(&r.integrator.as_str())
            {
                return Err(err(
                    "region.integrator",
                    "must be symplectic_euler, forward_euler or backward_euler",
                ));
            }
            if let Some(n) = &r.node {
                n.validate()
                    .map_err(|e| err("region.node", e.to_string()))?;
            }
            let cells = ((hi - lo) / r.spacing).ceil();
            if cells.x * cells.y * cells.z > 2e7 {
                return Err(err("region.spacing", "gives more than 2·10⁷ grid nodes"));
            }
        }
        for (i, op) in self.op.iter().enumerate() {
            let f = |x: &str| format!("op[{i}].{x}");
            let needs_region = || {
                if self.region.is_some() {
                    Ok(())
                } else {
                    Err(err(format!("op[{i}]"), "needs a [region]"))
                }
            };
            match op {
                Op::Rope {
                    path,
                    path_end,
                    radius,
                    strength,
                    profile,
                    table,
                    sheet,
                    ..
                } => {
                    needs_region()?;
                    if path.is_empty() {
                        return Err(err(f("path"), "needs at least one point"));
                    }
                    for (k, p) in path.iter().enumerate() {
                        finite3(f(&format!("path[{k}]")), *p)?;
                    }
                    if let Some(end) = path_end
                        && end.len() != path.len()
                    {
                        return Err(err(f("path_end"), "must have as many points as `path`"));
                    }
                    positive(f("radius"), *radius)?;
                    if !strength.is_finite() {
                        return Err(err(f("strength"), "must be finite"));
                    }
                    profile_of(profile, table.as_deref()).map_err(|r| err(f("profile"), r))?;
                    if let Some(s) = sheet {
                        finite3(f("sheet"), *s)?;
                    }
                }
                Op::Relax { .. } | Op::EndStroke => needs_region()?,
                Op::Paint {
                    object,
                    radius,
                    max_radius,
                    falloff,
                    ..
                } => {
                    known(f("object"), object, &names)?;
                    positive(f("radius"), *radius)?;
                    if let Some(m) = max_radius {
                        positive(f("max_radius"), *m)?;
                    }
                    profile_of(falloff, None).map_err(|r| err(f("falloff"), r))?;
                }
                Op::Emboss { object, depth, .. } => {
                    known(f("object"), object, &names)?;
                    if !depth.is_finite() {
                        return Err(err(f("depth"), "must be finite"));
                    }
                }
                Op::Csg { a, b, result, .. } => {
                    known(f("a"), a, &names)?;
                    known(f("b"), b, &names)?;
                    if !names.insert(result.clone()) {
                        return Err(err(
                            f("result"),
                            format!("object `{result}` already exists"),
                        ));
                    }
                }
                Op::Upsample { object, max_gap } => {
                    known(f("object"), object, &names)?;
                    positive(f("max_gap"), *max_gap)?;
                }
                Op::Downsample {
                    object,
                    min_distance,
                } => {
                    known(f("object"), object, &names)?;
                    positive(f("min_distance"), *min_distance)?;
                }
            }
        }
        Ok(())
    }
}

/// A profile from its script name (and table).
pub fn profile_of(name: &str, table: Option<&[f64]>) -> Result<sim_core::tools::Profile, String> {
    use sim_core::tools::Profile;
    match (name, table) {
        ("gaussian", _) => Ok(Profile::Gaussian),
        ("constant", _) => Ok(Profile::Constant),
        ("spherical", _) => Ok(Profile::Spherical),
        ("table", Some(t)) if !t.is_empty() && t.iter().all(|x| x.is_finite()) => {
            Ok(Profile::Table(t.to_vec()))
        }
        ("table", _) => Err("`table` profile needs a non-empty finite `table`".into()),
        _ => Err(format!(
            "unknown profile `{name}` (gaussian, constant, spherical, table)"
        )),
    }
}
