//! The scene file of a live session (`workstation run --scene`, `workstation demo`): objects,
//! materials, the sculpting region, the device-to-scene transform, tool defaults, rendering and
//! an optional scripted session. Documented field by field in `examples/live/README.md`.
//!
//! Objects, the region and the non-device operations reuse the `sculpt` script's formats
//! ([`crate::sculpt::script`]), so a scene and a script read alike. Parsing has the same two
//! layers: serde names unknown, missing and mistyped fields with their line; [`SceneFile::parse`]
//! then checks every value and reference and names the field, e.g.
//! `phase[2].stroke.path: must hold at least one point`. [`load_scene`] reads one from a file;
//! [`DEMO_SCENE`] is the built-in one.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Context as _;

use glam::{DQuat, DVec3, EulerRot};
use serde::{Deserialize, Serialize};
use sim_core::dynamics::NodeParams;
use sim_core::io::Format;

use crate::sculpt::script::{Generate, ObjectSpec, Op, RegionSpec, Script, ScriptError};

use super::transform::DeviceTransform;

/// The built-in demo scene (`examples/live/demo.toml`).
pub const DEMO_SCENE: &str = include_str!("../../../examples/live/demo.toml");
/// The image it embosses.
pub const DEMO_IMAGE: &[u8] = include_bytes!("../../../examples/live/ring.png");

/// Read and check a scene file; errors name the file and the field. A point or mesh file
/// (an extension [`Format::from_extension`] knows) opens as [`model_scene`].
pub fn load_scene(path: &Path) -> anyhow::Result<SceneFile> {
    let model = path
        .extension()
        .and_then(|e| e.to_str())
        .and_then(Format::from_extension);
    if model.is_some() {
        return model_scene(path);
    }
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    SceneFile::parse(&text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// The longest side of a model opened as a scene (m): the demo ball's diameter, which the
/// demo's tools, material and region are sized for.
pub const MODEL_SIZE_M: f64 = 0.1;

/// Room the region leaves around a model opened as a scene, each side (m): for pulls.
pub const MODEL_MARGIN_M: f64 = 0.02;

/// The scene a point or mesh file opens in (`workstation view scan.ply`): the file is the one,
/// sculpted object, scaled to [`MODEL_SIZE_M`] across and centred at the origin; the region is
/// its whole box and [`MODEL_MARGIN_M`] around it; tools, material and rendering are the
/// demo's. Its saves are in these scene metres.
pub fn model_scene(path: &Path) -> anyhow::Result<SceneFile> {
    let file = std::path::absolute(path)
        .with_context(|| format!("resolving {}", path.display()))?
        .to_str()
        .with_context(|| format!("{}: the path is not UTF-8", path.display()))?
        .to_owned();
    // Output files are named after the object: keep the stem's safe characters.
    let stem: String = path
        .file_stem()
        .map(|s| s.to_string_lossy())
        .unwrap_or_default()
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let name = if stem.is_empty() {
        "model".into()
    } else {
        stem
    };
    let mut scene =
        SceneFile::parse(DEMO_SCENE).map_err(|e| anyhow::anyhow!("the demo scene: {e}"))?;
    scene.phase.clear();
    let material = scene.dynamic_object().and_then(|o| o.material.clone());
    scene.object = vec![SceneObjectSpec {
        name: name.clone(),
        file: Some(file),
        generate: None,
        size: Some(MODEL_SIZE_M),
        offset: [0.0; 3],
        dynamic: Some(true),
        material,
    }];
    let half = 0.5 * MODEL_SIZE_M + MODEL_MARGIN_M;
    scene.region.object = name;
    scene.region.min = [-half; 3];
    scene.region.max = [half; 3];
    scene
        .validate()
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok(scene)
}

/// The largest number of phases a session may hold.
pub const MAX_PHASES: usize = 1_000;
/// The largest number of waypoints in one stroke.
pub const MAX_STROKE_POINTS: usize = 10_000;
/// The longest stroke, s.
pub const MAX_STROKE_SECONDS: f64 = 600.0;
/// The largest rendered image side, pixels.
pub const MAX_IMAGE_SIDE: u32 = 8_192;

/// A whole scene file (serialised by [`SceneFile::to_toml`] without its phases).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// The device-to-scene transform.
    #[serde(default)]
    pub device: DeviceSpec,
    /// Objects to load or generate, in order.
    pub object: Vec<SceneObjectSpec>,
    /// Named materials (node parameters of the simulated field) objects refer to.
    #[serde(default)]
    pub material: BTreeMap<String, NodeParams>,
    /// The sculpting region on the one dynamic object.
    pub region: RegionSpec,
    /// Tool defaults.
    #[serde(default)]
    pub tools: ToolDefaults,
    /// Rendering.
    #[serde(default)]
    pub render: RenderSpec,
    /// A scripted session: strokes of the (fake) device and operations, in order.
    #[serde(default, skip_serializing)]
    pub phase: Vec<Phase>,
    /// Cells along the longest side when meshing the zero set for saving.
    #[serde(default = "default_mesh_resolution")]
    pub mesh_resolution: usize,
}

fn default_mesh_resolution() -> usize {
    96
}

/// Where the stylus is in the scene: `x_scene = translation + scale · R · x_device`.
#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct DeviceSpec {
    /// Scene metres per device metre (workspace scaling).
    pub scale: f64,
    /// Scene position of the device origin (m).
    pub translation: [f64; 3],
    /// Rotation device → scene, XYZ Euler angles in degrees.
    pub rotation_deg: [f64; 3],
}

