//! The force-mapping thread (seed 000 Fig. 7): newest cursor + newest snapshot → force and local
//! model → the socket, once per cursor sample, never waiting for the simulation.
//!
//! [`ForceMapper`] is the deterministic core (no I/O, no clock): one [`ForceMapper::tick`] maps a
//! cursor through the device-to-scene transform, asks the tool's haptic query in scene units
//! (sim-core's field force with VCP and friction for touch and paint, an anchor spring for the
//! rope, the shaped probe's distributed springs against the surface samples for the probe), and
//! returns the output in the device frame plus the [`InputEvent`] the simulation consumes.
//! [`run`] is the thin driver: on UDP it waits in `poll(2)` on the session's socket itself (the
//! cursor's arrival wakes this thread and no other), otherwise it parks on an empty cursor ring
//! (QUIC, the mouse); it takes the newest cursor (older ones it skips are counted; one the
//! network reordered behind an already mapped one is refused, [`ForceMapper::admit`]), loads the
//! snapshots with `ArcSwap::load` (lock-free), sends through the session's [`HotSender`] unless
//! the perceptual deadband holds the command back ([`ForceDeadband`], `run --force-deadband`,
//! off by default; [`deadband_gate`]), pushes the event, and keeps period and work histograms.
//! Nothing on that path allocates (the histograms are sized at start) or locks, except quinn's
//! connection lock inside `send_datagram` on QUIC.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use glam::{DQuat, DVec3};
use haptics_client::client::ClientError;
use haptics_client::{BlockingReceiver, HotSender};
use hdrhistogram::Histogram;
use protocol::packet::ModelKind;
use protocol::{CursorSample, ForceCommand, ForceDeadband};
use sim_core::grid::ScalarGrid;
use sim_core::haptic::{ContactModel, FieldContactParams, FieldForce, HapticOutput};
use sim_core::probe::{
    ContactParams, MagnitudeMethod, Probe, ProbePose, ProbeRenderer, SampleGrid,
};

use super::scene_file::{ContactSpec, ProbeSpec, SceneFile};
use super::shared::{CursorMsg, ForceTool, InputEvent, LoopStats, PercentilesUs, Shared};
use super::transform::DeviceTransform;

/// How long a local model stays valid at the server without a newer command (s).
pub const MODEL_LIFETIME_S: f64 = 0.02;
/// Validity radius of the local models around the cursor (scene m).
pub const MODEL_VALIDITY_M: f64 = 0.004;

/// The deterministic force core; see the module doc.
#[derive(Debug)]
pub struct ForceMapper {
    transform: DeviceTransform,
    field: FieldForce,
    probe_renderer: ProbeRenderer,
    probe: Probe,
    /// The settings `field` and `probe_renderer` were made with; a [`ForceTool`] carrying
    /// others replaces them (cheap, no allocation: settings change when a person moves a
    /// slider, not per tick).
    contact: ContactSpec,
    probe_spec: ProbeSpec,
    search: (f64, f64),
    /// Servo tick of the newest cursor [`ForceMapper::admit`] let through this session.
    newest_tick: Option<u32>,
}

/// A cursor this many servo ticks (10 s) behind the newest is not a reordered packet but a
/// restarted server counting from zero again: it is admitted and becomes the newest.
pub const RESTART_TICKS: u32 = 10_000;

impl ForceMapper {
    /// From a scene's device transform and tool defaults.
    pub fn new(scene: &SceneFile) -> anyhow::Result<Self> {
        let search = (
            scene.region.band.max(4.0 * scene.region.spacing),
            0.5 * scene.region.spacing,
        );
        let p = &scene.tools.probe;
        Ok(Self {
            transform: scene.device.transform(),
            field: FieldForce::new(field_params(&scene.tools.contact, search))?,
            probe_renderer: ProbeRenderer::new(probe_params(p), 0)?,
            probe: Probe::ellipsoid(DVec3::from(p.semi_axes))?,
            contact: scene.tools.contact,
            probe_spec: *p,
            search,
            newest_tick: None,
        })
    }

