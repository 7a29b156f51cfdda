//! The driver thread: the only place the servo loop meets time, the device and the network.
//!
//! Per period: wait for the absolute deadline ([`rt::wait_until`]: sleep, then a short spin),
//! drain the session-event ring, then the force commands: on UDP straight from the socket
//! ([`HotSocket::drain`]: non-blocking reads, kernel arrival stamps, no receiver thread in
//! between), on QUIC from the ring its receiver fills (wait-free `rtrb` pops); read the device,
//! [`ServoCore::tick`], publish the cursor unless the perceptual deadband holds it back
//! ([`CursorDeadband`], off by default; then one non-blocking `send_to` for UDP, or a ring push
//! plus the one-byte send that wakes the QUIC sender task, [`RingWaker`]), write the force,
//! push a [`TickRecord`] to the
//! telemetry ring. No allocation, no lock, no blocking call inside the tick; full rings drop
//! (telemetry) or keep the newest (commands are drained every tick, so they never fill).
//! A tick that starts more than one period late is an overrun; missed deadlines are skipped,
//! not made up in a burst.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use glam::Vec3;
use protocol::packet::MAX_PACKET_BYTES;
use protocol::{Body, CursorDeadband, ForceCommand, Outbound, SessionKey};

use super::core::{ServoCore, ServoParams, SessionEvent};
use super::hot_socket::HotSocket;
use super::rt::{self, RtReport, RtRequest};
use crate::clock::MonoClock;
use crate::device::{Device, DeviceSample};
use crate::telemetry::{self, HotTick, ServoStats, Telemetry, TickRecord, record::Recorder};

/// A message from the network side to the servo thread.
#[derive(Debug, Clone)]
pub enum ServoMsg {
    /// A session started: arm the output, number cursor packets for `session` (MAC'd with
    /// `key` when `Some`, i.e. UDP, whose packets the servo thread then checks itself).
    Start {
        /// Session id from `Welcome`.
        session: u32,
        /// The hot-path key (UDP only).
        key: Option<SessionKey>,
    },
    /// A settings or emergency-stop event for the core.
    Core(SessionEvent),
    /// The session ended.
    End,
}

/// One encoded cursor packet on its way to the QUIC sender task.
#[derive(Debug, Clone, Copy)]
pub struct Datagram {
    /// Valid bytes in `bytes`.
    pub len: usize,
    /// The packet.
    pub bytes: [u8; MAX_PACKET_BYTES],
}

/// Where cursor packets go.
#[derive(Debug)]
pub enum CursorSink {
    /// Nowhere (loop-bench, tests of the loop alone).
    None,
    /// The UDP hot-path socket, read and written by the servo thread alone.
    Udp(Box<HotSocket>),
    /// A ring drained by the QUIC sender task, woken after each push by a byte on a datagram
    /// socket its runtime watches ([`RingWaker`]).
    Ring(rtrb::Producer<Datagram>, RingWaker),
}

/// The servo's end of a datagram socket pair: one non-blocking send of one byte wakes the
/// task on the other end (registered with its runtime's reactor): a system call and no lock,
/// like the UDP path's own send, and no thread between the servo and quinn. A full socket
/// buffer (the task behind) is ignored: a pending byte wakes it all the same.
#[derive(Debug)]
pub struct RingWaker(std::os::unix::net::UnixDatagram);

impl RingWaker {
    /// A connected pair: the waker, and the end the sender task reads (non-blocking both).
    pub fn pair() -> std::io::Result<(Self, std::os::unix::net::UnixDatagram)> {
        let (a, b) = std::os::unix::net::UnixDatagram::pair()?;
        a.set_nonblocking(true)?;
        b.set_nonblocking(true)?;
        Ok((Self(a), b))
    }

    /// Wake the task.
    pub fn wake(&self) {
        let _ = self.0.send(&[1]);
    }
}

/// The network side's handle on the servo thread.
#[derive(Debug)]
pub struct ServoLink {
    /// Validated force commands with their header sequence and arrival time (server clock,
    /// ns), from a receiver thread (QUIC; UDP commands never pass here).
    pub commands: rtrb::Producer<(ForceCommand, u32, u64)>,
    /// Session events.
    pub events: rtrb::Producer<ServoMsg>,
    /// The telemetry snapshot (updated every 10 ms by the telemetry thread).
    pub stats: Arc<Mutex<ServoStats>>,
    /// Set to start a new mark window of the telemetry (`lateness_since_mark_ns`).
    pub mark: Arc<AtomicBool>,
}

