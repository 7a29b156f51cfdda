//! Scenes: many objects, one sculpting region (DESIGN §3, "model only what a scene needs").
//!
//! Contract: only the object being sculpted, and only inside its region box, is simulated: the
//! region's [`DynamicGrid`] covers the box, its band covers the surface, and per-step work is
//! O(band nodes + points near nodes whose value changed). Static objects keep their fitted
//! fields and are never touched; points of the sculpted object outside the box stay bit-for-bit
//! unchanged. [`Scene::step`] either completes or leaves the model unchanged (rollback, see
//! [`crate::dynamics::Stepper`]); after warm-up it allocates only when the follower rebuckets
//! its points (see [`crate::follow::Follower`]).

use std::sync::Arc;

use glam::DVec3;

use crate::dynamics::{
    DynamicGrid, DynamicsError, Integrator, NodeParams, StepError, StepReport, Stepper,
};
use crate::field::GlobalField;
use crate::field::{NoProgress, Progress};
use crate::follow::{
    FollowOptions, FollowReport, Follower, apply_refit, refit_moved, refit_samples,
};
use crate::grid::{GridError, GridSpec, ScalarGrid};
use crate::local_fit::FitParams;
use crate::pointset::PointSet;
use crate::reconstruct::{IgnoreStages, NormalPolicy, ReconstructError, reconstruct};
use crate::resample::{UpsampleOptions, upsample_at};
use crate::tools::{GridTool, Rope, ToolError};

mod edit;
mod resample;

pub use resample::{MAX_PROJECTION, ResampleOptions, ResampleReport};

/// One object: its points (positions, unit normals, colours) and its implicit field.
#[derive(Debug, Clone)]
pub struct SceneObject {
    /// Name for scripts and reports.
    pub name: String,
    /// Positions (m).
    pub positions: Vec<DVec3>,
    /// Outward unit normals.
    pub normals: Vec<DVec3>,
    /// sRGB colours.
    pub colors: Vec<[u8; 3]>,
    /// The fitted field (updated by refits at the end of strokes).
    pub field: GlobalField,
}

impl SceneObject {
    /// Colour of points that arrive without one.
    pub const DEFAULT_COLOR: [u8; 3] = [200, 200, 200];

    /// Fit `points` into an object: given normals are kept (missing ones estimated), missing
    /// colours become [`SceneObject::DEFAULT_COLOR`].
    pub fn fit(
        name: impl Into<String>,
        points: PointSet,
        fit: &FitParams,
    ) -> Result<Self, ReconstructError> {
        Self::fit_reporting(name, points, fit, &NoProgress)
    }

    /// [`SceneObject::fit`], reporting the fit's progress (as `reconstruct` does, up to the
    /// number of points) to `progress`: a big scan takes seconds.
    pub fn fit_reporting(
        name: impl Into<String>,
        points: PointSet,
        fit: &FitParams,
        progress: &dyn Progress,
    ) -> Result<Self, ReconstructError> {
        let rec = reconstruct(
            &points,
            fit,
            NormalPolicy::Keep,
            &mut IgnoreStages,
            progress,
        )?;
        let n = points.positions.len();
        Ok(Self {
            name: name.into(),
            colors: points
                .colors
                .unwrap_or_else(|| vec![Self::DEFAULT_COLOR; n]),
            positions: points.positions,
            normals: rec.normals,
            field: rec.field,
        })
    }
}

/// How a sculpting region is simulated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionParams {
    /// Grid spacing (m).
    pub spacing: f64,
    /// Band half-width around the surface (m): nodes with `|d⁰| ≤ band` are simulated.
    pub band: f64,
    /// Initial parameters of every node.
    pub node: NodeParams,
    /// Time integrator.
    pub integrator: Integrator,
    /// Refit moved points' local fields every step (`false`: only at [`Scene::end_stroke`]).
    pub refit_every_step: bool,
    /// Points follow every this many steps (≥ 1), over the accumulated time: the field runs at
    /// the haptic rate, points at a display rate. [`Scene::end_stroke`] catches up first.
    pub follow_every: u32,
    /// How points follow.
    pub follow: FollowOptions,
    /// Up-sample at the end of each stroke around the moved points where the largest empty
    /// tangent circle is wider than this (m); `None`: never. Inserted points lie on the refitted
    /// field and carry no local field until [`Scene::refit`].
    pub auto_upsample: Option<f64>,
    /// Resample the region's changed points at the end of each stroke (project or remove
    /// points off the surface, merge crowded ones, fill holes; see [`ResampleOptions`]);
    /// `None`: never.
    pub resample: Option<ResampleOptions>,
    /// The band follows the surface ([`DynamicGrid::grow_band`] after every step, margin one
    /// grid cell): a stroke that carries the surface towards the band's edge extends the band
    /// instead of being cut flat there. `false`: the band stays where the region opened it.
    pub band_follows: bool,
}