impl Default for DeviceSpec {
    fn default() -> Self {
        Self {
            scale: 1.0,
            translation: [0.0; 3],
            rotation_deg: [0.0; 3],
        }
    }
}

impl DeviceSpec {
    /// The transform this spec describes.
    pub fn transform(&self) -> DeviceTransform {
        let [x, y, z] = self.rotation_deg.map(f64::to_radians);
        DeviceTransform::new(
            DQuat::from_euler(EulerRot::XYZ, x, y, z),
            DVec3::from(self.translation),
            self.scale,
        )
    }
}

/// One object: the `sculpt` script's object plus whether it is simulated and its material.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SceneObjectSpec {
    /// Name used by the region, operations and output files.
    pub name: String,
    /// A point or mesh file (PLY, OFF, OBJ, STL, XYZ), relative to the scene file.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// Or an analytic shape to sample.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub generate: Option<Generate>,
    /// With `file`: the longest side its points are scaled to, centred at the origin (m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size: Option<f64>,
    /// Translation applied after loading or generating (m).
    #[serde(default)]
    pub offset: [f64; 3],
    /// Simulated (the region's object; default) or static.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dynamic: Option<bool>,
    /// A `[material.NAME]` for the simulated field (default: the region's `node`, or defaults).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub material: Option<String>,
}

impl SceneObjectSpec {
    /// The `sculpt` script's view of this object.
    pub fn object_spec(&self) -> ObjectSpec {
        ObjectSpec {
            name: self.name.clone(),
            file: self.file.clone(),
            generate: self.generate.clone(),
            size: self.size,
            offset: self.offset,
        }
    }
}

/// Which tool the stylus button engages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ToolKind {
    /// Only feel the surface (field force with friction); the button does nothing.
    Touch,
    /// Rope at one point: press on the surface, drag to pull or push it.
    Rope,
    /// Rope along a curve: the cursor's path while pressed becomes the rope.
    RopeCurve,
    /// Paint at the contact point; the brush grows with the pressing force.
    Paint,
    /// The shaped probe carves where it goes while pressed.
    ProbePush,
    /// The shaped probe, pressed inside the material, drags it out.
    ProbePull,
}

impl ToolKind {
    /// The name in scene files and reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Touch => "touch",
            Self::Rope => "rope",
            Self::RopeCurve => "rope_curve",
            Self::Paint => "paint",
            Self::ProbePush => "probe_push",
            Self::ProbePull => "probe_pull",
        }
    }
}

/// Tool defaults.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ToolDefaults {
    /// The tool selected at start.
    pub selected: ToolKind,
    /// Touching the surface.
    pub contact: ContactSpec,
    /// The rope tools.
    pub rope: RopeSpec,
    /// The paint brush.
    pub paint: PaintSpec,
    /// The shaped probe.
    pub probe: ProbeSpec,
}

impl Default for ToolDefaults {
    fn default() -> Self {
        Self {
            selected: ToolKind::Touch,
            contact: ContactSpec::default(),
            rope: RopeSpec::default(),
            paint: PaintSpec::default(),
            probe: ProbeSpec::default(),
        }
    }
}