    /// Whether `cursor` is newer than every cursor admitted before (by servo tick, with
    /// wrap-around), recording it if so. A datagram the network reordered arrives after a
    /// newer one: mapping it would feed the simulation an old position and, worse, an old
    /// button state (a release and a new press: a spurious stroke; the delay study's jittered
    /// runs found it). Such a cursor is refused and gets no command (the server already holds
    /// a newer one). Equal ticks pass (the mouse stamps every cursor 0).
    pub fn admit(&mut self, cursor: &CursorSample) -> bool {
        let behind = self
            .newest_tick
            .map_or(0, |n| n.wrapping_sub(cursor.servo_tick));
        if behind == 0 || behind > RESTART_TICKS {
            self.newest_tick = Some(cursor.servo_tick);
            return true;
        }
        // `behind` in (0, RESTART_TICKS]: older than the newest. (A cursor ahead of it wraps
        // to a huge `behind` and is admitted above.)
        false
    }

    /// Forget the newest cursor (a new session's servo counts from its own start).
    pub fn new_session(&mut self) {
        self.newest_tick = None;
        self.field.reset();
    }

    /// Take the contact settings a tool carries, if they are new and valid (invalid ones keep
    /// the old: the simulation validated them before publishing).
    fn use_contact(&mut self, c: &ContactSpec) {
        if *c != self.contact {
            if let Ok(f) = FieldForce::new(field_params(c, self.search)) {
                self.field = f;
            }
            self.contact = *c;
        }
    }

    /// Take the probe settings a tool carries, if they are new.
    fn use_probe(&mut self, p: &ProbeSpec) {
        if *p != self.probe_spec {
            let _ = self.probe_renderer.set_params(probe_params(p));
            self.probe_spec = *p;
        }
    }

    /// The device-to-scene transform.
    pub fn transform(&self) -> &DeviceTransform {
        &self.transform
    }

    /// One tick: the force for `cursor` (device frame) against the newest `field` and
    /// `samples` under `tool`. Returns the output in the device frame and the scene-frame event.
    pub fn tick(
        &mut self,
        cursor: &CursorSample,
        field: Option<&ScalarGrid>,
        samples: Option<&SampleGrid>,
        tool: &ForceTool,
    ) -> (HapticOutput, InputEvent) {
        let t = self.transform;
        let x = t.point_to_scene(cursor.position.as_dvec3());
        let v = t.vector_to_scene(cursor.velocity.as_dvec3());
        let q = t.rotation_to_scene(cursor.orientation.as_dquat());
        let (out, contact) = if !(x.is_finite() && v.is_finite()) {
            (HapticOutput::idle(MODEL_LIFETIME_S), None)
        } else {
            match *tool {
                ForceTool::Touch(c) => match field {
                    Some(grid) => {
                        self.use_contact(&c);
                        let r = self.field.query(grid, x, v);
                        (r.output, r.contact.map(|c| (c.surface_point, c.normal)))
                    }
                    None => (HapticOutput::idle(MODEL_LIFETIME_S), None),
                },
                ForceTool::Rope {
                    anchor,
                    stiffness,
                    max_force,
                } => {
                    self.field.reset();
                    (rope_output(x, anchor, stiffness, max_force), None)
                }
                ForceTool::Probe(p) => {
                    self.field.reset();
                    self.use_probe(&p);
                    let semi_axes = DVec3::from(p.semi_axes);
                    (self.probe_output(x, q, v, semi_axes, samples), None)
                }
            }
        };
        let event = InputEvent {
            position: x,
            velocity: v,
            orientation: q,
            buttons: cursor.buttons,
            force: out.force,
            contact,
        };
        (t.output_to_device(&out), event)
    }