/// Everything the driver needs besides the device and sink.
#[derive(Debug, Clone)]
pub struct DriverConfig {
    /// Core parameters (rate, safety, smoothing).
    pub params: ServoParams,
    /// Real-time requests for the servo thread.
    pub rt: RtRequest,
    /// Spin this long before each deadline.
    pub spin: Duration,
    /// Log a telemetry summary this often (zero = never).
    pub log_every: Duration,
    /// Record the session here.
    pub record: Option<PathBuf>,
    /// Perceptual deadband on published cursors (Weber fraction; 0 = every tick).
    pub cursor_deadband: f32,
}

/// The running servo and telemetry threads.
#[derive(Debug)]
pub struct ServoThreads {
    stop: Arc<AtomicBool>,
    servo: Option<JoinHandle<RtReport>>,
    telemetry: Option<JoinHandle<()>>,
}

impl ServoThreads {
    /// Stop the loop (the device is left at zero force) and wait for both threads.
    pub fn stop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(h) = self.servo.take() {
            let _ = h.join();
        }
        if let Some(h) = self.telemetry.take() {
            let _ = h.join();
        }
    }
}

impl Drop for ServoThreads {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Start the servo thread (and its telemetry thread) on `device`.
pub fn spawn<D: Device + 'static>(
    mut device: D,
    sink: CursorSink,
    cfg: DriverConfig,
    clock: MonoClock,
) -> std::io::Result<(ServoLink, ServoThreads)> {
    let (commands, command_rx) = rtrb::RingBuffer::new(256);
    let (events, event_rx) = rtrb::RingBuffer::new(64);
    let (mut record_tx, mut record_rx) = rtrb::RingBuffer::new(16_384);
    prefault(&mut record_tx, &mut record_rx);
    let stats = Arc::new(Mutex::new(ServoStats::default()));
    let stop = Arc::new(AtomicBool::new(false));
    let dropped = Arc::new(AtomicU64::new(0));
    let mark = Arc::new(AtomicBool::new(false));
    let recorder = match &cfg.record {
        Some(p) => Some(Recorder::create(p)?),
        None => None,
    };
    let telemetry = {
        let (stats, stop, dropped, mark) = (
            Arc::clone(&stats),
            Arc::clone(&stop),
            Arc::clone(&dropped),
            Arc::clone(&mark),
        );
        let log_every = cfg.log_every;
        std::thread::Builder::new()
            .name("telemetry".into())
            .spawn(move || {
                telemetry::run(
                    record_rx,
                    Telemetry::new(recorder),
                    stats,
                    dropped,
                    stop,
                    mark,
                    log_every,
                )
            })?
    };
    let servo = {
        let stop = Arc::clone(&stop);
        std::thread::Builder::new()
            .name("servo".into())
            .spawn(move || {
                let report = rt::setup_current_thread(cfg.rt);
                for w in &report.warnings {
                    tracing::warn!("{w}");
                }
                if let Err(e) = device.start() {
                    tracing::error!("device start failed: {e}");
                }
                let mut lp = Loop {
                    core: ServoCore::new(cfg.params),
                    sink,
                    outbound: None,
                    command_rx,
                    event_rx,
                    record_tx,
                    dropped,
                    clock,
                    last_sample: DeviceSample::default(),
                    buf: [0; MAX_PACKET_BYTES],
                    deadband: CursorDeadband::new(cfg.cursor_deadband),
                };
                lp.run(&mut device, &stop, cfg.params.period_ns(), cfg.spin);
                device.stop();
                report
            })?
    };
    let link = ServoLink {
        commands,
        events,
        stats,
        mark,
    };
    Ok((
        link,
        ServoThreads {
            stop,
            servo: Some(servo),
            telemetry: Some(telemetry),
        },
    ))
}

/// Write every slot of the telemetry ring once, so its pages are resident from the start:
/// otherwise the servo thread's first lap around it (16 s at 1 kHz) touches a new page every
/// few ticks, a page fault in the 1 kHz path and resident memory that seems to grow.
fn prefault(tx: &mut rtrb::Producer<TickRecord>, rx: &mut rtrb::Consumer<TickRecord>) {
    let blank = TickRecord::default();
    while tx.push(blank).is_ok() {}
    while rx.pop().is_ok() {}
}

struct Loop {
    core: ServoCore,
    sink: CursorSink,
    outbound: Option<Outbound>,
    command_rx: rtrb::Consumer<(ForceCommand, u32, u64)>,
    event_rx: rtrb::Consumer<ServoMsg>,
    record_tx: rtrb::Producer<TickRecord>,
    dropped: Arc<AtomicU64>,
    clock: MonoClock,
    last_sample: DeviceSample,
    buf: [u8; MAX_PACKET_BYTES],
    deadband: CursorDeadband,
}