/// Touching the surface (Kim-style field force, DESIGN §5).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ContactSpec {
    /// Stiffness (N per scene metre).
    pub stiffness: f64,
    /// Damping (N·s/m).
    pub damping: f64,
    /// Coulomb friction coefficient.
    pub friction: f64,
}

impl Default for ContactSpec {
    fn default() -> Self {
        Self {
            stiffness: 400.0,
            damping: 0.5,
            friction: 0.2,
        }
    }
}

/// The rope tools: a spring from the stylus to the picked surface point pulls the material.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RopeSpec {
    /// Reach of the force profile on the field (m).
    pub radius: f64,
    /// Stiffness of the rope spring between stylus and surface (N/m): what the user feels.
    pub stiffness: f64,
    /// Peak force on the material (N); the spring's pull is capped here.
    pub max_force: f64,
    /// `gaussian`, `constant`, `spherical` or `table`.
    pub profile: String,
    /// Values for `profile = "table"`.
    pub table: Option<Vec<f64>>,
}

impl Default for RopeSpec {
    fn default() -> Self {
        Self {
            radius: 0.015,
            stiffness: 60.0,
            max_force: 3.0,
            profile: "gaussian".into(),
            table: None,
        }
    }
}

/// The paint brush (its radius grows with the force pressing on the surface).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct PaintSpec {
    /// sRGB colour.
    pub color: [u8; 3],
    /// Radius at zero force (m).
    pub radius: f64,
    /// Growth per newton (m/N).
    pub radius_per_newton: f64,
    /// Largest radius (m).
    pub max_radius: f64,
    /// `gaussian`, `constant` or `spherical`.
    pub falloff: String,
}

impl Default for PaintSpec {
    fn default() -> Self {
        Self {
            color: [220, 40, 40],
            radius: 0.004,
            radius_per_newton: 0.004,
            max_radius: 0.012,
            falloff: "spherical".into(),
        }
    }
}

/// The shaped probe (seed 004): an ellipsoid posed by the stylus.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProbeSpec {
    /// Semi-axes (m).
    pub semi_axes: [f64; 3],
    /// Contact stiffness per unit area (N/m³): what the user feels.
    pub surface_stiffness: f64,
    /// Contact damping per unit area (N·s/m³).
    pub surface_damping: f64,
    /// Stiffness of the springs that drive field values toward the probe's shape (N/m).
    pub sculpt_stiffness: f64,
    /// How the direction of the probe's force is found.
    pub direction: ProbeDirection,
}

/// How the direction of the probe's force is found (seed 004 §3.2.3; `sim_core::probe`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ProbeDirection {
    /// Depth-weighted mean of the surface normals under the probe: never reverses through a
    /// sheet, turns quickly over sharp edges.
    #[default]
    SurfaceNormal,
    /// Depth-weighted mean of the inward probe normals: smooth over edges, reverses when the
    /// probe's centre crosses the surface.
    ProbeNormal,
}

impl ProbeDirection {
    /// sim-core's method.
    pub fn method(self) -> sim_core::probe::DirectionMethod {
        match self {
            Self::SurfaceNormal => sim_core::probe::DirectionMethod::SurfaceNormal,
            Self::ProbeNormal => sim_core::probe::DirectionMethod::ProbeNormal,
        }
    }
}

impl Default for ProbeSpec {
    fn default() -> Self {
        Self {
            semi_axes: [0.008, 0.008, 0.008],
            surface_stiffness: 2e6,
            surface_damping: 20.0,
            sculpt_stiffness: 200.0,
            direction: ProbeDirection::SurfaceNormal,
        }
    }
}

/// Rendering.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderSpec {
    /// Image width (px).
    pub width: u32,
    /// Image height (px).
    pub height: u32,
    /// Direction the camera looks along (scene frame).
    pub view_dir: [f64; 3],
    /// Seconds between rendered frames of the rendering thread.
    pub interval_s: f64,
}

impl Default for RenderSpec {
    fn default() -> Self {
        Self {
            width: 1280,
            height: 720,
            view_dir: [-0.4, -0.5, -0.75],
            interval_s: 0.25,
        }
    }
}

/// One phase of a scripted session: a device stroke or an operation.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Phase {
    /// Shown in progress lines and the summary.
    pub name: String,
    /// A stroke of the stylus with the button pressed.
    pub stroke: Option<Stroke>,
    /// Or an operation of the `sculpt` script format (csg, emboss, paint, upsample…).
    pub op: Option<Op>,
}

