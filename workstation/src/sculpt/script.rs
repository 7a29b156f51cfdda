//! The `workstation sculpt` script format (TOML). Documented field by field in
//! `examples/sculpt/README.md`; every example there parses in the tests.
//!
//! Parsing has two layers: serde rejects unknown fields, missing fields and wrong types (the
//! message names the field and its line); [`Script::validate`] then checks values and references
//! and names the offending field as `op[3].radius: must be positive and finite`.

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
    /// A point or mesh file (PLY, OFF, OBJ, STL, XYZ), relative to the script; a mesh without
    /// vertex normals gives its points its faces' area-weighted normals.
    pub file: Option<String>,
    /// Or an analytic shape to sample.
    pub generate: Option<Generate>,
    /// With `file`: scale the loaded points uniformly so their box's longest side is this
    /// (m), centred at the origin before `offset` (a model in millimetres or any other unit).
    #[serde(default)]
    pub size: Option<f64>,
    /// Translation applied after loading or generating (m).
    #[serde(default)]
    pub offset: [f64; 3],
}

/// A sampled analytic shape.
#[derive(Debug, Clone, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Generate {
    /// `sphere`, `torus`, `plate`, `box`, or `sample:MESH_FILE` (points on a mesh's triangles,
    /// the file relative to the script: a dense scan stand-in).
    pub shape: String,
    /// Sphere radius, torus major radius, plate/box half size, a sampled mesh's longest side
    /// (m).
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
#[derive(Debug, Clone, Deserialize, serde::Serialize)]
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
    /// Resample the region's points (back onto the surface, crowded ones merged, holes filled,
    /// normals that agree with the field) after each commit and after CSG and embossing. Live sessions:
    /// on unless `false`; `sculpt` scripts: off unless `true`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resample: Option<bool>,
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

/// What a tool leaves behind when it lets go.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Release {
    /// Plastic: the deformed field becomes the new rest state (the shape stays), as a
    /// sculptor expects. What the device-driven tools do too.
    #[default]
    Commit,
    /// Elastic: nothing is committed; the field springs back over the following steps unless
    /// an `end_stroke` commits it first.
    SpringBack,
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
        /// What happens when the rope lets go after its steps.
        #[serde(default)]
        release: Release,
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

impl Script {
    /// Parse TOML; serde errors name the field and line.
    pub fn parse(text: &str) -> Result<Self, ScriptError> {
        let script: Self = toml::from_str(text).map_err(|e| {
            let span = e.span().map(|s| {
                let line = text[..s.start.min(text.len())].matches('\n').count() + 1;
                format!("line {line}")
            });
            ScriptError {
                field: span.unwrap_or_else(|| "script".into()),
                reason: e.message().to_string(),
            }
        })?;
        script.validate()?;
        Ok(script)
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