impl Loop {
    fn run(&mut self, device: &mut dyn Device, stop: &AtomicBool, period_ns: u64, spin: Duration) {
        // A vendor scheduler (OpenHaptics) may drive the ticks instead of our deadlines.
        let clock = self.clock;
        let mut prev_ns: Option<u64> = None;
        let scheduled = device.run_scheduled(&mut |dev| {
            if stop.load(Ordering::Acquire) {
                return false;
            }
            let now_ns = clock.now_ns();
            let late = prev_ns.map_or(0, |p| now_ns.saturating_sub(p).saturating_sub(period_ns));
            self.tick_and_record(dev, now_ns, Duration::from_nanos(late), prev_ns, period_ns);
            prev_ns = Some(now_ns);
            true
        });
        match scheduled {
            Some(Ok(())) => return,
            Some(Err(e)) => {
                tracing::error!("device scheduler failed: {e}");
                return;
            }
            None => {}
        }
        let period = Duration::from_nanos(period_ns);
        let mut deadline = Instant::now() + period;
        while !stop.load(Ordering::Acquire) {
            let started = rt::wait_until(deadline, spin);
            let now_ns = self.clock.ns_at(started);
            let lateness = started.saturating_duration_since(deadline);
            self.tick_and_record(device, now_ns, lateness, prev_ns, period_ns);
            prev_ns = Some(now_ns);
            deadline += period;
            let now = Instant::now();
            if now > deadline + period {
                // Fell behind: skip the missed deadlines instead of bursting to catch up.
                let behind = now.saturating_duration_since(deadline).as_nanos()
                    / u128::from(period_ns.max(1));
                deadline += period * u32::try_from(behind).unwrap_or(u32::MAX);
            }
        }
    }

