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

use glam::DVec3;
use sim_core::FitParams;
use sim_core::grid::ScalarGrid;
use sim_core::probe::{Probe, ProbePose, SampleGrid, SurfaceSample};
use sim_core::scene::{Scene, SceneObject};
use sim_core::tools::paint::{Brush, paint};
use sim_core::tools::{GridTool, ProbeMode, ProbeSculpt, Profile, Rope};

use super::scene_file::{SceneFile, ToolKind};
use super::shared::{ForceTool, InputEvent, RenderSnapshot, Shared};
use crate::sculpt::script::{Op, profile_of};

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
        use anyhow::Context as _;
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
        let probe = ForceTool::Probe {
            semi_axes: DVec3::from(t.probe.semi_axes),
        };
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
            Some(_) => ForceTool::Touch,
            // A queued tool is only engaged at its press; until then the selected one is felt
            // (switching the felt model under a resting stylus would kick it).
            None => match self.selected {
                ToolKind::ProbePush | ToolKind::ProbePull => probe,
                _ => ForceTool::Touch,
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

    /// The surface point nearest `x` on the region's object, with its outward normal.
    fn nearest_surface(&self, x: DVec3) -> (DVec3, DVec3) {
        let o = &self.scene.objects()[self.region_object];
        let p = o.field.project_to_zero_set(x).point;
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
                        let c = o.field.project_to_zero_set(e.position).point;
                        if c.is_finite()
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

/// Requests to the simulation thread from the session driver.
#[derive(Debug)]
pub enum SimCommand {
    /// Select the tool for later presses.
    Select(ToolKind),
    /// Run an operation; the answer comes back on the channel.
    Op(
        Box<Op>,
        mpsc::Sender<anyhow::Result<(&'static str, String)>>,
    ),
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
    let dt = core.file.region.dt;
    let render_every = Duration::from_secs_f64(core.file.render.interval_s.min(0.1));
    let samples_every = Duration::from_millis(20);
    let period = Duration::from_secs_f64(dt);
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
        shared.tool.store(Arc::new(ForceTool::Touch));
        let _ = reports.send(SimReport::Failed(format!("{e:#}")));
    };
    while !shared.stopping() {
        while let Ok(cmd) = commands.try_recv() {
            match cmd {
                SimCommand::Select(t) => core.select(t),
                SimCommand::Op(op, reply) => {
                    let r = core.run_op(&op);
                    retired.samples = shared.samples.swap(core.samples().map(Arc::new));
                    shared.render.store(Some(Arc::new(core.render_snapshot())));
                    let _ = reply.send(r);
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