/// A stroke: the hand moves (button up) to the first waypoint, presses, follows the waypoints
/// over `seconds`, releases, and rests `rest_s`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stroke {
    /// The tool the button engages.
    pub tool: ToolKind,
    /// Waypoints of the stylus tip in the scene frame (m).
    pub path: Vec<[f64; 3]>,
    /// Time along the path (s).
    pub seconds: f64,
    /// Time to travel to the first waypoint with the button up (s).
    #[serde(default = "default_travel")]
    pub travel_s: f64,
    /// Rest after the release (s).
    #[serde(default = "default_rest")]
    pub rest_s: f64,
}

fn default_travel() -> f64 {
    0.6
}
fn default_rest() -> f64 {
    0.4
}

fn err(field: impl Into<String>, reason: impl Into<String>) -> ScriptError {
    ScriptError {
        field: field.into(),
        reason: reason.into(),
    }
}

fn positive(field: &str, x: f64) -> Result<(), ScriptError> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(err(field, format!("must be positive and finite (got {x})")))
    }
}

fn non_negative(field: &str, x: f64) -> Result<(), ScriptError> {
    if x.is_finite() && x >= 0.0 {
        Ok(())
    } else {
        Err(err(field, format!("must be ≥ 0 and finite (got {x})")))
    }
}

impl SceneFile {
    /// Parse TOML and check every value and reference; errors name the field (or the line).
    pub fn parse(text: &str) -> Result<Self, ScriptError> {
        let scene: Self = toml::from_str(text).map_err(|e| {
            let span = e.span().map(|s| {
                let line = text[..s.start.min(text.len())].matches('\n').count() + 1;
                format!("line {line}")
            });
            err(
                span.unwrap_or_else(|| "scene".into()),
                e.message().to_string(),
            )
        })?;
        scene.validate()?;
        Ok(scene)
    }

    /// The `sculpt` script this scene's objects, region and operations make: its checks cover
    /// them, and its runner executes the operations.
    pub fn script(&self) -> Script {
        let mut region = self.region.clone();
        if region.node.is_none() {
            region.node = self
                .dynamic_object()
                .and_then(|o| o.material.as_ref())
                .and_then(|m| self.material.get(m))
                .copied();
        }
        Script {
            object: self.object.iter().map(|o| o.object_spec()).collect(),
            region: Some(region),
            op: self.phase.iter().filter_map(|p| p.op.clone()).collect(),
            mesh_resolution: self.mesh_resolution,
        }
    }

    /// TOML that [`SceneFile::parse`] reads back (without the phases: a saved scene is a
    /// starting point, not a replay).
    pub fn to_toml(&self) -> anyhow::Result<String> {
        Ok(toml::to_string(self)?)
    }

    /// The simulated object's entry.
    pub fn dynamic_object(&self) -> Option<&SceneObjectSpec> {
        self.object.iter().find(|o| o.name == self.region.object)
    }