    fn probe_output(
        &mut self,
        x: DVec3,
        q: DQuat,
        v: DVec3,
        semi_axes: DVec3,
        samples: Option<&SampleGrid>,
    ) -> HapticOutput {
        let Some(samples) = samples else {
            return HapticOutput::idle(MODEL_LIFETIME_S);
        };
        if self.probe.semi_axes() != semi_axes && self.probe.set_semi_axes(semi_axes).is_err() {
            return HapticOutput::idle(MODEL_LIFETIME_S);
        }
        if self
            .probe
            .set_pose(ProbePose {
                position: x,
                orientation: q,
            })
            .is_err()
        {
            return HapticOutput::idle(MODEL_LIFETIME_S);
        }
        self.probe_renderer.query(&self.probe, samples, v).output(
            x,
            MODEL_VALIDITY_M,
            MODEL_LIFETIME_S,
        )
    }
}

fn field_params(c: &ContactSpec, (max_search, approach_margin): (f64, f64)) -> FieldContactParams {
    FieldContactParams {
        stiffness: c.stiffness,
        damping: c.damping,
        friction: c.friction,
        max_search,
        approach_margin,
        validity_radius: MODEL_VALIDITY_M,
        lifetime_s: MODEL_LIFETIME_S,
    }
}

fn probe_params(p: &ProbeSpec) -> ContactParams {
    ContactParams {
        surface_stiffness: p.surface_stiffness,
        surface_damping: p.surface_damping,
        method: p.direction.method(),
        magnitude: MagnitudeMethod::VectorSum,
    }
}

/// The rope's reaction: a spring from the tip to the anchor, `|F| ≤ max_force` with its
/// direction kept; the anchor model lets the server render it between commands (or, once
/// clamped, the held force). A rope is held stretched away from its anchor, so the model is
/// valid within [`MODEL_VALIDITY_M`] of the tip's stretch, not of the anchor: a model valid
/// only 4 mm around the anchor rendered zero as soon as a pull passed 4 mm (found by the
/// delay study's rope pull).
pub fn rope_output(x: DVec3, anchor: DVec3, stiffness: f64, max_force: f64) -> HapticOutput {
    let f = stiffness * (anchor - x);
    let n = f.length();
    if n <= max_force {
        let stretch = x.distance(anchor);
        HapticOutput {
            force: f,
            model: ContactModel {
                kind: ModelKind::Anchor,
                point: anchor,
                normal: DVec3::ZERO,
                stiffness,
                damping: 0.0,
                friction: 0.0,
                validity_radius: stretch + MODEL_VALIDITY_M,
                lifetime_s: MODEL_LIFETIME_S,
            },
        }
    } else {
        HapticOutput {
            force: f * (max_force / n),
            model: ContactModel::none(MODEL_LIFETIME_S),
        }
    }
}

/// One session's hot path as the force thread holds it.
#[derive(Debug)]
pub struct HotLink {
    /// Where force commands go.
    pub sender: HotSender,
    /// UDP: the session's socket, which the force thread waits on itself, so a cursor wakes
    /// one thread between its arrival and its answer (on QUIC, quinn's driver task receives
    /// and the cursors come through the ring).
    pub receiver: Option<BlockingReceiver>,
}

/// The ends of the force thread's hand-offs (its events ring is the [`ForceLoop`]'s).
#[derive(Debug)]
pub struct ForcePorts {
    /// Cursors from the network side.
    pub cursors: rtrb::Consumer<CursorMsg>,
    /// A fresh hot path after each (re)connect, `None` when the session ended.
    pub senders: rtrb::Consumer<Option<HotLink>>,
}

/// Period and work statistics of a loop, histograms sized once (no allocation per tick);
/// published to a [`LoopStats`] every 200 ms.
#[derive(Debug)]
pub struct LoopTimer {
    period: Histogram<u64>,
    work: Histogram<u64>,
    last: Option<Instant>,
    since: Instant,
    ticks: u64,
    published: Instant,
}

impl Default for LoopTimer {
    fn default() -> Self {
        Self::new()
    }
}

impl LoopTimer {
    /// Empty statistics.
    pub fn new() -> Self {
        let h = || Histogram::new_with_bounds(100, 10_000_000_000, 3).expect("static bounds");
        let now = Instant::now();
        Self {
            period: h(),
            work: h(),
            last: None,
            since: now,
            ticks: 0,
            published: now,
        }
    }

