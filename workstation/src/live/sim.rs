//! The simulation thread: device-driven tools on the scene, dynamics over the sculpting region,
//! snapshots out.
//!
//! [`SimCore`] is deterministic (no clock, no threads): [`SimCore::input`] consumes the force
//! thread's [`InputEvent`]s in order (a button press engages the selected tool at the cursor, a
//! release lets go and **commits** the shape: plastic, the sculpted field becomes the rest state),
//! [`SimCore::step`] applies the engaged tool and steps the region's field. The driver [`run`]
//! paces steps at the region's `dt`, publishes the field grid right after every field step,
//! *then* lets the points follow (every [`FOLLOW_EVERY`] steps), and publishes the surface
//! samples and the points for the renderer at their own rates.
//!
//! Tools (the papers' sessions):
//! - `rope`: press anywhere; the rope attaches at the surface point nearest the tip and pulls
//!   the surface along its normal by `k·(tip − picked)·n` (capped at `max_force`); the user
//!   feels the spring to the moving attachment.
//! - `rope_curve`: the tip's path while pressed, projected onto the (rest) surface, becomes the
//!   rope; it pulls by `k·(height of the tip above the surface)`, capped at `max_force`.
//! - `paint`: while pressed and touching, the brush paints at the contact point, its radius
//!   growing with the pressing force.
//! - `probe_push` / `probe_pull`: the shaped probe carves (difference) or, pressed inside the
//!   material, drags it out (union) as it moves; the user feels the probe against the samples.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use glam::DVec3;
use sim_core::FitParams;
use sim_core::csg::CsgOp;
use sim_core::dynamics::NodeParams;
use sim_core::grid::ScalarGrid;
use sim_core::probe::{Probe, ProbePose, SampleGrid, SurfaceSample};
use sim_core::scene::{Scene, SceneObject};
use sim_core::tools::paint::{Brush, paint};
use sim_core::tools::{GridTool, ProbeMode, ProbeSculpt, Profile, Rope};

use super::scene_file::{ContactSpec, SceneFile, SceneObjectSpec, ToolDefaults, ToolKind};
use super::shared::{ForceTool, InputEvent, RenderSnapshot, Shared};
use crate::sculpt::script::{Generate, Op, profile_of};

/// Points follow the field every this many steps (500 Hz at 1 ms steps: far above any display
/// rate), after the field is published, so the force thread's snapshot never waits for them.
pub const FOLLOW_EVERY: u64 = 2;

/// Most waypoints a curve rope keeps.
pub const MAX_CURVE_POINTS: usize = 64;

/// What one stroke did, for progress lines and the summary.
#[derive(Debug, Clone, serde::Serialize)]
pub struct StrokeReport {
    /// 0-based stroke number.
    pub index: usize,
    /// The tool.
    pub tool: ToolKind,
    /// Simulation steps while pressed.
    pub steps: u64,
    /// Largest change of the field value committed at release (m of signed distance).
    pub committed_displacement_m: f64,
    /// Points painted (paint).
    pub painted: usize,
    /// Largest force felt (N).
    pub max_force_n: f64,
    /// One line for people.
    pub summary: String,
}

enum Active {
    Rope {
        rope: Rope,
        picked: DVec3,
        normal: DVec3,
    },
    Paint {
        painted: usize,
    },
    Probe(ProbeSculpt),
    Touch,
}

struct Stroke {
    tool: ToolKind,
    active: Active,
    steps: u64,
    max_force: f64,
}

/// The deterministic simulation core; see the module doc.
pub struct SimCore {
    scene: Scene,
    names: Vec<String>,
    hidden: Vec<bool>,
    /// Typical point spacing of each object (m), for the probe samples' areas.
    spacing: Vec<f64>,
    region_object: usize,
    bounds: (DVec3, DVec3),
    params: sim_core::scene::RegionParams,
    file: SceneFile,
    dir: PathBuf,
    fit: FitParams,
    selected: ToolKind,
    queue: std::collections::VecDeque<ToolKind>,
    stroke: Option<Stroke>,
    last: Option<InputEvent>,
    strokes: Vec<StrokeReport>,
    steps: u64,
    probe: Probe,
}

impl std::fmt::Debug for SimCore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimCore")
            .field("objects", &self.names)
            .field("steps", &self.steps)
            .finish()
    }
}

