//! What the workstation's threads hand each other, and the policy of every hand-off.
//!
//! | from → to | what | how | when full / empty |
//! |---|---|---|---|
//! | network → force | `Some(HotLink)` after each (re)connect (the sender; on UDP also the receiving socket, which the force thread then waits on itself), `None` when the session ends | `rtrb` ring, 4 | full: cannot happen (two per session, taken every tick) |
//! | network (QUIC) or mouse → force | [`CursorMsg`] | `rtrb` ring, 64 | full: the newest cursor is dropped and counted (the force thread is late anyway); empty: the force thread parks until the producer unparks it |
//! | force → simulation | [`InputEvent`] (cursor in the scene, buttons, contact, force) | `rtrb` ring, 4096 | full: the event is dropped and counted (the simulation is inside a long operation; it sees a jump when it is back) |
//! | simulation → force | the field grid snapshot and the [`ForceTool`] | [`ArcSwapOption`] / [`ArcSwap`]: immutable, swapped, never locked against the reader | the force thread always reads the newest; a missing grid means no contact |
//! | simulation → rendering | [`RenderSnapshot`] (points in `Arc` chunks, unchanged ones shared with the last snapshot) | [`ArcSwapOption`] | the renderer draws the newest |
//! | force → anyone | loop statistics, the last force and contact | atomics in [`HapticMonitor`] and [`LoopStats`] | — |
//!
//! The force thread's per-tick path allocates nothing, and takes no lock on UDP: ring pushes and
//! pops are wait-free, `ArcSwap::load` is lock-free, statistics are relaxed atomics. On QUIC,
//! each datagram's `Bytes` is cut from a reused block (`quic::DatagramArena`, no allocation)
//! and quinn locks its connection inside `send_datagram`.
//! Frees are kept off it as far as the hand-offs allow: the simulation holds each snapshot it
//! replaced until its next replacement, so the last reference is normally dropped there (only a
//! force thread preempted across two replacements drops one itself), and a session's sender is
//! dropped once per session.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

use arc_swap::{ArcSwap, ArcSwapOption};
use glam::{DQuat, DVec3};
use protocol::{CursorSample, Packet};
use sim_core::grid::ScalarGrid;
use sim_core::probe::SampleGrid;

use super::points::ChunkedPoints;
use super::scene_file::{ContactSpec, ProbeSpec, ToolKind};

/// Capacity of the network → force cursor ring.
pub const CURSOR_RING: usize = 64;
/// Capacity of the force → simulation event ring (4 s at 1 kHz).
pub const EVENT_RING: usize = 4096;

/// One cursor sample as the network side received it.
#[derive(Debug, Clone, Copy)]
pub struct CursorMsg {
    /// Header (sequence, the server's timestamp).
    pub packet_sequence: u32,
    /// The server's clock when it sent the sample, ns.
    pub server_timestamp_ns: u64,
    /// When the workstation received it.
    pub received: Instant,
    /// The sample.
    pub cursor: CursorSample,
}

impl CursorMsg {
    /// From a received packet.
    pub fn new(packet: &Packet, cursor: CursorSample, received: Instant) -> Self {
        Self {
            packet_sequence: packet.sequence,
            server_timestamp_ns: packet.timestamp_ns,
            received,
            cursor,
        }
    }
}

/// The cursor as the simulation sees it, once per force tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InputEvent {
    /// Tip position in the scene (m).
    pub position: DVec3,
    /// Tip velocity in the scene (m/s).
    pub velocity: DVec3,
    /// Stylus orientation in the scene.
    pub orientation: DQuat,
    /// Button mask (bit 0: the tool button).
    pub buttons: u16,
    /// The force sent for this cursor, scene frame (N).
    pub force: DVec3,
    /// The surface point and outward normal under the tip, when in or near contact.
    pub contact: Option<(DVec3, DVec3)>,
}

impl InputEvent {
    /// The tool button is down.
    pub fn pressed(&self) -> bool {
        self.buttons & 1 != 0
    }
}

