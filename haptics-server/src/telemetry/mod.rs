//! Telemetry, off the servo thread: the servo thread pushes one [`TickRecord`] per tick into a
//! wait-free ring; the telemetry thread drains it into HDR histograms (period, tick cost,
//! lateness), counters, the optional session recording ([`record`]) and a periodic `tracing`
//! summary, and publishes a [`ServoStats`] snapshot for the network side's `Stats` messages.
//! If the ring is full the record is dropped and counted (`dropped_records`): the servo thread
//! never waits for telemetry.

pub mod record;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use glam::Vec3;
use hdrhistogram::Histogram;
use protocol::control::Percentiles;
use protocol::{CursorSample, RejectCounts, SequenceStats};

/// One tick, as the servo thread saw it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TickRecord {
    /// Tick start, server clock, ns.
    pub now_ns: u64,
    /// How late the tick started after its deadline, ns.
    pub lateness_ns: u64,
    /// Time since the previous tick started, ns (0 on the first).
    pub period_ns: u64,
    /// Work inside the tick (read, core, publish, write), ns.
    pub cost_ns: u64,
    /// The tick started more than one period after its deadline.
    pub overrun: bool,
    /// The cursor packet went out.
    pub sent: bool,
    /// The clamp cut the force.
    pub clamped: bool,
    /// The watchdog began fading.
    pub fade_started: bool,
    /// A non-finite force was blocked.
    pub nonfinite: bool,
    /// The device read or write failed.
    pub device_error: bool,
    /// The published cursor (its `output_force` is the force written).
    pub cursor: CursorSample,
    /// What the servo's own hot-path socket did (UDP; all default on other transports).
    pub hot: HotTick,
}

/// The UDP hot path as the servo thread drained it on one tick
/// ([`crate::servo::hot_socket::HotSocket`]): this tick's events and the session's running
/// counts.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct HotTick {
    /// The session whose packets are accepted (`None` between sessions).
    pub session: Option<u32>,
    /// Authentic packets of this session so far.
    pub packets_in: u64,
    /// Arrival of the newest authentic packet (server clock, ns).
    pub last_activity_ns: u64,
    /// Rejections of this session so far, by reason.
    pub rejected: RejectCounts,
    /// Loss and reordering of this session's accepted packets.
    pub force_sequence: SequenceStats,
    /// Packets that arrived with no session, since the server started.
    pub unsolicited: u64,
    /// Datagrams read on this tick.
    pub drained: u32,
    /// The drain stopped at its per-tick cap with more queued.
    pub capped: bool,
    /// Cursor → arrival round trip of the command applied on this tick, ns (0: none).
    pub applied_rtt_ns: u64,
    /// The client's hot-path address.
    pub peer: Option<std::net::SocketAddr>,
    /// The address changed on this tick.
    pub peer_changed: bool,
}

/// The UDP hot path's numbers for `Stats`, from the servo thread's [`HotTick`]s.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct HotPathStats {
    /// The session they belong to (`None`: no session yet, or not the UDP transport).
    pub session: Option<u32>,
    /// Authentic packets of the session.
    pub packets_in: u64,
    /// Arrival of the newest authentic packet (server clock, ns).
    pub last_activity_ns: u64,
    /// Rejections of the session, by reason.
    pub rejected: RejectCounts,
    /// Loss and reordering of the session's accepted packets.
    pub force_sequence: SequenceStats,
    /// Cursor → arrival round trips of the session's applied commands.
    pub force_rtt_ns: Percentiles,
    /// Packets that arrived with no session, since the server started.
    pub unsolicited: u64,
    /// Ticks whose drain hit its cap (a flood), since the server started.
    pub capped_ticks: u64,
}

/// Servo-side numbers for `Stats` and logs.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ServoStats {
    /// Time since the first tick, ns.
    pub uptime_ns: u64,
    /// Ticks run.
    pub ticks: u64,
    /// Ticks that started more than one period late.
    pub overruns: u64,
    /// Tick-to-tick period.
    pub period_ns: Percentiles,
    /// Work inside one tick.
    pub tick_cost_ns: Percentiles,
    /// Start lateness after the deadline.
    pub lateness_ns: Percentiles,
    /// Start lateness since the last mark ([`crate::server::Server::mark_telemetry`]), so a
    /// run can compare phases (with and without load) of one server.
    pub lateness_since_mark_ns: Percentiles,
    /// Cursor packets sent.
    pub packets_out: u64,
    /// Ticks with the clamp active.
    pub clamped_ticks: u64,
    /// Watchdog fades begun.
    pub watchdog_fades: u64,
    /// Non-finite forces blocked.
    pub nonfinite_blocked: u64,
    /// Device read/write failures.
    pub device_errors: u64,
    /// Tick records lost because the telemetry ring was full.
    pub dropped_records: u64,
    /// Output live on the last tick.
    pub engaged: bool,
    /// The last force written, N.
    pub last_force: Vec3,
    /// The UDP hot path, read by the servo thread itself.
    pub hot: HotPathStats,
}

fn histogram() -> Histogram<u64> {
    // 1 ns … 10 s at 3 significant digits; allocated once, `record` never allocates.
    Histogram::new_with_bounds(1, 10_000_000_000, 3).expect("constant, valid histogram bounds")
}

/// p50/p99/p99.9/max of a histogram.
pub fn percentiles(h: &Histogram<u64>) -> Percentiles {
    Percentiles {
        p50: h.value_at_quantile(0.5),
        p99: h.value_at_quantile(0.99),
        p999: h.value_at_quantile(0.999),
        max: h.max(),
    }
}