impl SimCore {
    /// Load and fit the scene's objects and open the sculpting region; relative files resolve
    /// against `dir`.
    pub fn new(file: &SceneFile, dir: PathBuf) -> anyhow::Result<Self> {
        let fit = FitParams::default();
        let mut scene = Scene::new();
        let mut names = Vec::new();
        for spec in &file.object {
            let o = crate::sculpt::load_object(&spec.object_spec(), &dir, &fit)
                .with_context(|| format!("object `{}`", spec.name))?;
            scene.add(o);
            names.push(spec.name.clone());
        }
        let script = file.script();
        let region = script.region.as_ref().context("the scene has no region")?;
        let region_object = names
            .iter()
            .position(|n| *n == region.object)
            .context("region.object")?;
        let params = crate::sculpt::region_params(region);
        let bounds = (DVec3::from(region.min), DVec3::from(region.max));
        scene
            .open_region(region_object, bounds.0, bounds.1, params)
            .context("opening the sculpting region")?;
        Ok(Self {
            hidden: vec![false; names.len()],
            spacing: spacings(&scene),
            scene,
            names,
            region_object,
            bounds,
            params,
            dir,
            fit,
            selected: file.tools.selected,
            // A scripted session's strokes engage their tools in order, from the first press.
            queue: file
                .phase
                .iter()
                .filter_map(|p| p.stroke.as_ref().map(|s| s.tool))
                .collect(),
            stroke: None,
            last: None,
            strokes: Vec::new(),
            steps: 0,
            probe: Probe::ellipsoid(DVec3::from(file.tools.probe.semi_axes))?,
            file: file.clone(),
        })
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Object names, by index.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Objects still shown (not consumed by a CSG operation).
    pub fn visible(&self) -> impl Iterator<Item = &SceneObject> {
        self.scene
            .objects()
            .iter()
            .zip(&self.hidden)
            .filter(|(_, h)| !**h)
            .map(|(o, _)| o)
    }

    /// Strokes finished so far.
    pub fn strokes(&self) -> &[StrokeReport] {
        &self.strokes
    }

    /// Steps run.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The sculpting region box.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.bounds
    }

    /// Select the tool the button engages next.
    pub fn select(&mut self, tool: ToolKind) {
        self.selected = tool;
    }

    /// What the force thread should render now.
    pub fn force_tool(&self) -> ForceTool {
        let t = &self.file.tools;
        let probe = ForceTool::Probe(t.probe);
        match &self.stroke {
            Some(Stroke {
                tool,
                active:
                    Active::Rope {
                        rope,
                        picked,
                        normal,
                    },
                ..
            }) => {
                // A curve rope holds the surface where the tip last passed; a point rope where
                // it was picked.
                let (p, n) = match (tool, rope.path.last()) {
                    (ToolKind::RopeCurve, Some(&last)) => {
                        let field = &self.scene.objects()[self.region_object].field;
                        let n = field.value_and_gradient(last).1.try_normalize();
                        (last, n.unwrap_or(*normal))
                    }
                    _ => (*picked, *normal),
                };
                ForceTool::Rope {
                    anchor: self.attachment(p, n),
                    stiffness: t.rope.stiffness,
                    max_force: t.rope.max_force,
                }
            }
            Some(Stroke {
                active: Active::Probe(_),
                ..
            }) => probe,
            Some(_) => ForceTool::Touch(t.contact),
            // A queued tool is only engaged at its press; until then the selected one is felt
            // (switching the felt model under a resting stylus would kick it).
            None => match self.selected {
                ToolKind::ProbePush | ToolKind::ProbePull => probe,
                _ => ForceTool::Touch(t.contact),
            },
        }
    }

    /// Where the rope holds the surface now: the picked point moved along its normal to the
    /// current zero set.
    fn attachment(&self, picked: DVec3, normal: DVec3) -> DVec3 {
        let d = self
            .scene
            .region()
            .and_then(|r| {
                let m = r.model();
                let spec = m.spec();
                let (c, t) = spec.locate(picked)?;
                let up = |a: usize| c[a] + usize::from(t[a] > 0.5);
                Some(m.value(spec.index(up(0), up(1), up(2))))
            })
            .unwrap_or(0.0);
        picked - normal * d
    }

    /// The surface point nearest `x` on the region's object, with its outward normal. A
    /// projection that lands on an untrusted piece of the zero set (away from the points) is
    /// not the surface: the nearest point of the object is taken instead (once per press, so
    /// a scan is fine).
    fn nearest_surface(&self, x: DVec3) -> (DVec3, DVec3) {
        let o = &self.scene.objects()[self.region_object];
        let pr = o.field.project_to_zero_set(x);
        let p = if pr.trusted {
            pr.point
        } else {
            o.positions
                .iter()
                .copied()
                .min_by(|a, b| a.distance_squared(x).total_cmp(&b.distance_squared(x)))
                .unwrap_or(pr.point)
        };
        let n = o
            .field
            .value_and_gradient(p)
            .1
            .try_normalize()
            .unwrap_or(DVec3::Z);
        (p, n)
    }

