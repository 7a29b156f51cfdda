//! One measured session of `bench-view`: load and fit, then the simulation, force and renderer
//! threads under a scripted hand; statistics from the threads' own [`LoopStats`].

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Mutex, mpsc};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use glam::{DVec3, Quat};
use protocol::CursorSample;
use serde::Serialize;

use crate::bigscan::peak_rss_kib;
use crate::live::force::{ForceMapper, LoopTimer};
use crate::live::frames::{FrameMaker, SplatCache, SplatUpdate};
use crate::live::scene_file::{SceneFile, ToolKind};
use crate::live::shared::{EVENT_RING, PercentilesUs, RenderSnapshot, Shared};
use crate::live::sim::{self, SimCommand, SimCore};

/// Warm-up before statistics start (s).
const WARMUP_S: f64 = 1.0;
/// Length of one stroke cycle of the scripted hand (s).
const CYCLE_S: f64 = 4.0;

/// What to run.
#[derive(Debug, Clone)]
pub struct SessionSpec {
    /// Absolute path of the mesh to sample.
    pub mesh: PathBuf,
    /// Points to sample.
    pub points: usize,
    /// Longest side of the model (m).
    pub size: f64,
    /// Measured seconds.
    pub seconds: f64,
    /// The old full splat recompute instead of the incremental cache.
    pub full: bool,
    /// Draw frames headless.
    pub draw: bool,
    /// Draw at most about this many splats (thinned).
    pub thin: Option<usize>,
    /// No progress lines.
    pub quiet: bool,
}

/// Median, 99th percentile and largest of a sample (ms).
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Spread {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest.
    pub max: f64,
}

impl Spread {
    fn of(mut v: Vec<f64>) -> Self {
        if v.is_empty() {
            return Self::default();
        }
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        Self {
            p50: at(0.5),
            p99: at(0.99),
            max: v[v.len() - 1],
        }
    }
}

/// One session's measurements.
#[derive(Debug, Clone, Serialize)]
pub struct SessionReport {
    /// Sampling the mesh, fitting the object and opening the region (s).
    pub fit_s: f64,
    /// Peak resident memory once loaded and fitted (MiB; the peak is reset before each scene).
    pub peak_rss_mib: f64,
    /// Peak resident memory by the end of the session (MiB).
    pub session_peak_rss_mib: f64,
    /// Points inside the sculpting region.
    pub region_points: usize,
    /// The simulation's field step: tools, integration, publishing the grid (µs).
    pub field_step_us: PercentilesUs,
    /// A whole simulation iteration: field step, points following, snapshots, commits (µs).
    pub sim_iteration_us: PercentilesUs,
    /// Simulation iterations per second (target 1000).
    pub sim_hz: f64,
    /// Force-loop ticks per second (target 1000).
    pub force_hz: f64,
    /// Work per force tick (µs).
    pub force_work_us: PercentilesUs,
    /// Period between force ticks (µs).
    pub force_period_us: PercentilesUs,
    /// Snapshot → splats ready on the renderer thread (ms), per new snapshot.
    pub frame_prep_ms: Spread,
    /// Snapshots prepared while measuring.
    pub frames: usize,
    /// Radii recomputed per prepared snapshot, mean.
    pub mean_recomputed: f64,
    /// Drawing a prepared frame headless (ms), with `--draw`.
    pub draw_ms: Option<Spread>,
    /// Strokes committed while measuring and warming up.
    pub strokes: usize,
    /// Points the commits' resampling inserted, removed and projected back.
    pub resample_inserted: usize,
    /// See `resample_inserted`.
    pub resample_removed: usize,
    /// See `resample_inserted`.
    pub resample_projected: usize,
    /// Events the simulation's ring refused.
    pub events_dropped: u64,
}

