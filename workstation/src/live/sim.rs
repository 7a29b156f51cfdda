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
//! One job per file, arrows only into this one:
//! - here: the core's state, its construction and the snapshots it publishes;
//! - `stroke`: the tools (press, step, release; the tools are listed there);
//! - `edit`: operations between strokes (CSG, emboss, a primitive at the cursor, save scene);
//! - `settings`: [`Settings`] changed at run time;
//! - `save`: [`save`] the model's points and meshed zero set;
//! - `share`: what a shared scene takes from the simulation and gives it ([`SharedPoints`]);
//! - `driver`: the thread ([`run`]) and its messages ([`SimCommand`], [`SimReport`]);
//! - `tests`.

mod driver;
mod edit;
mod save;
mod settings;
mod share;
mod stroke;
#[cfg(test)]
mod tests;

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context as _;
use glam::DVec3;
use sim_core::FitParams;
use sim_core::grid::ScalarGrid;
use sim_core::probe::{Probe, SampleGrid, SurfaceSample};
use sim_core::scene::{ResampleOptions, Scene, SceneObject};

pub use driver::{Reply, SimCommand, SimReport, run};
pub use edit::MAX_PRIMITIVE_POINTS;
pub use save::{Saved, save};
pub use settings::Settings;
pub use share::SharedPoints;
pub use stroke::{MAX_CURVE_POINTS, StrokeReport};

use super::points::{ObjectPoints, PointPublisher};
use super::scene_file::{SceneFile, ToolKind};
use super::shared::{InputEvent, RenderSnapshot};
use stroke::Stroke;