    /// Consume one input event (in the order the force thread produced them).
    pub fn input(&mut self, e: &InputEvent) -> anyhow::Result<()> {
        let was = self.last.is_some_and(|l| l.pressed());
        if e.pressed() && !was {
            self.press(e);
        } else if !e.pressed() && was {
            self.release()?;
        }
        if let Some(s) = &mut self.stroke {
            s.max_force = s.max_force.max(e.force.length());
        }
        self.last = Some(*e);
        Ok(())
    }

    fn press(&mut self, e: &InputEvent) {
        let tool = self.queue.pop_front().unwrap_or(self.selected);
        let t = &self.file.tools;
        let active = match tool {
            ToolKind::Rope | ToolKind::RopeCurve => {
                let (picked, normal) = self.nearest_surface(e.position);
                let profile = profile_of(&t.rope.profile, t.rope.table.as_deref())
                    .unwrap_or(Profile::Gaussian);
                Active::Rope {
                    rope: Rope {
                        path: vec![picked],
                        radius: t.rope.radius,
                        strength: 0.0,
                        profile,
                        sheet: None,
                    },
                    picked,
                    normal,
                }
            }
            ToolKind::Paint => Active::Paint { painted: 0 },
            ToolKind::ProbePush | ToolKind::ProbePull => Active::Probe(ProbeSculpt {
                probe: self.probe,
                mode: if tool == ToolKind::ProbePush {
                    ProbeMode::Push
                } else {
                    ProbeMode::Pull
                },
                stiffness: t.probe.sculpt_stiffness,
            }),
            ToolKind::Touch => Active::Touch,
        };
        tracing::debug!(tool = tool.name(), at = ?e.position, "stroke begins");
        self.stroke = Some(Stroke {
            tool,
            active,
            steps: 0,
            max_force: 0.0,
        });
    }

    fn release(&mut self) -> anyhow::Result<()> {
        let Some(s) = self.stroke.take() else {
            return Ok(());
        };
        let committed = self.scene.region().map_or(0.0, |r| {
            r.model()
                .displacement()
                .iter()
                .fold(0.0, |a: f64, u| a.max(u.abs()))
        });
        let refitted = self.scene.end_stroke()?;
        let painted = match s.active {
            Active::Paint { painted } => painted,
            _ => 0,
        };
        let index = self.strokes.len();
        let summary = match s.tool {
            ToolKind::Paint => format!(
                "{painted} point colourings over {} steps, up to {:.2} N",
                s.steps, s.max_force
            ),
            ToolKind::Touch => format!("touched for {} steps, up to {:.2} N", s.steps, s.max_force),
            _ => format!(
                "{} steps, field changed by up to {:.2} mm and committed at release, {refitted} local fields refitted, up to {:.2} N felt",
                s.steps,
                committed * 1e3,
                s.max_force
            ),
        };
        self.strokes.push(StrokeReport {
            index,
            tool: s.tool,
            steps: s.steps,
            committed_displacement_m: committed,
            painted,
            max_force_n: s.max_force,
            summary,
        });
        Ok(())
    }

    /// One simulation step of `dt` with the engaged tool at the newest cursor.
    pub fn step(&mut self, dt: f64) -> anyhow::Result<()> {
        let t = self.file.tools.clone();
        let cursor = self.last;
        let mut tool: Option<&dyn GridTool> = None;
        if let (Some(s), Some(e)) = (&mut self.stroke, cursor) {
            s.steps += 1;
            match &mut s.active {
                Active::Rope {
                    rope,
                    picked,
                    normal,
                } => {
                    // Point rope: how far the tip is pulled out along the picked normal. Curve
                    // rope: how far the tip is above the (rest) surface where it is now.
                    let out = if s.tool == ToolKind::RopeCurve {
                        self.scene.objects()[self.region_object]
                            .field
                            .value(e.position)
                    } else {
                        (e.position - *picked).dot(*normal)
                    };
                    let pull = t.rope.stiffness * out;
                    rope.strength = pull.clamp(-t.rope.max_force, t.rope.max_force);
                    if s.tool == ToolKind::RopeCurve && rope.path.len() < MAX_CURVE_POINTS {
                        // The tip's path projected onto the rest surface becomes the rope.
                        let o = &self.scene.objects()[self.region_object];
                        let pr = o.field.project_to_zero_set(e.position);
                        let c = pr.point;
                        if pr.trusted
                            && c.is_finite()
                            && rope
                                .path
                                .last()
                                .is_some_and(|l| l.distance(c) > t.rope.radius * 0.5)
                        {
                            rope.path.push(c);
                        }
                    }
                    tool = Some(&*rope);
                }
                Active::Paint { painted } => {
                    if let Some((c, _)) = e.contact {
                        let brush = Brush {
                            color: t.paint.color,
                            radius: t.paint.radius,
                            radius_per_newton: t.paint.radius_per_newton,
                            max_radius: t.paint.max_radius,
                            falloff: profile_of(&t.paint.falloff, None)
                                .unwrap_or(Profile::Spherical),
                        };
                        let obj = self
                            .scene
                            .object_mut(self.region_object)
                            .expect("the region's object exists");
                        let r =
                            paint(&brush, c, e.force.length(), &obj.positions, &mut obj.colors)?;
                        *painted += r.painted;
                    }
                }
                Active::Probe(p) => {
                    p.probe.set_pose(ProbePose {
                        position: e.position,
                        orientation: e.orientation,
                    })?;
                    tool = Some(&*p);
                }
                Active::Touch => {}
            }
        }
        match tool {
            Some(t) => self.scene.step_field(dt, &[t])?,
            None => self.scene.step_field(dt, &[])?,
        };
        self.steps += 1;
        Ok(())
    }