/// The scene: the sampled mesh as the one, sculpted object; the region on the bunny's back.
fn scene_file(spec: &SessionSpec) -> anyhow::Result<SceneFile> {
    let k = spec.size / 0.1;
    let mesh = toml::Value::String(format!("sample:{}", spec.mesh.display())).to_string();
    let v = |x: [f64; 3]| format!("[{}, {}, {}]", x[0] * k, x[1] * k, x[2] * k);
    let text = format!(
        r#"
[[object]]
name = "scan"
generate = {{ shape = {mesh}, size = {size}, points = {n}, seed = 1 }}
[region]
object = "scan"
min = {min}
max = {max}
spacing = {h}
band = {band}
[tools]
selected = "rope"
rope = {{ radius = {rope}, stiffness = 60.0, max_force = 3.0, profile = "gaussian" }}
probe = {{ semi_axes = [{p}, {p}, {p}], surface_stiffness = 2e6, surface_damping = 0.0, sculpt_stiffness = 1000.0 }}
[render]
width = 640
height = 480
interval_s = 0.1
"#,
        size = spec.size,
        n = spec.points,
        min = v([0.0, -0.005, -0.012]),
        max = v([0.042, 0.035, 0.032]),
        h = 0.0025 * k,
        band = 0.008 * k,
        rope = 0.008 * k,
        p = 0.005 * k,
    );
    SceneFile::parse(&text).context("the benchmark scene")
}

/// The scripted hand: where the tip is, whether the button is down and which tool is selected
/// at time `t` (s).
#[derive(Debug, Clone, Copy)]
struct Hand {
    rope: (DVec3, DVec3),
    probe: (DVec3, DVec3, DVec3),
    radius: f64,
    pull: f64,
}

impl Hand {
    fn at(&self, t: f64) -> (DVec3, bool, ToolKind) {
        let u = t.rem_euclid(CYCLE_S);
        let (a, na) = self.rope;
        let (b0, b1, nb) = self.probe;
        let pressed_in = self.radius - 0.2 * self.radius;
        let above = self.radius + 0.6 * self.radius;
        if u < 0.2 {
            (a + na * 0.25 * self.pull, false, ToolKind::Rope)
        } else if u < 1.7 {
            (a + na * self.pull * (u - 0.2) / 1.5, true, ToolKind::Rope)
        } else if u < 2.2 {
            let s = ((u - 2.0) / 0.2).clamp(0.0, 1.0);
            (
                b0 + nb * (above + (pressed_in - above) * s),
                false,
                ToolKind::ProbePush,
            )
        } else if u < 3.8 {
            let s = (u - 2.2) / 1.6;
            (b0.lerp(b1, s) + nb * pressed_in, true, ToolKind::ProbePush)
        } else {
            (b1 + nb * above, false, ToolKind::ProbePush)
        }
    }
}