/// What the force thread renders, with the settings it renders it with; published by the
/// simulation when a stroke starts, moves or ends, or the settings change.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ForceTool {
    /// Touch the surface: field force with friction.
    Touch(ContactSpec),
    /// A rope stroke: a spring from the tip to `anchor`, the picked surface point as it moves.
    Rope {
        /// Where the rope holds the surface (m).
        anchor: DVec3,
        /// Spring stiffness (N/m).
        stiffness: f64,
        /// Largest force (N).
        max_force: f64,
    },
    /// The shaped probe against the surface samples.
    Probe(ProbeSpec),
}

/// Points for the renderer, published by the simulation at the rendering rate.
#[derive(Debug, Clone, Default)]
pub struct RenderSnapshot {
    /// Positions, unit normals and sRGB colours of the visible objects' points, in chunks
    /// shared with earlier snapshots where nothing changed.
    pub points: ChunkedPoints,
    /// The sculpting region box.
    pub region: Option<(DVec3, DVec3)>,
    /// The selected tool.
    pub tool: Option<ToolKind>,
    /// The sculpted object's name.
    pub region_object: Option<String>,
    /// Probe semi-axes, when the probe is the tool.
    pub probe_semi_axes: Option<DVec3>,
    /// Simulation steps so far.
    pub steps: u64,
}

/// A relaxed atomic `f64`.
#[derive(Debug, Default)]
pub struct AtomicF64(AtomicU64);

impl AtomicF64 {
    /// Store.
    pub fn set(&self, v: f64) {
        self.0.store(v.to_bits(), Ordering::Relaxed);
    }
    /// Load.
    pub fn get(&self) -> f64 {
        f64::from_bits(self.0.load(Ordering::Relaxed))
    }
}

/// The last cursor, force and contact (for the renderer and reports); the cursor is NaN until
/// the first one arrives.
#[derive(Debug)]
pub struct HapticMonitor {
    /// Tip in the scene.
    pub cursor: [AtomicF64; 3],
    /// Force sent, scene frame.
    pub force: [AtomicF64; 3],
    /// Contact point (NaN when none).
    pub contact: [AtomicF64; 3],
    /// Buttons.
    pub buttons: AtomicU64,
}

impl Default for HapticMonitor {
    fn default() -> Self {
        let m = Self {
            cursor: Default::default(),
            force: Default::default(),
            contact: Default::default(),
            buttons: AtomicU64::new(0),
        };
        Self::set3(&m.cursor, DVec3::splat(f64::NAN));
        Self::set3(&m.contact, DVec3::splat(f64::NAN));
        m
    }
}

impl HapticMonitor {
    fn set3(slot: &[AtomicF64; 3], v: DVec3) {
        for (s, x) in slot.iter().zip(v.to_array()) {
            s.set(x);
        }
    }
    fn get3(slot: &[AtomicF64; 3]) -> DVec3 {
        DVec3::new(slot[0].get(), slot[1].get(), slot[2].get())
    }
    /// Record one tick.
    pub fn record(&self, e: &InputEvent) {
        Self::set3(&self.cursor, e.position);
        Self::set3(&self.force, e.force);
        Self::set3(
            &self.contact,
            e.contact.map_or(DVec3::splat(f64::NAN), |c| c.0),
        );
        self.buttons.store(u64::from(e.buttons), Ordering::Relaxed);
    }
    /// The last tip position.
    pub fn cursor(&self) -> DVec3 {
        Self::get3(&self.cursor)
    }
    /// The last force sent (scene frame).
    pub fn force(&self) -> DVec3 {
        Self::get3(&self.force)
    }
    /// The last contact point.
    pub fn contact(&self) -> Option<DVec3> {
        Some(Self::get3(&self.contact)).filter(|c| c.is_finite())
    }
}

/// Percentiles in microseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct PercentilesUs {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// 99.9th percentile.
    pub p999: f64,
    /// Largest.
    pub max: f64,
}

/// Percentiles published through atomics.
#[derive(Debug, Default)]
pub struct AtomicPercentiles {
    p50: AtomicF64,
    p99: AtomicF64,
    p999: AtomicF64,
    max: AtomicF64,
}