    /// Let the points follow the field stepped since they last did.
    pub fn follow(&mut self) -> anyhow::Result<()> {
        self.scene.follow_points()?;
        Ok(())
    }

    /// The field snapshot for the force thread.
    pub fn publish_field(&mut self) -> Option<Arc<ScalarGrid>> {
        self.scene.publish()
    }

    /// Surface samples of the visible objects for the probe (each sample's area from its
    /// object's spacing, measured when the object was made: sculpting barely changes it).
    pub fn samples(&self) -> Option<SampleGrid> {
        let mut s = Vec::new();
        let objects = self.scene.objects().iter().zip(&self.spacing);
        for ((o, &h), _) in objects.zip(&self.hidden).filter(|(_, hidden)| !**hidden) {
            s.extend(o.positions.iter().zip(&o.normals).filter_map(|(&p, &n)| {
                Some(SurfaceSample {
                    position: p,
                    normal: n.try_normalize()?,
                    area: h * h,
                })
            }));
        }
        let cell = DVec3::from(self.file.tools.probe.semi_axes).max_element();
        SampleGrid::new(&s, cell).ok()
    }

    /// Points for the renderer.
    pub fn render_snapshot(&self) -> RenderSnapshot {
        let mut r = RenderSnapshot {
            region: Some(self.bounds),
            tool: Some(self.stroke.as_ref().map_or(self.selected, |s| s.tool)),
            region_object: Some(self.names[self.region_object].clone()),
            probe_semi_axes: Some(DVec3::from(self.file.tools.probe.semi_axes)),
            steps: self.steps,
            ..Default::default()
        };
        for o in self.visible() {
            r.positions.extend_from_slice(&o.positions);
            r.normals.extend_from_slice(&o.normals);
            r.colors.extend_from_slice(&o.colors);
        }
        r
    }

    /// Run a `sculpt` operation (CSG, emboss, paint, resampling…) between strokes. A CSG result
    /// replaces its inputs on screen; if it consumed the sculpted object the region moves to it.
    pub fn run_op(&mut self, op: &Op) -> anyhow::Result<(&'static str, String)> {
        if self.stroke.is_some() {
            self.release()?;
        }
        self.scene.close_region()?;
        let before = self.names.len();
        let dt = self.file.region.dt;
        let result = crate::sculpt::ops::run_op(
            &mut self.scene,
            &mut self.names,
            op,
            dt,
            &self.dir,
            &self.fit,
        );
        self.hidden.resize(self.names.len(), false);
        self.spacing = spacings(&self.scene);
        if let Op::Csg { a, b, .. } = op
            && self.names.len() > before
        {
            let result = self.names.len() - 1;
            for n in [a, b] {
                if let Some(i) = self.names.iter().position(|x| x == n) {
                    self.hidden[i] = true;
                    if i == self.region_object {
                        self.region_object = result;
                    }
                }
            }
        }
        // Reopened whether or not the operation worked: a failed one leaves the scene as it was.
        self.scene.open_region(
            self.region_object,
            self.bounds.0,
            self.bounds.1,
            self.params,
        )?;
        result
    }

    /// The settings in force.
    pub fn settings(&self) -> Settings {
        Settings::of(&self.file)
    }

    /// The tool selected for the next press.
    pub fn selected(&self) -> ToolKind {
        self.selected
    }