    /// One iteration that worked from `start` to `end`.
    pub fn tick(&mut self, start: Instant, end: Instant, stats: &LoopStats) {
        if stats.reset.swap(false, Ordering::Relaxed) {
            self.period.reset();
            self.work.reset();
            self.ticks = 0;
            self.since = start;
            self.last = None;
        }
        if let Some(last) = self.last {
            self.period
                .saturating_record(start.duration_since(last).as_nanos() as u64);
        }
        self.last = Some(start);
        self.work
            .saturating_record(end.duration_since(start).as_nanos() as u64);
        self.ticks += 1;
        if end.duration_since(self.published) >= Duration::from_millis(200) {
            self.publish(end, stats);
        }
    }

    fn publish(&mut self, now: Instant, stats: &LoopStats) {
        self.published = now;
        stats.ticks.store(self.ticks, Ordering::Relaxed);
        stats
            .seconds
            .set(now.duration_since(self.since).as_secs_f64());
        stats.period_us.set(percentiles_us(&self.period));
        stats.work_us.set(percentiles_us(&self.work));
    }
}

/// Percentiles of a nanosecond histogram, in µs.
pub fn percentiles_us(h: &Histogram<u64>) -> PercentilesUs {
    if h.is_empty() {
        return PercentilesUs::default();
    }
    let us = |ns: u64| ns as f64 / 1e3;
    PercentilesUs {
        p50: us(h.value_at_quantile(0.5)),
        p99: us(h.value_at_quantile(0.99)),
        p999: us(h.value_at_quantile(0.999)),
        max: us(h.max()),
    }
}

/// `SCHED_FIFO` priority of the force-mapping thread: above everything else of the workstation,
/// below a servo thread on the same machine (the demo's in-process server asks for
/// [`SERVO_FIFO_PRIORITY`]): the device side must never wait for the workstation.
pub const FORCE_FIFO_PRIORITY: i32 = 60;
/// The in-process demo server's servo priority.
pub const SERVO_FIFO_PRIORITY: i32 = 80;

/// Ask for real-time priority for this thread (SCHED_FIFO on Linux, which needs
/// `CAP_SYS_NICE` or an rtprio limit), else a better nice value; says what it got.
pub fn raise_priority() -> &'static str {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: pthread_setschedparam and setpriority take plain values and a pointer to a
        // local; pthread_self is always valid for the calling thread.
        unsafe {
            let param = libc::sched_param {
                sched_priority: FORCE_FIFO_PRIORITY,
            };
            if libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) == 0 {
                return "SCHED_FIFO";
            }
            // Not permitted: at least the best nice value we may take.
            if libc::setpriority(libc::PRIO_PROCESS, 0, -10) == 0 {
                return "nice -10";
            }
        }
    }
    "normal (no real-time permission)"
}

/// Whether `command` goes out at `now_ns` under the deadband with Weber fraction `k` (which
/// replaces `deadband` when it changed; `k = 0`: always).
pub fn deadband_gate(
    deadband: &mut ForceDeadband,
    k: f64,
    now_ns: u64,
    command: &ForceCommand,
) -> bool {
    let wanted = ForceDeadband::new(k as f32);
    if wanted.weber() != deadband.weber() {
        *deadband = wanted;
    }
    deadband.should_send(now_ns, command)
}

/// What the force-mapping loop keeps between cursors: the core, the simulation's event ring,
/// the session's sender, the deadband and the loop's statistics. [`run`] drives it from its
/// own thread (UDP, the mouse); on QUIC the network thread drives it itself
/// ([`super::net`]), so a cursor quinn delivers is answered on the thread it arrived on.
#[derive(Debug)]
pub struct ForceLoop {
    mapper: ForceMapper,
    events: rtrb::Producer<InputEvent>,
    sender: Option<HotSender>,
    clock: LoopTimer,
    deadband: ForceDeadband,
    epoch: Instant,
}