/// Run one session.
pub fn run(spec: &SessionSpec) -> anyhow::Result<SessionReport> {
    let file = scene_file(spec)?;
    // Peak memory per scene: reset the high-water mark (Linux; harmless elsewhere).
    let _ = std::fs::write("/proc/self/clear_refs", "5");
    let t0 = Instant::now();
    let dir = spec.mesh.parent().map(PathBuf::from).unwrap_or_default();
    let mut core = SimCore::new(&file, dir)?;
    let fit_s = t0.elapsed().as_secs_f64();
    let peak_rss_mib = peak_rss_kib() as f64 / 1024.0;
    let k = spec.size / 0.1;
    let region_points = core.scene().region().map_or(0, |r| r.points_inside().len());
    let hand = {
        let o = &core.scene().objects()[0];
        let on = |x: DVec3| {
            let p = o.field.project_to_zero_set(x * k).point;
            let n = o.field.value_and_gradient(p).1.normalize_or(DVec3::Y);
            (p, n)
        };
        let (a, na) = on(DVec3::new(0.02, 0.03, 0.0));
        let (b0, nb) = on(DVec3::new(0.008, 0.03, 0.018));
        let (b1, _) = on(DVec3::new(0.028, 0.03, 0.018));
        Hand {
            rope: (a, na),
            probe: (b0, b1, nb),
            radius: 0.005 * k,
            pull: 0.008 * k,
        }
    };
    if !spec.quiet {
        eprintln!(
            "  loaded and fitted in {fit_s:.2} s, peak {peak_rss_mib:.0} MiB, {region_points} points in the region; sculpting {:.0} s…",
            WARMUP_S + spec.seconds
        );
    }

    let shared = Shared::new();
    shared.net.connected.store(true, Ordering::Release);
    shared.field.store(core.publish_field());
    shared.render.store(Some(Arc::new(core.render_snapshot())));
    let mut mapper = ForceMapper::new(&file)?;
    let (mut events_tx, events_rx) = rtrb::RingBuffer::new(EVENT_RING);
    let (cmd_tx, cmd_rx) = mpsc::channel();
    let (rep_tx, rep_rx) = mpsc::channel();
    let spawn = |name: &str, f: Box<dyn FnOnce() + Send>| {
        std::thread::Builder::new()
            .name(name.into())
            .spawn(f)
            .with_context(|| format!("starting the {name} thread"))
    };
    let s = Arc::clone(&shared);
    let sim_thread = spawn(
        "simulation",
        Box::new(move || sim::run(core, events_rx, cmd_rx, rep_tx, s)),
    )?;

    // The force thread: the scripted hand through the real force mapper, at 1 kHz.
    let s = Arc::clone(&shared);
    let commands = cmd_tx.clone();
    let force_thread = spawn(
        "force-mapping",
        Box::new(move || {
            crate::live::force::raise_priority();
            let mut timer = LoopTimer::new();
            let period = Duration::from_millis(1);
            let start = Instant::now();
            let mut next = start;
            let (mut last, _, _) = hand.at(0.0);
            let mut selected = None;
            let mut tick = 0u32;
            while !s.stopping() {
                let t = start.elapsed().as_secs_f64();
                let (x, pressed, tool) = hand.at(t);
                if selected != Some(tool) {
                    let _ = commands.send(SimCommand::Select(tool));
                    selected = Some(tool);
                }
                let v = (x - last) / period.as_secs_f64();
                last = x;
                let cursor = CursorSample {
                    position: x.as_vec3(),
                    orientation: Quat::IDENTITY,
                    velocity: v.as_vec3(),
                    buttons: u16::from(pressed),
                    output_force: glam::Vec3::ZERO,
                    servo_tick: tick,
                    engaged: true,
                    estop: false,
                    ack: None,
                };
                tick = tick.wrapping_add(1);
                let w0 = Instant::now();
                let field = s.field.load();
                let samples = s.samples.load();
                let tool = s.tool.load();
                let (_, event) = mapper.tick(&cursor, field.as_deref(), samples.as_deref(), &tool);
                s.haptic.record(&event);
                if events_tx.push(event).is_err() {
                    s.events_dropped.fetch_add(1, Ordering::Relaxed);
                }
                timer.tick(w0, Instant::now(), &s.force_loop);
                next += period;
                let now = Instant::now();
                if next > now {
                    std::thread::sleep(next - now);
                } else if now - next > 5 * period {
                    next = now;
                }
            }
        }),
    )?;

    // The renderer thread: every new snapshot → splats (and a drawn frame with --draw).
    let s = Arc::clone(&shared);
    let measuring = Arc::new(AtomicBool::new(false));
    let recomputed = Arc::new(AtomicU64::new(0));
    let prep: Arc<Mutex<(Vec<f64>, Vec<f64>)>> = Arc::default();
    let (m, rc, pr) = (
        Arc::clone(&measuring),
        Arc::clone(&recomputed),
        Arc::clone(&prep),
    );
    let mode = if spec.full {
        SplatUpdate::Full
    } else {
        SplatUpdate::Incremental
    };
    let mut maker = if spec.draw {
        let mut maker = FrameMaker::with_splats(&file.render, mode)?;
        maker.thin_to(spec.thin);
        Some(maker)
    } else {
        None
    };
    let render_thread = spawn(
        "rendering",
        Box::new(move || {
            let mut cache = SplatCache::new(mode);
            let mut last: Option<Arc<RenderSnapshot>> = None;
            while !s.stopping() {
                std::thread::sleep(Duration::from_millis(16));
                let Some(snap) = s.render.load_full() else {
                    continue;
                };
                if last.as_ref().is_some_and(|l| Arc::ptr_eq(l, &snap)) {
                    continue;
                }
                last = Some(Arc::clone(&snap));
                let (t_prep, t_draw, work) = match maker.as_mut() {
                    Some(mk) => {
                        if mk.render(&snap, &s).is_err() {
                            continue;
                        }
                        let (a, b) = mk.timings();
                        (a, Some(b), mk.splat_cache().last_work())
                    }
                    None => {
                        let t = Instant::now();
                        let work = cache.update(&snap.points);
                        (t.elapsed(), None, work)
                    }
                };
                if m.load(Ordering::Relaxed) {
                    rc.fetch_add(work.recomputed as u64, Ordering::Relaxed);
                    let mut g = pr.lock().unwrap_or_else(|e| e.into_inner());
                    g.0.push(t_prep.as_secs_f64() * 1e3);
                    if let Some(d) = t_draw {
                        g.1.push(d.as_secs_f64() * 1e3);
                    }
                }
            }
        }),
    )?;

    std::thread::sleep(Duration::from_secs_f64(WARMUP_S));
    for l in [&shared.field_loop, &shared.sim_loop, &shared.force_loop] {
        l.reset.store(true, Ordering::Relaxed);
    }
    measuring.store(true, Ordering::Relaxed);
    std::thread::sleep(Duration::from_secs_f64(spec.seconds));
    measuring.store(false, Ordering::Relaxed);
    // Give the loops a moment to publish their last statistics, then read them.
    std::thread::sleep(Duration::from_millis(250));
    let field_step_us = shared.field_loop.work_us.get();
    let sim_iteration_us = shared.sim_loop.work_us.get();
    let sim_hz = shared.sim_loop.rate_hz();
    let force_hz = shared.force_loop.rate_hz();
    let force_work_us = shared.force_loop.work_us.get();
    let force_period_us = shared.force_loop.period_us.get();
    let (back_tx, back_rx) = mpsc::channel();
    let _ = cmd_tx.send(SimCommand::Finish(back_tx));
    let core = back_rx.recv_timeout(Duration::from_secs(60)).ok();
    shared.request_stop();
    for (name, t) in [
        ("simulation", sim_thread),
        ("force-mapping", force_thread),
        ("rendering", render_thread),
    ] {
        t.join()
            .map_err(|_| anyhow::anyhow!("the {name} thread panicked"))?;
    }
    let failed: Vec<String> = rep_rx
        .try_iter()
        .filter_map(|r| match r {
            sim::SimReport::Failed(e) => Some(e),
            sim::SimReport::Stroke(_) => None,
        })
        .collect();
    anyhow::ensure!(
        failed.is_empty(),
        "the simulation failed: {}",
        failed.join("; ")
    );
    let core = core.context("the simulation did not hand its core back")?;
    let (prep, draw) = std::mem::take(&mut *prep.lock().unwrap_or_else(|e| e.into_inner()));
    let frames = prep.len();
    let strokes = core.strokes();
    Ok(SessionReport {
        fit_s,
        peak_rss_mib,
        session_peak_rss_mib: peak_rss_kib() as f64 / 1024.0,
        region_points,
        field_step_us,
        sim_iteration_us,
        sim_hz,
        force_hz,
        force_work_us,
        force_period_us,
        frame_prep_ms: Spread::of(prep),
        frames,
        mean_recomputed: recomputed.load(Ordering::Relaxed) as f64 / frames.max(1) as f64,
        draw_ms: (!draw.is_empty()).then(|| Spread::of(draw)),
        strokes: strokes.len(),
        resample_inserted: strokes.iter().map(|s| s.resampled.inserted).sum(),
        resample_removed: strokes.iter().map(|s| s.resampled.removed).sum(),
        resample_projected: strokes.iter().map(|s| s.resampled.projected).sum(),
        events_dropped: shared.events_dropped.load(Ordering::Relaxed),
    })
}