    /// Change tools, material, integrator or step at run time. The values are checked as a
    /// scene file's are (errors name the field, e.g. `tools.rope.stiffness`); on error nothing
    /// changes. Tool settings apply from the next press (the force thread's from the next
    /// published tool); a new material, integrator or step lets go of an engaged stroke and
    /// reopens the region over the current shape.
    pub fn configure(&mut self, s: &Settings) -> anyhow::Result<()> {
        let mut file = self.file.clone();
        file.tools = ToolDefaults {
            selected: file.tools.selected,
            ..s.tools.clone()
        };
        file.region.node = Some(s.material);
        file.region.integrator.clone_from(&s.integrator);
        file.region.dt = s.dt;
        file.validate()?;
        let probe = Probe::ellipsoid(DVec3::from(file.tools.probe.semi_axes))?;
        let region = file.script().region.context("the scene has no region")?;
        let params = crate::sculpt::region_params(&region);
        if Settings::of(&self.file).region_part() != s.region_part() {
            if self.stroke.is_some() {
                self.release()?;
            }
            self.scene.close_region()?;
            self.scene
                .open_region(self.region_object, self.bounds.0, self.bounds.1, params)?;
            self.params = params;
        }
        self.file = file;
        self.probe = probe;
        Ok(())
    }

    /// Add a primitive at `at` and combine it with the sculpted object: `Difference` carves it
    /// out, `Union` adds it, `Intersection` keeps the overlap. The primitive is sampled at about
    /// the sculpted object's spacing.
    pub fn csg_primitive(
        &mut self,
        op: CsgOp,
        shape: &str,
        size: f64,
        at: DVec3,
    ) -> anyhow::Result<(&'static str, String)> {
        anyhow::ensure!(at.is_finite(), "the cursor is not in the scene yet");
        anyhow::ensure!(
            size.is_finite() && size > 0.0,
            "primitive size must be positive (got {size})"
        );
        let h = self.spacing[self.region_object];
        let area = match shape {
            "sphere" => 4.0 * std::f64::consts::PI * size * size,
            "box" => 24.0 * size * size,
            other => anyhow::bail!("unknown primitive `{other}` (sphere, box)"),
        };
        let points = ((area / (h * h)) as usize).clamp(200, MAX_PRIMITIVE_POINTS);
        let n = self.names.len();
        let name = format!("{shape}_{n}");
        let spec = SceneObjectSpec {
            name: name.clone(),
            file: None,
            generate: Some(Generate {
                shape: shape.into(),
                size,
                size2: if shape == "box" { 0.1 * size } else { 0.0 },
                points,
                seed: n as u64,
            }),
            offset: at.to_array(),
            dynamic: Some(false),
            material: None,
        };
        let object = crate::sculpt::load_object(&spec.object_spec(), &self.dir, &self.fit)?;
        self.scene.add(object);
        self.names.push(name.clone());
        self.hidden.push(true); // an operand: consumed by the operation below
        self.spacing = spacings(&self.scene);
        let a = self.names[self.region_object].clone();
        self.run_op(&Op::Csg {
            op,
            a,
            b: name,
            result: format!("csg_{n}"),
        })
    }

    /// Write the visible objects as `<name>.ply` and a `scene.toml` that loads them with this
    /// session's region, materials and settings into `dir`; returns the scene file's path.
    pub fn save_scene(&self, dir: &std::path::Path) -> anyhow::Result<PathBuf> {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let mut file = self.file.clone();
        file.object.clear();
        for ((o, name), _) in self
            .scene
            .objects()
            .iter()
            .zip(&self.names)
            .zip(&self.hidden)
            .filter(|(_, h)| !**h)
        {
            let path = dir.join(format!("{name}.ply"));
            let points = sim_core::PointSet {
                positions: o.positions.clone(),
                normals: Some(o.normals.clone()),
                colors: Some(o.colors.clone()),
            };
            let f = std::fs::File::create(&path)
                .with_context(|| format!("creating {}", path.display()))?;
            sim_core::io::write_points_ply(std::io::BufWriter::new(f), &points, false)?;
            let spec = self.file.object.iter().find(|s| s.name == *name);
            file.object.push(SceneObjectSpec {
                name: name.clone(),
                file: Some(format!("{name}.ply")),
                generate: None,
                offset: [0.0; 3],
                dynamic: Some(*name == self.names[self.region_object]),
                material: spec.and_then(|s| s.material.clone()),
            });
        }
        file.region.object = self.names[self.region_object].clone();
        file.tools.selected = self.selected;
        let path = dir.join("scene.toml");
        std::fs::write(&path, file.to_toml()?)
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(path)
    }

    /// Whether a stroke is engaged.
    pub fn engaged(&self) -> bool {
        self.stroke.is_some()
    }

    /// Let go of an engaged stroke as if the button were released (the session dropped).
    pub fn release_engaged(&mut self) -> anyhow::Result<()> {
        if let Some(mut e) = self.last {
            e.buttons &= !1;
            self.input(&e)?;
        }
        Ok(())
    }
}