impl ForceLoop {
    /// A loop around `mapper` feeding `events`, without a session.
    pub fn new(mapper: ForceMapper, events: rtrb::Producer<InputEvent>) -> Self {
        Self {
            mapper,
            events,
            sender: None,
            clock: LoopTimer::new(),
            deadband: ForceDeadband::new(0.0),
            epoch: Instant::now(),
        }
    }

    /// A new session's sender (`None`: the session ended; forces are computed, not sent).
    pub fn set_session(&mut self, sender: Option<HotSender>) {
        // Rare (once per session); dropping an old sender here is the one free on this path.
        self.sender = sender;
        self.mapper.new_session();
        self.deadband.reset();
    }

    /// Map the newest cursor `msg` (`skipped` older ones were passed over): admit it, compute
    /// the force from the newest snapshots, send it (unless the deadband holds it), push the
    /// simulation's event, record the loop's statistics. No allocation, no lock but quinn's
    /// connection lock inside `send_datagram` on QUIC.
    pub fn step(&mut self, msg: CursorMsg, skipped: u64, shared: &Shared) {
        if skipped > 0 {
            shared
                .net
                .cursors_skipped
                .fetch_add(skipped, Ordering::Relaxed);
        }
        if !self.mapper.admit(&msg.cursor) {
            shared.net.cursors_late.fetch_add(1, Ordering::Relaxed);
            return;
        }
        let start = Instant::now();
        let field = shared.field.load();
        let samples = shared.samples.load();
        let tool = shared.tool.load();
        let (out, event) =
            self.mapper
                .tick(&msg.cursor, field.as_deref(), samples.as_deref(), &tool);
        drop((field, samples, tool));

        let cmd = out.to_command(msg.packet_sequence, msg.server_timestamp_ns);
        let now_ns = start.duration_since(self.epoch).as_nanos() as u64;
        let k = shared.net.force_deadband.get();
        if self.sender.is_some() && !deadband_gate(&mut self.deadband, k, now_ns, &cmd) {
            shared.net.forces_held.fetch_add(1, Ordering::Relaxed);
        } else if let Some(s) = &mut self.sender {
            match s.send_force(&cmd) {
                Ok(()) => {
                    shared.net.forces_sent.fetch_add(1, Ordering::Relaxed);
                    if let Some((sequence, _)) = s.last_sent() {
                        shared.net.applied.sent(sequence, msg.cursor.servo_tick);
                    }
                }
                Err(ClientError::Closed) => self.sender = None,
                Err(e) => tracing::debug!("force command not sent: {e}"),
            }
        }
        shared.haptic.record(&event);
        if self.events.push(event).is_err() {
            shared.events_dropped.fetch_add(1, Ordering::Relaxed);
        }
        let end = Instant::now();
        shared.net.turnaround_ns.store(
            end.duration_since(msg.received).as_nanos() as u64,
            Ordering::Relaxed,
        );
        self.clock.tick(start, end, &shared.force_loop);
    }
}