/// Points follow the field every this many steps (500 Hz at 1 ms steps: far above any display
/// rate), after the field is published, so the force thread's snapshot never waits for them.
pub const FOLLOW_EVERY: u64 = 2;

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
    /// The renderer's chunks of the visible objects' points, and what changed since.
    publisher: PointPublisher,
    changed: Vec<u32>,
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
        let started = std::time::Instant::now();
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
        let spacing = spacings(&scene);
        let mut params = crate::sculpt::region_params(region);
        if region.resample != Some(false) {
            params.resample = Some(ResampleOptions::new(spacing[region_object]));
        }
        // Points follow only where the field moved by a visible fraction of their spacing:
        // the springs' far ripples would otherwise send every point of the region through
        // the follower at 500 Hz, O(region points) per step (see docs/BENCHMARKS.md, Big scans).
        params.follow.motion_epsilon = params
            .follow
            .motion_epsilon
            .max(FOLLOW_EPSILON_PER_SPACING * spacing[region_object]);
        let bounds = (DVec3::from(region.min), DVec3::from(region.max));
        scene
            .open_region(region_object, bounds.0, bounds.1, params)
            .context("opening the sculpting region")?;
        let points: usize = scene.objects().iter().map(|o| o.positions.len()).sum();
        tracing::info!(
            points,
            seconds = started.elapsed().as_secs_f64(),
            peak_rss_mib = crate::bigscan::peak_rss_kib() / 1024,
            "scene loaded and fitted"
        );
        Ok(Self {
            hidden: vec![false; names.len()],
            spacing,
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
            publisher: PointPublisher::new(),
            changed: Vec::new(),
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
    /// Scenes of more than [`SAMPLES_ALL_MAX`] points give only the sculpted object's points in
    /// the region near the cursor (within [`SAMPLES_AROUND_CURSOR_M`] plus the probe's size):
    /// the probe sculpts only there, and the samples are rebuilt 50 times a second while it
    /// does. Before the first cursor, the whole region.
    pub fn samples(&self) -> Option<SampleGrid> {
        let mut s = Vec::new();
        let reach = DVec3::from(self.file.tools.probe.semi_axes).max_element();
        let total: usize = self.visible().map(|o| o.positions.len()).sum();
        let sample = |o: &SceneObject, h: f64, i: usize| {
            Some(SurfaceSample {
                position: o.positions[i],
                normal: o.normals[i].try_normalize()?,
                area: h * h,
            })
        };
        match self.scene.region() {
            Some(region) if total > SAMPLES_ALL_MAX => {
                let (o, h) = (
                    &self.scene.objects()[region.object()],
                    self.spacing[region.object()],
                );
                let (mut lo, mut hi) = (self.bounds.0 - reach, self.bounds.1 + reach);
                if let Some(e) = self.last.filter(|e| e.position.is_finite()) {
                    let r = DVec3::splat(reach + SAMPLES_AROUND_CURSOR_M);
                    (lo, hi) = (lo.max(e.position - r), hi.min(e.position + r));
                }
                // The region's points, plus those within the probe's reach of its box: a scan
                // of the box's neighbourhood would be O(scene), so the region's list it is.
                s.extend(
                    region
                        .points_inside()
                        .iter()
                        .map(|&i| i as usize)
                        .filter(|&i| {
                            let p = o.positions[i];
                            p.cmpge(lo).all() && p.cmple(hi).all()
                        })
                        .filter_map(|i| sample(o, h, i)),
                );
            }
            _ => {
                let objects = self.scene.objects().iter().zip(&self.spacing);
                for ((o, &h), _) in objects.zip(&self.hidden).filter(|(_, hidden)| !**hidden) {
                    s.extend((0..o.positions.len()).filter_map(|i| sample(o, h, i)));
                }
            }
        }
        SampleGrid::new(&s, reach).ok()
    }

    /// Points for the renderer: chunks holding no point changed since the last snapshot are
    /// shared with it (the simulation reports the points it moved, appended or refilled).
    pub fn render_snapshot(&mut self) -> RenderSnapshot {
        self.changed.clear();
        if let Some(object) = self.scene.take_changed_points(&mut self.changed) {
            let slot = self.visible_slot(object);
            self.publisher
                .mark_many(slot, self.changed.iter().map(|&i| i as usize));
        }
        let objects: Vec<ObjectPoints<'_>> = self
            .scene
            .objects()
            .iter()
            .zip(&self.hidden)
            .filter(|(_, h)| !**h)
            .map(|(o, _)| ObjectPoints {
                positions: &o.positions,
                normals: &o.normals,
                colors: &o.colors,
            })
            .collect();
        RenderSnapshot {
            points: self.publisher.publish(&objects),
            region: Some(self.bounds),
            tool: Some(self.stroke.as_ref().map_or(self.selected, |s| s.tool)),
            region_object: Some(self.names[self.region_object].clone()),
            probe_semi_axes: Some(DVec3::from(self.file.tools.probe.semi_axes)),
            steps: self.steps,
        }
    }

    /// Where object `object` is among the visible ones (the publisher's numbering).
    fn visible_slot(&self, object: usize) -> usize {
        self.hidden[..object].iter().filter(|h| !**h).count()
    }

    /// Points changed outside the simulation's reports (an operation, a reopened region):
    /// the next snapshot copies every chunk.
    fn points_replaced(&mut self) {
        self.publisher.mark_all();
    }

    /// The tool selected for the next press.
    pub fn selected(&self) -> ToolKind {
        self.selected
    }
}

/// Above this many visible points, the probe's samples cover only the region's points near
/// the cursor ([`SimCore::samples`]).
pub const SAMPLES_ALL_MAX: usize = 50_000;

/// Points follow field changes larger than this fraction of their spacing (the follower's
/// `motion_epsilon`; a point's error from the zero set stays below twice that).
pub const FOLLOW_EPSILON_PER_SPACING: f64 = 0.02;

/// Half size of the box around the cursor whose points a big scene's probe samples hold,
/// beyond the probe's own reach (m): the samples are rebuilt every 20 ms while probing, and
/// a hand moves far less than this in that time.
pub const SAMPLES_AROUND_CURSOR_M: f64 = 0.02;

/// The median nearest-neighbour distance of each object's points (m, at least 1 µm), from at
/// most 20,000 of them.
fn spacings(scene: &Scene) -> Vec<f64> {
    scene
        .objects()
        .iter()
        .map(|o| sim_core::resample::spacing_sampled(&o.positions, 20_000).max(1e-6))
        .collect()
}