/// The median nearest-neighbour distance of each object's points (m, at least 1 µm).
fn spacings(scene: &Scene) -> Vec<f64> {
    scene
        .objects()
        .iter()
        .map(|o| sim_core::resample::spacing(&o.positions).max(1e-6))
        .collect()
}

/// The most points a CSG primitive from the panel is sampled with.
pub const MAX_PRIMITIVE_POINTS: usize = 40_000;

/// What can change while a session runs (the window's panel): tools, material, integrator and
/// step.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Contact, rope, paint and probe settings (`selected` is not used: see
    /// [`SimCommand::Select`]).
    pub tools: ToolDefaults,
    /// The sculpted material's node parameters.
    pub material: NodeParams,
    /// `symplectic_euler`, `forward_euler` or `backward_euler`.
    pub integrator: String,
    /// Simulation step (s).
    pub dt: f64,
}

impl Settings {
    /// A scene file's settings.
    pub fn of(file: &SceneFile) -> Self {
        let region = file.script().region;
        Self {
            tools: file.tools.clone(),
            material: region.as_ref().and_then(|r| r.node).unwrap_or_default(),
            integrator: file.region.integrator.clone(),
            dt: file.region.dt,
        }
    }

    fn region_part(&self) -> (NodeParams, &str, f64) {
        (self.material, &self.integrator, self.dt)
    }
}

/// A reply channel of a [`SimCommand`].
pub type Reply<T> = mpsc::Sender<anyhow::Result<T>>;

