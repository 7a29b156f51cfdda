//! The simulation thread's driver: the commands it takes, the reports it sends, and [`run`],
//! which paces steps at the region's `dt`, publishes the field grid right after every field
//! step, *then* lets the points follow (every [`FOLLOW_EVERY`] steps), and publishes the
//! surface samples and the points for the renderer at their own rates.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use glam::DVec3;
use sim_core::csg::CsgOp;
use sim_core::grid::ScalarGrid;
use sim_core::probe::SampleGrid;

use super::{FOLLOW_EVERY, Saved, Settings, SharedPoints, SimCore, StrokeReport, save};
use crate::live::force::LoopTimer;
use crate::live::scene_file::{ContactSpec, ToolKind};
use crate::live::shared::{ForceTool, InputEvent, Shared};
use crate::sculpt::script::Op;

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
    /// Save the model and its meshed zero set ([`save`]) into a directory.
    Save(PathBuf, Reply<Saved>),
    /// Save a scene file that reloads this model ([`SimCore::save_scene`]) into a directory.
    SaveScene(PathBuf, Reply<PathBuf>),
    /// Run an operation; the answer comes back on the channel.
    Op(Box<Op>, Reply<(&'static str, String)>),
    /// Hand the core over (at the end of a session, for saving).
    Finish(mpsc::Sender<SimCore>),
    /// Join a shared scene (`crate::share`): the sculpted object's points after every local
    /// commit (a stroke that shaped or painted, an operation) go to `outbox`; the answer is the
    /// points now.
    Share(
        tokio::sync::mpsc::UnboundedSender<SharedPoints>,
        Reply<SharedPoints>,
    ),
    /// Adopt another station's state ([`SimCore::adopt`]), after the stroke in progress if one
    /// is (the newest waiting state wins); the answer comes when it is taken.
    Adopt(Box<SharedPoints>, Reply<()>),
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
    let mut loop_clock = LoopTimer::new();
    let mut field_clock = LoopTimer::new();
    // Snapshots replaced here are kept until the next replacement, so their memory is freed on
    // this thread, not on the force thread when it drops its last guard.
    let mut retired = Retired {
        samples: shared.samples.swap(core.samples().map(Arc::new)),
        ..Retired::default()
    };
    // A shared scene's outbox, and a state waiting for the stroke in progress to end.
    let mut outbox: Option<tokio::sync::mpsc::UnboundedSender<SharedPoints>> = None;
    let mut adopt: Option<(Box<SharedPoints>, Reply<()>)> = None;
    // The shared version the points were made from: commits name it, so a stroke made before
    // a newer state was taken is known for one made from an older state.
    let mut base = 0;
    let shared_points = |core: &SimCore, base| SharedPoints {
        version: base,
        ..core.shared_points()
    };
    // Hand a local commit to the shared scene, if one is joined.
    let offer = |outbox: &Option<tokio::sync::mpsc::UnboundedSender<SharedPoints>>,
                 core: &SimCore,
                 base| {
        if let Some(o) = outbox {
            let _ = o.send(shared_points(core, base));
        }
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
                    if r.is_ok() {
                        offer(&outbox, &core, base);
                    }
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
                    if r.is_ok() {
                        offer(&outbox, &core, base);
                    }
                    let _ = reply.send(r);
                }
                SimCommand::Save(dir, reply) => {
                    let _ = reply.send(save(&core, &dir, core.file.mesh_resolution));
                }
                SimCommand::SaveScene(dir, reply) => {
                    let _ = reply.send(core.save_scene(&dir));
                }
                SimCommand::Finish(reply) => {
                    let _ = reply.send(core);
                    return;
                }
                SimCommand::Share(tx, reply) => {
                    let _ = reply.send(Ok(shared_points(&core, base)));
                    outbox = Some(tx);
                }
                SimCommand::Adopt(s, reply) => adopt = Some((s, reply)),
            }
        }
        if !core.engaged()
            && let Some((s, reply)) = adopt.take()
        {
            let r = core.adopt(&s);
            match &r {
                Ok(()) => base = s.version,
                Err(e) => tracing::warn!("a shared state not taken: {e:#}"),
            }
            retired.samples = shared.samples.swap(core.samples().map(Arc::new));
            retired.field = shared.field.swap(core.publish_field());
            shared.render.store(Some(Arc::new(core.render_snapshot())));
            let _ = reply.send(r);
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
        // A local commit that changed the shape or its colours goes to the shared scene.
        if core.strokes()[strokes..]
            .iter()
            .any(|s| s.tool != ToolKind::Touch)
        {
            offer(&outbox, &core, base);
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