impl AtomicPercentiles {
    /// Publish.
    pub fn set(&self, p: PercentilesUs) {
        self.p50.set(p.p50);
        self.p99.set(p.p99);
        self.p999.set(p.p999);
        self.max.set(p.max);
    }
    /// Read.
    pub fn get(&self) -> PercentilesUs {
        PercentilesUs {
            p50: self.p50.get(),
            p99: self.p99.get(),
            p999: self.p999.get(),
            max: self.max.get(),
        }
    }
}

/// Statistics of one loop, written by its thread, read by anyone.
#[derive(Debug, Default)]
pub struct LoopStats {
    /// Iterations since the statistics were last reset.
    pub ticks: AtomicU64,
    /// Seconds covered by `ticks`.
    pub seconds: AtomicF64,
    /// Period between iterations.
    pub period_us: AtomicPercentiles,
    /// Work inside one iteration.
    pub work_us: AtomicPercentiles,
    /// Ask the loop to start its statistics afresh.
    pub reset: AtomicBool,
}

impl LoopStats {
    /// Iterations per second since the last reset.
    pub fn rate_hz(&self) -> f64 {
        let s = self.seconds.get();
        if s > 0.0 {
            self.ticks.load(Ordering::Relaxed) as f64 / s
        } else {
            0.0
        }
    }
}

/// Which cursor each force command answered, so the cursors' acknowledgements tell the age of
/// the command every servo tick applied ([`protocol::AppliedAge`]). The force thread writes a
/// slot per command it sends, the network thread reads it per cursor: lock-free, allocated
/// once; a slot is overwritten [`AppliedAgeTracker::SLOTS`] commands later (1 s at 1 kHz), and
/// an acknowledgement of an overwritten command counts as "no command" rather than a wrong age.
#[derive(Debug)]
pub struct AppliedAgeTracker {
    /// Per command sequence modulo `SLOTS`: `sequence << 32 | answered cursor's servo tick`.
    answered: Box<[AtomicU64]>,
    /// Ticks applying the answer to the previous tick's cursor, 1 late, ≥ 2 late, none yet.
    counts: [AtomicU64; 4],
}

impl Default for AppliedAgeTracker {
    fn default() -> Self {
        Self {
            answered: (0..Self::SLOTS).map(|_| AtomicU64::new(u64::MAX)).collect(),
            counts: Default::default(),
        }
    }
}

impl AppliedAgeTracker {
    /// Commands remembered.
    pub const SLOTS: usize = 1024;

    /// The force thread sent command `sequence` answering the cursor of servo tick
    /// `answers_tick`.
    pub fn sent(&self, sequence: u32, answers_tick: u32) {
        self.answered[sequence as usize % Self::SLOTS].store(
            u64::from(sequence) << 32 | u64::from(answers_tick),
            Ordering::Relaxed,
        );
    }

    /// A cursor arrived: count its tick by the age of the command it says was applied.
    pub fn on_cursor(&self, cursor: &CursorSample) {
        let answers_tick = cursor.ack.and_then(|ack| {
            let v = self.answered[ack.sequence as usize % Self::SLOTS].load(Ordering::Relaxed);
            (v >> 32 == u64::from(ack.sequence)).then_some(v as u32)
        });
        let mut one = protocol::AppliedAge::default();
        one.record(cursor.servo_tick, answers_tick);
        for (slot, n) in
            self.counts
                .iter()
                .zip([one.next, one.two, one.three_or_more, one.no_command])
        {
            slot.fetch_add(n, Ordering::Relaxed);
        }
    }

    /// The counts so far.
    pub fn get(&self) -> protocol::AppliedAge {
        let [next, two, three_or_more, no_command] =
            self.counts.each_ref().map(|c| c.load(Ordering::Relaxed));
        protocol::AppliedAge {
            next,
            two,
            three_or_more,
            no_command,
        }
    }
}