/// Requests to the simulation thread from the session driver or the window.
#[derive(Debug)]
pub enum SimCommand {
    /// Select the tool for later presses.
    Select(ToolKind),
    /// Change settings ([`SimCore::configure`]).
    Configure(Box<Settings>, Reply<()>),
    /// Combine a primitive with the sculpted object ([`SimCore::csg_primitive`]).
    CsgPrimitive {
        /// The operation.
        op: CsgOp,
        /// `sphere` or `box`.
        shape: String,
        /// Radius or half size (m).
        size: f64,
        /// Where (scene m).
        at: DVec3,
        /// The answer.
        reply: Reply<(&'static str, String)>,
    },
    /// Save the model and its meshed zero set ([`super::save`]) into a directory.
    Save(PathBuf, Reply<super::Saved>),
    /// Save a scene file that reloads this model ([`SimCore::save_scene`]) into a directory.
    SaveScene(PathBuf, Reply<PathBuf>),
    /// Run an operation; the answer comes back on the channel.
    Op(Box<Op>, Reply<(&'static str, String)>),
    /// Hand the core over (at the end of a session, for saving).
    Finish(mpsc::Sender<SimCore>),
}

/// Messages from the simulation thread.
#[derive(Debug, Clone)]
pub enum SimReport {
    /// A stroke ended.
    Stroke(StrokeReport),
    /// The simulation failed and stopped.
    Failed(String),
}

/// Snapshots the simulation replaced, held one more round (see [`run`]).
#[derive(Default)]
struct Retired {
    field: Option<Arc<ScalarGrid>>,
    samples: Option<Arc<SampleGrid>>,
    tool: Option<Arc<ForceTool>>,
}

/// The thread body: paces steps at `dt`, until told to finish or `shared` says stop.
pub fn run(
    mut core: SimCore,
    mut events: rtrb::Consumer<InputEvent>,
    commands: mpsc::Receiver<SimCommand>,
    reports: mpsc::Sender<SimReport>,
    shared: Arc<Shared>,
) {
    let mut dt = core.file.region.dt;
    let render_every = Duration::from_secs_f64(core.file.render.interval_s.min(0.1));
    let samples_every = Duration::from_millis(20);
    let mut period = Duration::from_secs_f64(dt);
    let (mut last_render, mut last_samples) = (Instant::now() - render_every, Instant::now());
    let mut next = Instant::now();
    let mut loop_clock = super::force::LoopTimer::new();
    let mut field_clock = super::force::LoopTimer::new();
    // Snapshots replaced here are kept until the next replacement, so their memory is freed on
    // this thread, not on the force thread when it drops its last guard.
    let mut retired = Retired {
        samples: shared.samples.swap(core.samples().map(Arc::new)),
        ..Retired::default()
    };
    let fail = |e: anyhow::Error, reports: &mpsc::Sender<SimReport>| {
        tracing::error!("simulation stopped: {e:#}");
        // Nothing to feel from a dead simulation: no field, no tool spring.
        shared.field.store(None);
        shared
            .tool
            .store(Arc::new(ForceTool::Touch(ContactSpec::default())));
        let _ = reports.send(SimReport::Failed(format!("{e:#}")));
    };
    while !shared.stopping() {
        while let Ok(cmd) = commands.try_recv() {
            match cmd {
                SimCommand::Select(t) => {
                    core.select(t);
                    shared.render.store(Some(Arc::new(core.render_snapshot())));
                }
                SimCommand::Configure(s, reply) => {
                    let r = core.configure(&s);
                    (dt, period) = (
                        core.file.region.dt,
                        Duration::from_secs_f64(core.file.region.dt),
                    );
                    retired.samples = shared.samples.swap(core.samples().map(Arc::new));
                    shared.render.store(Some(Arc::new(core.render_snapshot())));
                    let _ = reply.send(r);
                }
                SimCommand::Op(op, reply) => {
                    let r = core.run_op(&op);
                    retired.samples = shared.samples.swap(core.samples().map(Arc::new));
                    shared.render.store(Some(Arc::new(core.render_snapshot())));
                    let _ = reply.send(r);
                }
                SimCommand::CsgPrimitive {
                    op,
                    shape,
                    size,
                    at,
                    reply,
                } => {
                    let r = core.csg_primitive(op, &shape, size, at);
                    retired.samples = shared.samples.swap(core.samples().map(Arc::new));
                    shared.render.store(Some(Arc::new(core.render_snapshot())));
                    let _ = reply.send(r);
                }
                SimCommand::Save(dir, reply) => {
                    let _ = reply.send(super::save(&core, &dir, core.file.mesh_resolution));
                }
                SimCommand::SaveScene(dir, reply) => {
                    let _ = reply.send(core.save_scene(&dir));
                }
                SimCommand::Finish(reply) => {
                    let _ = reply.send(core);
                    return;
                }
            }
        }
        let start = Instant::now();
        let strokes = core.strokes().len();
        while let Ok(e) = events.pop() {
            if let Err(e) = core.input(&e) {
                return fail(e, &reports);
            }
        }
        // The session dropped mid-stroke: let go rather than keep acting at a stale cursor.
        if core.engaged()
            && !shared.net.connected.load(Ordering::Acquire)
            && let Err(e) = core.release_engaged()
        {
            return fail(e, &reports);
        }
        if let Err(e) = core.step(dt) {
            return fail(e, &reports);
        }
        retired.field = shared.field.swap(core.publish_field());
        let tool = core.force_tool();
        // The probe feels samples that move only while it sculpts (and at releases, below).
        let probing = core.engaged() && matches!(tool, ForceTool::Probe { .. });
        if **shared.tool.load() != tool {
            retired.tool = Some(shared.tool.swap(Arc::new(tool)));
        }
        field_clock.tick(start, Instant::now(), &shared.field_loop);
        if core.steps().is_multiple_of(FOLLOW_EVERY)
            && let Err(e) = core.follow()
        {
            return fail(e, &reports);
        }
        for s in &core.strokes()[strokes..] {
            let _ = reports.send(SimReport::Stroke(s.clone()));
        }
        let now = Instant::now();
        if core.strokes().len() > strokes
            || (probing && now.duration_since(last_samples) >= samples_every)
        {
            retired.samples = shared.samples.swap(core.samples().map(Arc::new));
            last_samples = now;
        }
        if now.duration_since(last_render) >= render_every {
            shared.render.store(Some(Arc::new(core.render_snapshot())));
            last_render = now;
        }
        loop_clock.tick(start, Instant::now(), &shared.sim_loop);
        shared.sim_steps.store(core.steps(), Ordering::Relaxed);
        // Pace at dt: sleep to the next deadline; a step that ran long is caught up by the
        // following ones (no sleep) unless it fell more than 5 steps behind, then the clock
        // restarts (simulated time then runs slower than wall time, never in a burst).
        next += period;
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        } else if now - next > 5 * period {
            next = now;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    fn core(selected: &str) -> SimCore {
        let scene = SceneFile::parse(&format!(
            r#"
[[object]]
name = "ball"
generate = {{ shape = "sphere", size = 0.05, points = 2000, seed = 2 }}
[region]
object = "ball"
min = [-0.05, 0.0, -0.05]
max = [0.05, 0.06, 0.05]
spacing = 0.0025
band = 0.008
[tools]
selected = "{selected}"
rope = {{ radius = 0.01, stiffness = 60.0, max_force = 3.0 }}
"#
        ))
        .unwrap();
        SimCore::new(&scene, ".".into()).unwrap()
    }

    fn at(p: DVec3, buttons: u16) -> InputEvent {
        InputEvent {
            position: p,
            velocity: DVec3::ZERO,
            orientation: DQuat::IDENTITY,
            buttons,
            force: DVec3::ZERO,
            contact: None,
        }
    }

    fn lift_near(core: &SimCore, c: DVec3) -> f64 {
        core.scene().objects()[0]
            .positions
            .iter()
            .filter(|p| p.distance(c) < 0.006)
            .map(|p| p.length() - 0.05)
            .fold(f64::NEG_INFINITY, f64::max)
    }

    #[test]
    fn a_curve_rope_pulls_along_the_tips_path_and_the_shape_stays() {
        let mut c = core("rope_curve");
        // Press above the surface, slide 4 cm over it 8 mm out, release.
        let (a, b) = (DVec3::new(-0.02, 0.05, 0.0), DVec3::new(0.02, 0.05, 0.0));
        let to_surface = |p: DVec3| p.normalize() * 0.058;
        c.input(&at(to_surface(a), 1)).unwrap();
        for k in 0..=400 {
            let p = to_surface(a.lerp(b, k as f64 / 400.0));
            c.input(&at(p, 1)).unwrap();
            c.step(1e-3).unwrap();
            if k % 2 == 0 {
                c.follow().unwrap();
            }
        }
        c.input(&at(to_surface(b), 0)).unwrap();
        for _ in 0..50 {
            c.step(1e-3).unwrap();
        }
        c.follow().unwrap();
        assert_eq!(c.strokes().len(), 1);
        // Both ends and the middle of the path rose, not only where it was pressed.
        for x in [-0.02, 0.0, 0.02] {
            let p = DVec3::new(x, 0.05, 0.0).normalize() * 0.05;
            let lift = lift_near(&c, p);
            assert!(
                lift > 1e-3,
                "surface under the curve at x = {x}: {lift:e} m"
            );
        }
    }

    #[test]
    fn settings_change_at_run_time_and_bad_ones_name_the_field() {
        let mut c = core("touch");
        let mut s = c.settings();
        s.tools.rope.stiffness = 120.0;
        s.tools.probe.semi_axes = [0.004, 0.004, 0.006];
        c.configure(&s).unwrap();
        assert_eq!(c.settings().tools.rope.stiffness, 120.0);
        c.select(ToolKind::ProbePush);
        assert_eq!(c.force_tool(), ForceTool::Probe(s.tools.probe));
        // A new material, integrator and step reopen the region; stepping goes on.
        s.material.stiffness = 20.0;
        s.integrator = "backward_euler".into();
        s.dt = 2e-3;
        c.configure(&s).unwrap();
        c.step(2e-3).unwrap();
        assert!(c.publish_field().is_some());
        assert_eq!(c.settings(), s);
        let mut bad = s.clone();
        bad.tools.rope.stiffness = -1.0;
        let e = c.configure(&bad).unwrap_err();
        assert!(format!("{e:#}").contains("tools.rope.stiffness"), "{e:#}");
        assert_eq!(c.settings(), s, "nothing changed");
    }

    #[test]
    fn a_primitive_carves_at_the_cursor_and_a_saved_scene_reloads_the_result() {
        let mut c = core("touch");
        let top = DVec3::new(0.0, 0.05, 0.0);
        let (kind, _) = c
            .csg_primitive(CsgOp::Difference, "sphere", 0.01, top)
            .unwrap();
        assert_eq!(kind, "csg");
        let near = c
            .visible()
            .flat_map(|o| o.positions.iter())
            .filter(|p| p.distance(top) < 0.007)
            .count();
        assert_eq!(near, 0, "points left inside the carved sphere");
        assert!(c.csg_primitive(CsgOp::Union, "cone", 0.01, top).is_err());
        assert!(
            c.csg_primitive(CsgOp::Union, "sphere", 0.01, DVec3::NAN)
                .is_err()
        );
        let dir = std::env::temp_dir().join(format!("ws-save-scene-{}", std::process::id()));
        let path = c.save_scene(&dir).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let scene = SceneFile::parse(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
        let again = SimCore::new(&scene, dir.clone()).unwrap();
        let count = |c: &SimCore| c.visible().map(|o| o.positions.len()).sum::<usize>();
        assert_eq!(count(&again), count(&c));
        assert_eq!(again.settings(), c.settings());
        let _ = std::fs::remove_dir_all(dir);
    }

    #[test]
    fn a_failed_operation_leaves_the_scene_usable() {
        let mut c = core("touch");
        let bad: Op = toml::from_str(
            "kind = \"csg\"\nop = \"union\"\na = \"ball\"\nb = \"nothing\"\nresult = \"r\"",
        )
        .unwrap();
        assert!(c.run_op(&bad).is_err());
        c.step(1e-3).unwrap();
        assert!(c.publish_field().is_some(), "the region is open again");
    }
}