/// The telemetry thread's state.
#[derive(Debug)]
pub struct Telemetry {
    period: Histogram<u64>,
    cost: Histogram<u64>,
    lateness: Histogram<u64>,
    window_cost: Histogram<u64>,
    window_lateness: Histogram<u64>,
    marked_lateness: Histogram<u64>,
    force_rtt: Histogram<u64>,
    stats: ServoStats,
    first_ns: Option<u64>,
    recorder: Option<record::Recorder>,
}

impl Telemetry {
    /// Empty histograms; `recorder` receives every tick when set.
    pub fn new(recorder: Option<record::Recorder>) -> Self {
        Self {
            period: histogram(),
            cost: histogram(),
            lateness: histogram(),
            window_cost: histogram(),
            window_lateness: histogram(),
            marked_lateness: histogram(),
            force_rtt: histogram(),
            stats: ServoStats::default(),
            first_ns: None,
            recorder,
        }
    }

    /// Account one tick.
    pub fn add(&mut self, r: &TickRecord) {
        let s = &mut self.stats;
        let first = *self.first_ns.get_or_insert(r.now_ns);
        s.uptime_ns = r.now_ns.saturating_sub(first);
        s.ticks += 1;
        s.overruns += u64::from(r.overrun);
        s.packets_out += u64::from(r.sent);
        s.clamped_ticks += u64::from(r.clamped);
        s.watchdog_fades += u64::from(r.fade_started);
        s.nonfinite_blocked += u64::from(r.nonfinite);
        s.device_errors += u64::from(r.device_error);
        s.engaged = r.cursor.engaged;
        s.last_force = r.cursor.output_force;
        let clamp = |v: u64| v.clamp(1, 10_000_000_000);
        if r.period_ns > 0 {
            let _ = self.period.record(clamp(r.period_ns));
        }
        let _ = self.cost.record(clamp(r.cost_ns));
        let _ = self.lateness.record(clamp(r.lateness_ns));
        let _ = self.window_cost.record(clamp(r.cost_ns));
        let _ = self.window_lateness.record(clamp(r.lateness_ns));
        let _ = self.marked_lateness.record(clamp(r.lateness_ns));
        self.add_hot(&r.hot);
        if let Some(rec) = &mut self.recorder
            && let Err(e) = rec.write(r)
        {
            tracing::error!("recording stopped: {e}");
            self.recorder = None;
        }
    }

    fn add_hot(&mut self, h: &HotTick) {
        let s = &mut self.stats.hot;
        if h.session != s.session {
            self.force_rtt.reset();
        }
        if h.peer_changed
            && let Some(peer) = h.peer
        {
            tracing::info!(%peer, "hot path: streaming cursor samples to the workstation");
        }
        if h.applied_rtt_ns > 0 {
            let _ = self
                .force_rtt
                .record(h.applied_rtt_ns.clamp(1, 10_000_000_000));
        }
        s.session = h.session;
        s.packets_in = h.packets_in;
        s.last_activity_ns = h.last_activity_ns;
        s.rejected = h.rejected;
        s.force_sequence = h.force_sequence;
        s.unsolicited = h.unsolicited;
        s.capped_ticks += u64::from(h.capped);
    }

    /// The current snapshot.
    pub fn snapshot(&mut self, dropped_records: u64) -> ServoStats {
        self.stats.hot.force_rtt_ns = percentiles(&self.force_rtt);
        self.stats.period_ns = percentiles(&self.period);
        self.stats.tick_cost_ns = percentiles(&self.cost);
        self.stats.lateness_ns = percentiles(&self.lateness);
        self.stats.lateness_since_mark_ns = percentiles(&self.marked_lateness);
        self.stats.dropped_records = dropped_records;
        self.stats
    }

    /// Start a new mark window ([`ServoStats::lateness_since_mark_ns`]).
    pub fn mark(&mut self) {
        self.marked_lateness.reset();
    }

    /// Log a summary of the window since the last call, then start a new window.
    pub fn log_window(&mut self) {
        let c = percentiles(&self.window_cost);
        let l = percentiles(&self.window_lateness);
        let s = &self.stats;
        tracing::info!(
            ticks = s.ticks,
            overruns = s.overruns,
            engaged = s.engaged,
            packets_out = s.packets_out,
            "servo: tick cost p50 {} ns p99 {} ns max {} ns; lateness p50 {} ns p99 {} ns max {} ns",
            c.p50,
            c.p99,
            c.max,
            l.p50,
            l.p99,
            l.max
        );
        self.window_cost.reset();
        self.window_lateness.reset();
    }

    /// Flush the recording.
    pub fn finish(&mut self) {
        if let Some(rec) = &mut self.recorder
            && let Err(e) = rec.flush()
        {
            tracing::error!("recording flush failed: {e}");
        }
    }
}

/// Run the telemetry thread until `stop` is set and the ring is drained. Setting `mark`
/// starts a new mark window (after the ticks already queued are accounted).
pub fn run(
    mut consumer: rtrb::Consumer<TickRecord>,
    mut telemetry: Telemetry,
    shared: Arc<Mutex<ServoStats>>,
    dropped: Arc<std::sync::atomic::AtomicU64>,
    stop: Arc<AtomicBool>,
    mark: Arc<AtomicBool>,
    log_every: Duration,
) {
    let mut last_log = std::time::Instant::now();
    loop {
        let stopping = stop.load(Ordering::Acquire);
        let marking = mark.swap(false, Ordering::AcqRel);
        while let Ok(r) = consumer.pop() {
            telemetry.add(&r);
        }
        if marking {
            telemetry.mark();
        }
        let snap = telemetry.snapshot(dropped.load(Ordering::Relaxed));
        if let Ok(mut s) = shared.lock() {
            *s = snap;
        }
        if !log_every.is_zero() && last_log.elapsed() >= log_every {
            telemetry.log_window();
            last_log = std::time::Instant::now();
        }
        if stopping {
            telemetry.finish();
            return;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}