    /// Check values and references.
    pub fn validate(&self) -> Result<(), ScriptError> {
        // Objects, region and operations: the sculpt script's checks, with operation indices
        // renamed to the phases they sit in.
        let op_phase: Vec<usize> = (0..self.phase.len())
            .filter(|&i| self.phase[i].op.is_some())
            .collect();
        self.script().validate().map_err(|mut e| {
            if let Some(rest) = e.field.strip_prefix("op[")
                && let Some((idx, tail)) = rest.split_once(']')
                && let Ok(i) = idx.parse::<usize>()
                && let Some(&p) = op_phase.get(i)
            {
                e.field = format!("phase[{p}].op{tail}");
            }
            e
        })?;
        let d = &self.device;
        positive("device.scale", d.scale)?;
        if !d
            .translation
            .iter()
            .chain(&d.rotation_deg)
            .all(|v| v.is_finite())
        {
            return Err(err("device", "translation and rotation_deg must be finite"));
        }
        for (i, o) in self.object.iter().enumerate() {
            if o.dynamic == Some(true) && o.name != self.region.object {
                return Err(err(
                    format!("object[{i}].dynamic"),
                    format!(
                        "one simulated object per session: the region's (`{}`)",
                        self.region.object
                    ),
                ));
            }
            if o.dynamic == Some(false) && o.name == self.region.object {
                return Err(err(
                    format!("object[{i}].dynamic"),
                    "the region's object is the simulated one",
                ));
            }
            if let Some(m) = &o.material {
                if !self.material.contains_key(m) {
                    return Err(err(
                        format!("object[{i}].material"),
                        format!("no [material.{m}] in the scene"),
                    ));
                }
                if o.name == self.region.object && self.region.node.is_some() {
                    return Err(err(
                        format!("object[{i}].material"),
                        "the region already sets `node`: give one or the other",
                    ));
                }
            }
        }
        for (name, m) in &self.material {
            m.validate()
                .map_err(|e| err(format!("material.{name}"), e.to_string()))?;
        }
        self.validate_tools()?;
        let r = &self.render;
        for (f, v) in [("render.width", r.width), ("render.height", r.height)] {
            if v == 0 || v > MAX_IMAGE_SIDE {
                return Err(err(f, format!("must be 1..={MAX_IMAGE_SIDE} (got {v})")));
            }
        }
        if DVec3::from(r.view_dir).try_normalize().is_none() {
            return Err(err("render.view_dir", "must be a finite non-zero vector"));
        }
        positive("render.interval_s", r.interval_s)?;
        if r.interval_s > 3600.0 {
            return Err(err("render.interval_s", "at most 3600 s"));
        }
        if self.mesh_resolution < 8 || self.mesh_resolution > 1024 {
            return Err(err("mesh_resolution", "must be 8..=1024"));
        }
        if self.phase.len() > MAX_PHASES {
            return Err(err(
                "phase",
                format!("at most {MAX_PHASES} phases (got {})", self.phase.len()),
            ));
        }
        for (i, p) in self.phase.iter().enumerate() {
            let f = |x: &str| format!("phase[{i}].{x}");
            match (&p.stroke, &p.op) {
                (Some(s), None) => {
                    if s.path.is_empty() || s.path.len() > MAX_STROKE_POINTS {
                        return Err(err(
                            f("stroke.path"),
                            format!("must hold 1..={MAX_STROKE_POINTS} points"),
                        ));
                    }
                    if !s.path.iter().flatten().all(|v| v.is_finite()) {
                        return Err(err(f("stroke.path"), "must be finite"));
                    }
                    positive(&f("stroke.seconds"), s.seconds)?;
                    if s.seconds > MAX_STROKE_SECONDS {
                        return Err(err(
                            f("stroke.seconds"),
                            format!("at most {MAX_STROKE_SECONDS} s"),
                        ));
                    }
                    positive(&f("stroke.travel_s"), s.travel_s)?;
                    non_negative(&f("stroke.rest_s"), s.rest_s)?;
                }
                (None, Some(_)) => {}
                _ => {
                    return Err(err(
                        format!("phase[{i}]"),
                        "give exactly one of `stroke` or `op`",
                    ));
                }
            }
        }
        Ok(())
    }

    fn validate_tools(&self) -> Result<(), ScriptError> {
        let t = &self.tools;
        positive("tools.contact.stiffness", t.contact.stiffness)?;
        non_negative("tools.contact.damping", t.contact.damping)?;
        non_negative("tools.contact.friction", t.contact.friction)?;
        positive("tools.rope.radius", t.rope.radius)?;
        positive("tools.rope.stiffness", t.rope.stiffness)?;
        positive("tools.rope.max_force", t.rope.max_force)?;
        crate::sculpt::script::profile_of(&t.rope.profile, t.rope.table.as_deref())
            .map_err(|e| err("tools.rope.profile", e))?;
        positive("tools.paint.radius", t.paint.radius)?;
        non_negative("tools.paint.radius_per_newton", t.paint.radius_per_newton)?;
        positive("tools.paint.max_radius", t.paint.max_radius)?;
        if t.paint.max_radius < t.paint.radius {
            return Err(err(
                "tools.paint.max_radius",
                "must be ≥ tools.paint.radius",
            ));
        }
        if !["gaussian", "constant", "spherical"].contains(&t.paint.falloff.as_str()) {
            return Err(err(
                "tools.paint.falloff",
                "must be gaussian, constant or spherical",
            ));
        }
        for (k, v) in t.probe.semi_axes.iter().enumerate() {
            positive(&format!("tools.probe.semi_axes[{k}]"), *v)?;
        }
        positive("tools.probe.surface_stiffness", t.probe.surface_stiffness)?;
        non_negative("tools.probe.surface_damping", t.probe.surface_damping)?;
        positive("tools.probe.sculpt_stiffness", t.probe.sculpt_stiffness)?;
        Ok(())
    }
}