/// Network statistics.
#[derive(Debug, Default)]
pub struct NetStats {
    /// A session is up.
    pub connected: AtomicBool,
    /// Sessions opened (1 + reconnects).
    pub sessions: AtomicU64,
    /// Cursor samples received.
    pub cursors: AtomicU64,
    /// When the last cursor arrived (the session's client clock, ns): the network side ends a
    /// session silent for [`CURSOR_SILENCE`](super::net::CURSOR_SILENCE) when the force
    /// thread takes the cursors off the socket itself (UDP).
    pub last_cursor_ns: AtomicU64,
    /// Cursors dropped because the force thread's ring was full.
    pub cursors_dropped: AtomicU64,
    /// Cursors the force thread skipped because a newer one was already waiting.
    pub cursors_skipped: AtomicU64,
    /// Cursors refused because a newer one was already mapped (the network reordered them).
    pub cursors_late: AtomicU64,
    /// Force commands sent.
    pub forces_sent: AtomicU64,
    /// Force commands the perceptual deadband held back (not felt as different).
    pub forces_held: AtomicU64,
    /// Perceptual deadband on the force stream (Weber fraction; 0 = every command), read by
    /// the force thread every tick (`run --force-deadband`).
    pub force_deadband: AtomicF64,
    /// Clock offset server − workstation (ns) and its bound.
    pub clock_offset_ns: AtomicF64,
    /// Bound of the offset (ns).
    pub clock_uncertainty_ns: AtomicF64,
    /// Round trip of the clock ping the offset estimate used (ns).
    pub ping_rtt_ns: AtomicU64,
    /// Cursor → force round trip as the server measured it (its `Stats`).
    pub force_rtt_us: AtomicPercentiles,
    /// Cursor received → force sent inside the workstation, the last tick (ns).
    pub turnaround_ns: AtomicU64,
    /// Server servo period p99 (µs), from its `Stats`.
    pub server_period_p99_us: AtomicF64,
    /// Server servo rate between its last two `Stats` (Hz).
    pub servo_hz: AtomicF64,
    /// The last `Stats`' servo ticks and uptime (ns), for the rate.
    pub server_ticks: [AtomicU64; 2],
    /// Why the last attempt to connect failed (certificate mismatch, unauthenticated, busy,
    /// version mismatch, refused, timed out), for the window's status line; cleared when a
    /// session comes up. Written by the network thread at its retry rate, read by anyone.
    pub connect_error: ArcSwapOption<String>,
    /// The age of the command each servo tick applied.
    pub applied: AppliedAgeTracker,
}

/// Everything shared between the threads of one workstation.
#[derive(Debug)]
pub struct Shared {
    /// The sculpting region's field, newest first.
    pub field: ArcSwapOption<ScalarGrid>,
    /// The surface samples the probe touches.
    pub samples: ArcSwapOption<SampleGrid>,
    /// What the force thread renders besides the field.
    pub tool: ArcSwap<ForceTool>,
    /// Points for the renderer.
    pub render: ArcSwapOption<RenderSnapshot>,
    /// The last cursor, force and contact.
    pub haptic: HapticMonitor,
    /// The force-mapping loop.
    pub force_loop: LoopStats,
    /// The simulation loop.
    pub sim_loop: LoopStats,
    /// The field's part of each simulation step: tools, integration, publishing (what the force
    /// thread's snapshot waits for).
    pub field_loop: LoopStats,
    /// Simulation steps run.
    pub sim_steps: AtomicU64,
    /// The network side.
    pub net: NetStats,
    /// Events dropped because the simulation's ring was full.
    pub events_dropped: AtomicU64,
    /// Every thread ends when set.
    pub stop: AtomicBool,
}

impl Default for Shared {
    fn default() -> Self {
        Self {
            field: ArcSwapOption::empty(),
            samples: ArcSwapOption::empty(),
            tool: ArcSwap::from_pointee(ForceTool::Touch(ContactSpec::default())),
            render: ArcSwapOption::empty(),
            haptic: HapticMonitor::default(),
            force_loop: LoopStats::default(),
            sim_loop: LoopStats::default(),
            field_loop: LoopStats::default(),
            sim_steps: AtomicU64::new(0),
            net: NetStats::default(),
            events_dropped: AtomicU64::new(0),
            stop: AtomicBool::new(false),
        }
    }
}

impl Shared {
    /// A fresh shared state.
    pub fn new() -> Arc<Self> {
        Arc::new(Self::default())
    }

    /// Ask every thread to end.
    pub fn request_stop(&self) {
        self.stop.store(true, Ordering::Release);
    }

    /// Whether the threads should end.
    pub fn stopping(&self) -> bool {
        self.stop.load(Ordering::Acquire)
    }
}