    fn tick_and_record(
        &mut self,
        device: &mut dyn Device,
        now_ns: u64,
        lateness: Duration,
        prev_ns: Option<u64>,
        period_ns: u64,
    ) {
        let mut record = self.tick(device, now_ns);
        let cost = self.clock.now_ns().saturating_sub(now_ns);
        record.lateness_ns = u64::try_from(lateness.as_nanos()).unwrap_or(u64::MAX);
        record.cost_ns = cost;
        record.period_ns = prev_ns.map_or(0, |p| now_ns.saturating_sub(p));
        record.overrun = record.lateness_ns > period_ns;
        if self.record_tx.push(record).is_err() {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// One tick; see the module doc. No allocation, no lock.
    fn tick(&mut self, device: &mut dyn Device, now_ns: u64) -> TickRecord {
        while let Ok(msg) = self.event_rx.pop() {
            match msg {
                ServoMsg::Start { session, key } => {
                    if let CursorSink::Udp(socket) = &mut self.sink {
                        socket.start(session, key.clone(), now_ns);
                    }
                    self.outbound = Some(Outbound::new(session, key));
                    self.deadband.reset();
                    self.core.on_event(now_ns, SessionEvent::Start);
                }
                ServoMsg::Core(ev) => self.core.on_event(now_ns, ev),
                ServoMsg::End => {
                    if let CursorSink::Udp(socket) = &mut self.sink {
                        socket.end();
                    }
                    self.outbound = None;
                    self.core.on_event(now_ns, SessionEvent::End);
                }
            }
        }
        let core = &mut self.core;
        let hot = match &mut self.sink {
            CursorSink::Udp(socket) => socket.drain(&self.clock, |cmd, sequence, arrived| {
                core.on_command_packet(arrived, sequence, cmd);
            }),
            _ => HotTick::default(),
        };
        while let Ok((cmd, sequence, arrived)) = self.command_rx.pop() {
            self.core.on_command_packet(arrived, sequence, cmd);
        }
        let mut device_error = false;
        match device.read(now_ns) {
            Ok(s) => self.last_sample = s,
            Err(_) => device_error = true,
        }
        let out = self.core.tick(now_ns, &self.last_sample);
        let force = if out.safety.force.is_finite() {
            out.safety.force
        } else {
            Vec3::ZERO
        };
        if device.write_force(force).is_err() {
            device_error = true;
        }
        // The cursor goes out last, just before the thread sleeps: the workstation's thread
        // it wakes can then run on this core at once instead of waking an idle one.
        let sent = self.publish(now_ns, &out.cursor);
        TickRecord {
            now_ns,
            lateness_ns: 0,
            period_ns: 0,
            cost_ns: 0,
            overrun: false,
            sent,
            clamped: out.safety.clamped,
            fade_started: out.safety.fade_started,
            nonfinite: out.safety.nonfinite,
            device_error,
            cursor: out.cursor,
            hot,
        }
    }

    fn publish(&mut self, now_ns: u64, cursor: &protocol::CursorSample) -> bool {
        let Some(outbound) = &mut self.outbound else {
            return false;
        };
        // The deadband holds back cursors the workstation would not feel the difference of
        // (off by default); the heartbeat (10 ms) keeps the stream alive.
        if !self.deadband.should_send(now_ns, cursor) {
            return false;
        }
        match &mut self.sink {
            CursorSink::None => false,
            CursorSink::Udp(socket) => {
                if socket.peer.is_none() {
                    return false;
                }
                let len = outbound.encode(now_ns, Body::Cursor(*cursor), &mut self.buf);
                socket.send(&self.buf[..len])
            }
            CursorSink::Ring(producer, waker) => {
                let mut d = Datagram {
                    len: 0,
                    bytes: [0; MAX_PACKET_BYTES],
                };
                d.len = outbound.encode(now_ns, Body::Cursor(*cursor), &mut d.bytes);
                let ok = producer.push(d).is_ok();
                waker.wake();
                ok
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::fake::{FakeDevice, FakeParams, HandPath};

    /// Drive the loop's own tick on a virtual clock (1 kHz, `ms` ticks) with the hand
    /// sliding 15 mm/s and pressing the button from 400 to 600 ms; the published cursors.
    fn published(deadband: f32, ms: u64) -> Vec<protocol::CursorSample> {
        let (tx, mut rx) = rtrb::RingBuffer::new(4096);
        let (mut events, event_rx) = rtrb::RingBuffer::new(8);
        let (_commands, command_rx) = rtrb::RingBuffer::new(8);
        let (record_tx, _records) = rtrb::RingBuffer::new(4096);
        let params = ServoParams::omni_at_1khz();
        let (waker, _wake) = RingWaker::pair().unwrap();
        let mut lp = Loop {
            core: ServoCore::new(params),
            sink: CursorSink::Ring(tx, waker),
            outbound: None,
            command_rx,
            event_rx,
            record_tx,
            dropped: Arc::default(),
            clock: MonoClock::new(),
            last_sample: DeviceSample::default(),
            buf: [0; MAX_PACKET_BYTES],
            deadband: CursorDeadband::new(deadband),
        };
        let path: Arc<[(f32, Vec3, u16)]> = vec![
            (0.0, Vec3::ZERO, 0),
            (0.4, Vec3::X * 0.006, 1),
            (0.6, Vec3::X * 0.009, 0),
            (10.0, Vec3::X * 0.15, 0),
        ]
        .into();
        let mut dev = FakeDevice::new(FakeParams {
            path: HandPath::Recorded(path),
            tremor_m: 0.0,
            ..FakeParams::default()
        });
        events
            .push(ServoMsg::Start {
                session: 1,
                key: None,
            })
            .unwrap();
        let mut out = Vec::new();
        for t in 1..=ms {
            lp.tick(&mut dev, t * 1_000_000);
            while let Ok(d) = rx.pop() {
                let p = protocol::Packet::decode(&d.bytes[..d.len]).unwrap();
                if let protocol::Body::Cursor(c) = p.body {
                    out.push(c);
                }
            }
        }
        out
    }

    #[test]
    fn the_cursor_deadband_thins_the_stream_but_sends_every_button_change() {
        let all = published(0.0, 1000);
        assert_eq!(all.len(), 1000, "off: every tick");
        let thin = published(0.1, 1000);
        assert!(thin.len() < 250, "{} of 1000 sent", thin.len());
        assert!(thin.len() >= 100, "the 10 ms heartbeat at least");
        // Every tick's button state reached the workstation in order: the press and release.
        let presses = |cs: &[protocol::CursorSample]| {
            cs.windows(2)
                .filter(|w| w[0].buttons != w[1].buttons)
                .count()
        };
        assert_eq!(presses(&thin), presses(&all));
        assert_eq!(presses(&all), 2);
        // The largest gap between published ticks is the heartbeat.
        let gap = thin
            .windows(2)
            .map(|w| w[1].servo_tick - w[0].servo_tick)
            .max()
            .unwrap();
        assert!(gap <= 10, "{gap}");
    }
}