impl RegionParams {
    /// Defaults around a spacing and band: default nodes, symplectic Euler (stable to ≈ 2.5 ms
    /// with default nodes), refit at the end of strokes, points following every step.
    pub fn new(spacing: f64, band: f64) -> Self {
        Self {
            spacing,
            band,
            node: NodeParams::default(),
            integrator: Integrator::SymplecticEuler,
            refit_every_step: false,
            follow_every: 1,
            follow: FollowOptions::default(),
            auto_upsample: None,
            resample: None,
            band_follows: true,
        }
    }
}

/// Why a scene operation failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SceneError {
    /// No object has this index.
    #[error("no object {0}")]
    NoObject(usize),
    /// No sculpting region is open.
    #[error("no sculpting region is open")]
    NoRegion,
    /// The region box or spacing is invalid.
    #[error(transparent)]
    Grid(#[from] GridError),
    /// The model could not be built.
    #[error(transparent)]
    Dynamics(#[from] DynamicsError),
    /// A tool was invalid.
    #[error(transparent)]
    Tool(#[from] ToolError),
    /// The step was refused and rolled back.
    #[error(transparent)]
    Step(#[from] StepError),
    /// Refitting an object failed.
    #[error(transparent)]
    Fit(#[from] ReconstructError),
}

/// The simulated part of a scene.
#[derive(Debug, Clone)]
pub struct Region {
    object: usize,
    bounds: (DVec3, DVec3),
    model: DynamicGrid,
    stepper: Stepper,
    /// The object's field when the stroke began (`None` only inside `end_stroke`).
    base: Option<GlobalField>,
    inside: Vec<u32>,
    follower: Follower,
    samples: Vec<f64>,
    pending_dt: f64,
    steps: u64,
    params: RegionParams,
    last_resample: ResampleReport,
}

impl Region {
    /// Replace the resampling a commit does ([`RegionParams::resample`]; `None`: none).
    pub fn set_resample(&mut self, resample: Option<ResampleOptions>) {
        self.params.resample = resample;
    }

    /// What the last commit's resampling did.
    pub fn last_resample(&self) -> ResampleReport {
        self.last_resample
    }

    /// The dynamic model.
    pub fn model(&self) -> &DynamicGrid {
        &self.model
    }

    /// The dynamic model, for editing node parameters or adding forces directly.
    pub fn model_mut(&mut self) -> &mut DynamicGrid {
        &mut self.model
    }

    /// Index of the sculpted object.
    pub fn object(&self) -> usize {
        self.object
    }

    /// Points of the object inside the region box.
    pub fn points_inside(&self) -> &[u32] {
        &self.inside
    }

    /// Let the points follow over the time accumulated since they last did.
    fn catch_up(&mut self, obj: &mut SceneObject) -> FollowReport {
        let dt = std::mem::take(&mut self.pending_dt);
        if dt == 0.0 {
            return FollowReport::default();
        }
        let base = self
            .base
            .as_ref()
            .expect("an open region has its base field");
        self.follower.follow(
            base,
            &self.model,
            &self.inside,
            &mut obj.positions,
            &mut obj.normals,
            dt,
        )
    }

    /// Heap bytes of the simulation state (model + region bookkeeping).
    pub fn memory_bytes(&self) -> usize {
        self.model.memory_bytes()
            + self.inside.capacity() * 4
            + self.follower.memory_bytes()
            + self.samples.capacity() * 8
    }
}

/// The stages of [`Scene::step_observed`], in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SculptStage {
    /// Forces cleared and tools applied.
    Tools,
    /// The integrator step.
    Integrate,
    /// Points followed the field.
    Follow,
    /// Local fields refitted (only with `refit_every_step`).
    Refit,
}

/// Told when each stage of a step ends (the workstation times stages with it; sim-core reads
/// no clock).
pub trait StepObserver {
    /// `stage` just finished.
    fn stage_done(&mut self, stage: SculptStage);
}

impl StepObserver for () {
    fn stage_done(&mut self, _stage: SculptStage) {}
}

/// What [`Scene::step`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SculptStepReport {
    /// The integrator's report.
    pub step: StepReport,
    /// The points' report.
    pub follow: FollowReport,
    /// Nodes touched by tools.
    pub tool_nodes: usize,
}

/// Objects plus at most one sculpting region.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    objects: Vec<SceneObject>,
    region: Option<Region>,
}

impl Scene {
    /// An empty scene.
    pub fn new() -> Self {
        Self::default()
    }

    /// Add an object; returns its index.
    pub fn add(&mut self, object: SceneObject) -> usize {
        self.objects.push(object);
        self.objects.len() - 1
    }

    /// The objects.
    pub fn objects(&self) -> &[SceneObject] {
        &self.objects
    }

    /// The open region, if any.
    pub fn region(&self) -> Option<&Region> {
        self.region.as_ref()
    }

    /// The open region, mutably.
    pub fn region_mut(&mut self) -> Option<&mut Region> {
        self.region.as_mut()
    }

    /// Open a sculpting region on `object` over the box `[min, max]` (closing any open one with
    /// [`Scene::end_stroke`] first). Samples the object's field on the grid (in parallel).
    pub fn open_region(
        &mut self,
        object: usize,
        min: DVec3,
        max: DVec3,
        params: RegionParams,
    ) -> Result<(), SceneError> {
        if self.region.is_some() {
            self.end_stroke()?;
        }
        let obj = self
            .objects
            .get(object)
            .ok_or(SceneError::NoObject(object))?;
        let spec = GridSpec::try_covering(min, max, params.spacing)?;
        let field = obj.field.clone();
        let rest = crate::sparse::sample_trusted(&field, spec);
        let model = DynamicGrid::new(&rest, params.band, params.node)?;
        let inside = (0..obj.positions.len() as u32)
            .filter(|&i| spec.contains(obj.positions[i as usize]))
            .collect();
        self.region = Some(Region {
            object,
            bounds: (min, max),
            model,
            stepper: Stepper::new(params.integrator),
            base: Some(field),
            inside,
            follower: Follower::new(obj.positions.len(), params.follow),
            samples: Vec::new(),
            pending_dt: 0.0,
            steps: 0,
            params,
            last_resample: ResampleReport::default(),
        });
        Ok(())
    }

    /// One step: clear forces, apply `ropes`, integrate `dt`, let points follow.
    pub fn step(&mut self, dt: f64, ropes: &[Rope]) -> Result<SculptStepReport, SceneError> {
        self.step_observed(dt, ropes, &mut ())
    }

    /// [`Scene::step`], telling `observer` as each stage ends.
    pub fn step_observed(
        &mut self,
        dt: f64,
        ropes: &[Rope],
        observer: &mut dyn StepObserver,
    ) -> Result<SculptStepReport, SceneError> {
        self.step_inner(
            dt,
            &mut |model| apply_tools(model, ropes.iter().map(|r| r as &dyn GridTool)),
            observer,
        )
    }

    fn step_inner(
        &mut self,
        dt: f64,
        tools: &mut dyn FnMut(&mut DynamicGrid) -> Result<usize, ToolError>,
        observer: &mut dyn StepObserver,
    ) -> Result<SculptStepReport, SceneError> {
        let mut report = self.field_step(dt, tools, observer)?;
        let region = self.region.as_ref().ok_or(SceneError::NoRegion)?;
        if region.steps % u64::from(region.params.follow_every.max(1)) == 0 {
            report.follow = self.follow_observed(observer)?;
        }
        Ok(report)
    }

    /// Only the field's part of a step with any mix of tools (ropes, the sculpting probe, …):
    /// clear forces, apply `tools` in order, integrate `dt`. The points do not move until
    /// [`Scene::follow_points`]. A live workstation publishes the field between the two, so the
    /// haptic thread's snapshot does not wait for the points.
    pub fn step_field(
        &mut self,
        dt: f64,
        tools: &[&dyn GridTool],
    ) -> Result<SculptStepReport, SceneError> {
        self.field_step(
            dt,
            &mut |model| apply_tools(model, tools.iter().copied()),
            &mut (),
        )
    }

    /// Let the points follow the field over the time stepped since they last did (and refit
    /// them with `refit_every_step`).
    pub fn follow_points(&mut self) -> Result<FollowReport, SceneError> {
        self.follow_observed(&mut ())
    }

    fn field_step(
        &mut self,
        dt: f64,
        tools: &mut dyn FnMut(&mut DynamicGrid) -> Result<usize, ToolError>,
        observer: &mut dyn StepObserver,
    ) -> Result<SculptStepReport, SceneError> {
        let region = self.region.as_mut().ok_or(SceneError::NoRegion)?;
        region.model.clear_forces();
        let tool_nodes = tools(&mut region.model)?;
        observer.stage_done(SculptStage::Tools);
        let step = region.stepper.step(&mut region.model, dt)?;
        if region.params.band_follows {
            region.model.grow_band(region.params.spacing);
        }
        observer.stage_done(SculptStage::Integrate);
        region.pending_dt += dt;
        region.steps += 1;
        Ok(SculptStepReport {
            step,
            follow: FollowReport::default(),
            tool_nodes,
        })
    }

    fn follow_observed(
        &mut self,
        observer: &mut dyn StepObserver,
    ) -> Result<FollowReport, SceneError> {
        let region = self.region.as_mut().ok_or(SceneError::NoRegion)?;
        let obj = &mut self.objects[region.object];
        let follow = region.catch_up(obj);
        observer.stage_done(SculptStage::Follow);
        if region.params.refit_every_step {
            refit_moved(
                region
                    .base
                    .as_ref()
                    .expect("an open region has its base field"),
                &mut obj.field,
                &region.model,
                region.follower.moved(),
                &mut region.samples,
            );
            observer.stage_done(SculptStage::Refit);
        }
        Ok(follow)
    }

    /// End the stroke: refit moved points' local fields from the grid and make the sculpted
    /// field the new rest state (plastic), so the shape stays when the tools let go; then, with
    /// [`RegionParams::resample`], resample the changed points (see [`ResampleOptions`]).
    /// Returns the number of points the stroke moved. The object's field is refitted in place
    /// (the region lets go of its handle first), so a commit costs O(moved points), not a copy
    /// of the whole field.
    pub fn end_stroke(&mut self) -> Result<usize, SceneError> {
        let region = self.region.as_mut().ok_or(SceneError::NoRegion)?;
        let obj = &mut self.objects[region.object];
        region.catch_up(obj);
        region
            .follower
            .settle_normals(&region.model, &obj.positions, &mut obj.normals);
        let base = region
            .base
            .take()
            .expect("an open region has its base field");
        let n = region.follower.moved().len();
        let mut report = ResampleReport::default();
        let mut changed: Vec<u32> = region.follower.moved().to_vec();
        let mut removed = Vec::new();
        if let Some(opts) = region.params.resample {
            // Stranded points never moved, and points beside the deformation may not have
            // moved by more than ε: check every point where the field changed.
            let follower = &region.follower;
            let changed_box = region.model.displaced_box(0.01 * opts.spacing);
            changed.extend(region.inside.iter().copied().filter(|&i| {
                follower.is_stranded(i as usize)
                    || changed_box.is_some_and(|(lo, hi)| {
                        let p = obj.positions[i as usize];
                        p.cmpge(lo).all() && p.cmple(hi).all()
                    })
            }));
            changed.sort_unstable();
            changed.dedup();
            removed = resample::off_surface(
                obj,
                &mut region.follower,
                &changed,
                &opts,
                Some((&base, &region.model)),
                &mut report,
            );
        }
        // Removed points' fields are refitted too: they stay in the blend as orphans.
        let slots = refit_samples(&base, &region.model, &changed, &mut region.samples);
        let relocations = relocations(
            &obj.field,
            &region.model,
            &base,
            &obj.positions,
            &obj.normals,
            &changed,
        );
        drop(base);
        apply_refit(&mut obj.field, &slots, &region.samples);
        for (i, frame, samples) in relocations {
            obj.field.relocate_point(i as usize, frame, &samples);
        }
        region.model.commit();
        if let Some(max_gap) = region.params.auto_upsample {
            let which: Vec<usize> = region
                .follower
                .moved()
                .iter()
                .map(|&i| i as usize)
                .collect();
            let opts = UpsampleOptions { max_gap, k: 16 };
            let items = upsample_at(&obj.positions, &obj.normals, &obj.field, &opts, &which);
            edit::append_points(obj, Some(region), &items);
        }
        region.follower.clear_moved();
        if let Some(opts) = region.params.resample {
            let mut cands: std::collections::HashSet<u32> = changed.iter().copied().collect();
            report.removed += resample::apply_removals(obj, region, removed, &mut cands);
            resample::even_out(obj, region, cands, &opts, &mut report);
        }
        region.last_resample = report;
        region.base = Some(obj.field.clone());
        Ok(n)
    }

    /// The points of the region's object changed since the last call (moved by the field,
    /// projected, appended, or refilled by a removal), each once, appended to `out`; returns the
    /// object, or `None` without a region. Points changed by other means (object edits,
    /// [`Scene::replace_points`], a region reopened) are the caller's to track.
    pub fn take_changed_points(&mut self, out: &mut Vec<u32>) -> Option<usize> {
        let region = self.region.as_mut()?;
        region.follower.take_changed(out);
        Some(region.object)
    }

    /// Close the region (after ending the stroke).
    pub fn close_region(&mut self) -> Result<(), SceneError> {
        self.end_stroke()?;
        self.region = None;
        Ok(())
    }

    /// A snapshot of the region's field for the haptic thread.
    pub fn publish(&mut self) -> Option<Arc<ScalarGrid>> {
        self.region.as_mut().map(|r| r.model.publish())
    }
}

/// A moved point farther than this fraction of its local domain's half edge from the domain's
/// centre gets a new local field centred where it is now (see `relocations`).
pub const RELOCATE_BEYOND: f64 = 0.5;

/// The local fields to move with their points at a commit: for every point of `changed` that
/// a stroke carried more than [`RELOCATE_BEYOND`] of its domain away from the domain's centre,
/// a frame centred on the point (axes from its normal, the same size) and the sculpted field's
/// samples at the refit nodes of that frame (the region's grid values `d⁰ + u` where the grid
/// reaches, else `f_base + Δ`). Without this, the blend near a surface pulled farther than half
/// a domain has only fields fitted around where the surface was: their low-order patches do not
/// reach the new surface well, and the committed point-set field lags behind the grid's (a 7.5
/// mm rope bump's top stayed 7.6 mm low, and its mesh and points showed a torn plateau).
fn relocations(
    field: &GlobalField,
    model: &DynamicGrid,
    base: &GlobalField,
    positions: &[DVec3],
    normals: &[DVec3],
    changed: &[u32],
) -> Vec<(u32, crate::local_fit::LocalFrame, Vec<f64>)> {
    use rayon::prelude::*;
    let op = std::sync::Arc::clone(field.refit_operator());
    let n = op.samples();
    changed
        .par_iter()
        .filter_map(|&i| {
            let s = field.slot_of(i as usize)?;
            let old = field.slot_frame(s);
            let (p, normal) = (positions[i as usize], normals[i as usize]);
            if field.slot_support(s) <= 0.0 || p.distance(old.center) <= RELOCATE_BEYOND * old.half
            {
                return None;
            }
            let w = normal.try_normalize()?;
            let (u, v) = w.any_orthonormal_pair();
            let frame = crate::local_fit::LocalFrame {
                center: p,
                axes: [u, v, w],
                half: old.half,
            };
            let mut samples = Vec::with_capacity(n * n * n);
            for a in 0..n {
                for b in 0..n {
                    for c in 0..n {
                        let x = frame.to_world(op.node(a, b, c));
                        let f = model
                            .value_at(x)
                            .unwrap_or_else(|| crate::follow::sculpted_value(base, model, x).0);
                        samples.push(f);
                    }
                }
            }
            Some((i, frame, samples))
        })
        .collect()
}

/// Apply `tools` in order; the number of nodes they touched.
fn apply_tools<'a>(
    model: &mut DynamicGrid,
    tools: impl Iterator<Item = &'a dyn GridTool>,
) -> Result<usize, ToolError> {
    let mut n = 0;
    for t in tools {
        n += t.apply(model)?;
    }
    Ok(n)
}