/// The thread body: runs until `shared` says stop.
pub fn run(mut force: ForceLoop, mut ports: ForcePorts, shared: Arc<Shared>) {
    let priority = raise_priority();
    tracing::info!(priority, "force-mapping thread started");
    let mut receiver: Option<BlockingReceiver> = None;
    while !shared.stopping() {
        while let Ok(link) = ports.senders.pop() {
            let (sender, rx) = match link {
                Some(l) => (Some(l.sender), l.receiver),
                None => (None, None),
            };
            receiver = rx;
            force.set_session(sender);
        }
        let mut newest = None;
        let mut skipped = 0u64;
        if let (Some(rx), Some(tx)) = (&mut receiver, &force.sender) {
            // Wait on the socket; the timeout only bounds how late a new session or a stop is
            // seen. Then take what else is queued, keeping the newest.
            let mut wait = Duration::from_millis(5);
            loop {
                match rx.recv_cursor(wait) {
                    Ok(Some((packet, cursor))) => {
                        let net = &shared.net;
                        net.cursors.fetch_add(1, Ordering::Relaxed);
                        net.last_cursor_ns
                            .store(tx.clock().now_ns(), Ordering::Relaxed);
                        net.applied.on_cursor(&cursor);
                        skipped += u64::from(newest.is_some());
                        newest = Some(CursorMsg::new(&packet, cursor, Instant::now()));
                        wait = Duration::ZERO;
                    }
                    Ok(None) => break,
                    Err(e) => {
                        // The network side sees the silence and reconnects.
                        tracing::warn!("hot-path receive failed: {e}");
                        receiver = None;
                        break;
                    }
                }
            }
        }
        while let Ok(c) = ports.cursors.pop() {
            skipped += u64::from(newest.is_some());
            newest = Some(c);
        }
        match newest {
            Some(msg) => force.step(msg, skipped, &shared),
            None if receiver.is_none() => {
                // Unparked by the cursors' producer on every push; the timeout only bounds
                // stop latency.
                std::thread::park_timeout(Duration::from_millis(5));
            }
            None => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3};
    use sim_core::grid::GridSpec;

    fn scene() -> SceneFile {
        SceneFile::parse(
            r#"
[[object]]
name = "ball"
generate = { shape = "sphere", size = 0.02, points = 500, seed = 1 }
[region]
object = "ball"
min = [-0.03, -0.03, -0.03]
max = [0.03, 0.03, 0.03]
spacing = 0.001
band = 0.004
[tools.contact]
stiffness = 500.0
damping = 0.0
friction = 0.0
"#,
        )
        .unwrap()
    }

    fn cursor(p: [f32; 3]) -> CursorSample {
        CursorSample {
            position: Vec3::from(p),
            orientation: Quat::IDENTITY,
            velocity: Vec3::ZERO,
            buttons: 1,
            output_force: Vec3::ZERO,
            servo_tick: 0,
            engaged: true,
            estop: false,
            ack: None,
        }
    }

    #[test]
    fn touch_force_is_stiffness_times_depth_and_outward() {
        let mut m = ForceMapper::new(&scene()).unwrap();
        let spec = GridSpec::covering(DVec3::splat(-0.03), DVec3::splat(0.03), 0.001);
        let grid = ScalarGrid::from_fn(spec, |p| p.length() - 0.02);
        let (out, ev) = m.tick(
            &cursor([0.0, 0.019, 0.0]),
            Some(&grid),
            None,
            &ForceTool::Touch(scene().tools.contact),
        );
        assert!((out.force.y - 0.5).abs() < 0.02, "{:?}", out.force);
        assert!(ev.contact.is_some() && ev.pressed());
        let touch = ForceTool::Touch(scene().tools.contact);
        let (idle, _) = m.tick(&cursor([0.0, 0.019, 0.0]), None, None, &touch);
        assert_eq!(idle.force, DVec3::ZERO, "no snapshot yet: no force");
    }

    #[test]
    fn contact_settings_carried_by_the_tool_take_effect_at_once() {
        let mut m = ForceMapper::new(&scene()).unwrap();
        let spec = GridSpec::covering(DVec3::splat(-0.03), DVec3::splat(0.03), 0.001);
        let grid = ScalarGrid::from_fn(spec, |p| p.length() - 0.02);
        let mut c = scene().tools.contact;
        c.stiffness *= 2.0;
        let (out, _) = m.tick(
            &cursor([0.0, 0.019, 0.0]),
            Some(&grid),
            None,
            &ForceTool::Touch(c),
        );
        assert!((out.force.y - 1.0).abs() < 0.04, "{:?}", out.force);
        // An invalid setting keeps the last good one.
        c.stiffness = -1.0;
        let (out, _) = m.tick(
            &cursor([0.0, 0.019, 0.0]),
            Some(&grid),
            None,
            &ForceTool::Touch(c),
        );
        assert!((out.force.y - 1.0).abs() < 0.04, "{:?}", out.force);
    }

    #[test]
    fn rope_force_is_clamped_with_its_direction_kept() {
        let out = rope_output(DVec3::new(0.1, 0.0, 0.0), DVec3::ZERO, 100.0, 3.0);
        assert!((out.force.length() - 3.0).abs() < 1e-12);
        assert!(out.force.x < 0.0 && out.force.y == 0.0);
        let near = rope_output(DVec3::new(0.01, 0.0, 0.0), DVec3::ZERO, 100.0, 3.0);
        assert!((near.force.x + 1.0).abs() < 1e-12);
        assert_eq!(near.model.kind, ModelKind::Anchor);
    }

    #[test]
    fn a_cursor_reordered_behind_a_mapped_one_is_refused() {
        let mut m = ForceMapper::new(&scene()).unwrap();
        let admit = |m: &mut ForceMapper, tick: u32| {
            let mut c = cursor([0.0, 0.03, 0.0]);
            c.servo_tick = tick;
            m.admit(&c)
        };
        let mut at = |tick: u32| admit(&mut m, tick);
        assert!(at(100));
        assert!(!at(99), "older: its position and buttons are the past");
        assert!(at(100), "equal (the mouse stamps 0 on every cursor)");
        assert!(at(101));
        assert!(at(u32::MAX.wrapping_add(200)), "newer across the wrap");
        assert!(!at(150));
        // A restarted server counts from zero: far behind is a new count, not a reorder.
        assert!(at(50_000));
        assert!(at(3));
        assert!(at(4));
        m.new_session();
        assert!(admit(&mut m, 1));
    }

    #[test]
    fn the_server_renders_a_stretched_rope_as_the_workstation_computed_it() {
        // Pulled 25 mm from its anchor (1.5 N at 60 N/m): the server's renderer, at the same
        // cursor and 2 mm further out, gives the spring's force, never zero.
        let anchor = DVec3::new(0.0, 0.05, 0.0);
        let x = anchor + DVec3::new(0.0, 0.025, 0.0);
        let cmd = rope_output(x, anchor, 60.0, 3.0).to_command(0, 0);
        let mut r = protocol::ModelRenderer::new();
        for dy in [0.0f32, 0.002] {
            let at = x.as_vec3() + glam::Vec3::new(0.0, dy, 0.0);
            let f = r.render(&cmd, at, glam::Vec3::ZERO, 0);
            let want = 60.0 * (0.025 + dy);
            assert!((f.y + want).abs() < 1e-4, "{dy}: {f}");
        }
    }

    #[test]
    fn the_force_deadband_gate_holds_unfelt_commands_and_follows_k() {
        let mut db = ForceDeadband::new(0.0);
        let mut out = rope_output(DVec3::new(0.01, 0.0, 0.0), DVec3::ZERO, 100.0, 3.0);
        let cmd = |o: &HapticOutput| o.to_command(0, 0);
        // Off: every command.
        assert!((0..5).all(|t| deadband_gate(&mut db, 0.0, t * 1_000_000, &cmd(&out))));
        // K = 0.1: the same 1 N rope force is held until the 5 ms heartbeat ...
        let sent: Vec<u64> = (5..30)
            .filter(|&t| deadband_gate(&mut db, 0.1, t * 1_000_000, &cmd(&out)))
            .collect();
        assert_eq!(sent, [5, 10, 15, 20, 25]);
        // ... a felt change (+20 %) goes at once ...
        out.force *= 1.2;
        out.model.stiffness *= 1.2;
        assert!(deadband_gate(&mut db, 0.1, 30_000_000, &cmd(&out)));
        // ... and turning it off sends everything again.
        assert!(deadband_gate(&mut db, 0.0, 31_000_000, &cmd(&out)));
    }

    #[test]
    fn non_finite_cursors_give_zero_force() {
        let mut m = ForceMapper::new(&scene()).unwrap();
        let (out, _) = m.tick(
            &cursor([f32::NAN, 0.0, 0.0]),
            None,
            None,
            &ForceTool::Rope {
                anchor: DVec3::ZERO,
                stiffness: 100.0,
                max_force: 3.0,
            },
        );
        assert_eq!(out.force, DVec3::ZERO);
    }
}
