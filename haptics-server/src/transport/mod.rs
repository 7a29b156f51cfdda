//! Transports: what both share (one session at a time, the control conversation, hot-path
//! acceptance) and the two wire bindings, [`udp`] and [`quic`].
//!
//! A session: the client sends `Hello` on the control channel; if no other session is active
//! the server answers `Welcome` (fresh random session id and key) and tells the servo thread
//! ([`ServoMsg::Start`]); otherwise it answers `Error { Busy }` and closes. During the session
//! it answers `ClockPing`s, forwards `Config` and `EmergencyStop` to the servo thread, sends
//! `Stats` every `stats_interval`, and ends the session on `Bye`, on a closed control channel,
//! or when nothing authentic arrived for `idle_timeout` (the workstation vanished). Ending
//! sends [`ServoMsg::End`] (output falls to zero) and frees the slot for the next client.
//! Hot-path packets pass [`protocol::Inbound`] (MAC on UDP, session, replay window, ranges);
//! only accepted `ForceCommand`s reach the servo ring, rejects are counted by reason.

pub mod quic;
pub mod udp;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use protocol::control::{ClockPong, ControlError, ErrorCode, ErrorMessage, Stats, Welcome};
use protocol::{Body, Control, FrameDecoder, Inbound, PROTOCOL_VERSION, SessionKey};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};

use crate::clock::MonoClock;
use crate::device::DeviceInfo;
use crate::servo::SessionEvent;
use crate::servo::driver::{ServoLink, ServoMsg};
use crate::telemetry::ServoStats;

/// Timeouts and intervals of the network side.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NetSettings {
    /// A session with no authentic packet or control message for this long is dropped.
    pub idle_timeout: Duration,
    /// `Stats` are sent this often.
    pub stats_interval: Duration,
    /// A client must send `Hello` (and finish the TLS handshake) within this.
    pub hello_timeout: Duration,
}

impl Default for NetSettings {
    fn default() -> Self {
        Self {
            idle_timeout: Duration::from_secs(2),
            stats_interval: Duration::from_secs(1),
            hello_timeout: Duration::from_secs(5),
        }
    }
}

/// Why the network side failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TransportError {
    /// Socket I/O.
    #[error("I/O: {0}")]
    Io(#[from] std::io::Error),
    /// The peer broke the control protocol.
    #[error("control channel: {0}")]
    Control(#[from] ControlError),
    /// The peer took too long.
    #[error("timed out waiting for {0}")]
    Timeout(&'static str),
    /// QUIC connection error.
    #[error("QUIC: {0}")]
    Quic(String),
}

/// One session's hot-path state, shared by the control task and the packet receiver.
#[derive(Debug)]
pub struct HotState {
    /// The session id.
    pub session: u32,
    inbound: Mutex<Inbound>,
    packets_in: AtomicU64,
    last_activity_ns: AtomicU64,
    ended: AtomicBool,
    peer: Mutex<Option<std::net::SocketAddr>>,
}

/// Everything the network tasks share.
#[derive(Debug)]
pub struct Shared {
    /// The server clock (same epoch as the servo thread's).
    pub clock: MonoClock,
    link: Mutex<ServoLink>,
    /// What `Welcome` says about the device.
    pub device: DeviceInfo,
    /// Servo rate, Hz.
    pub servo_rate_hz: u32,
    /// Force limit the server applies, N.
    pub max_force_n: f32,
    /// Timeouts.
    pub net: NetSettings,
    active: Mutex<Option<Arc<HotState>>>,
    last_stats: Mutex<Stats>,
    /// Sessions started since the server started.
    pub sessions_started: AtomicU64,
    /// Clients refused because a session was active.
    pub refused_busy: AtomicU64,
    /// Hot-path packets that arrived with no session active.
    pub unsolicited: AtomicU64,
}

impl Shared {
    /// Shared state around the servo link.
    pub fn new(
        clock: MonoClock,
        link: ServoLink,
        device: DeviceInfo,
        servo_rate_hz: u32,
        max_force_n: f32,
        net: NetSettings,
    ) -> Self {
        Self {
            clock,
            link: Mutex::new(link),
            device,
            servo_rate_hz,
            max_force_n,
            net,
            active: Mutex::new(None),
            last_stats: Mutex::new(Stats::default()),
            sessions_started: AtomicU64::new(0),
            refused_busy: AtomicU64::new(0),
            unsolicited: AtomicU64::new(0),
        }
    }

    fn servo(&self, msg: ServoMsg) {
        if let Ok(mut link) = self.link.lock()
            && link.events.push(msg).is_err()
        {
            tracing::error!("servo event ring full; event dropped");
        }
    }

    /// The active session, if any.
    pub fn active(&self) -> Option<Arc<HotState>> {
        self.active.lock().ok().and_then(|a| a.clone())
    }

    /// Check one hot-path datagram against `hot`; accepted force commands go to the servo.
    /// Returns whether it was accepted.
    pub fn accept_hot(&self, hot: &HotState, datagram: &[u8]) -> bool {
        let now = self.clock.now_ns();
        let result = match hot.inbound.lock() {
            Ok(mut inbound) => inbound.accept(datagram),
            Err(_) => return false,
        };
        match result {
            Ok(packet) => {
                hot.packets_in.fetch_add(1, Ordering::Relaxed);
                hot.last_activity_ns.store(now, Ordering::Release);
                match packet.body {
                    Body::Force(cmd) => {
                        if let Ok(mut link) = self.link.lock() {
                            // Drained every tick; full only if the servo thread is stuck.
                            let _ = link.commands.push((cmd, now));
                        }
                        true
                    }
                    // A cursor sample sent to the server is authentic but meaningless.
                    Body::Cursor(_) => false,
                }
            }
            Err(e) => {
                tracing::debug!("hot-path packet rejected: {e}");
                false
            }
        }
    }

    /// `Stats` of `hot` (or the last session's, when `None`).
    pub fn stats(&self, hot: Option<&HotState>) -> Stats {
        let Some(hot) = hot else {
            return self.last_stats.lock().map(|s| *s).unwrap_or_default();
        };
        let servo: ServoStats = self
            .link
            .lock()
            .ok()
            .and_then(|l| l.stats.lock().ok().map(|s| *s))
            .unwrap_or_default();
        let (rejected, force_sequence) = match hot.inbound.lock() {
            Ok(i) => (*i.rejects(), i.sequence_stats()),
            Err(_) => Default::default(),
        };
        let stats = Stats {
            uptime_ns: servo.uptime_ns,
            ticks: servo.ticks,
            overruns: servo.overruns,
            period_ns: servo.period_ns,
            tick_cost_ns: servo.tick_cost_ns,
            packets_in: hot.packets_in.load(Ordering::Relaxed),
            packets_out: servo.packets_out,
            rejected,
            force_sequence,
            clamped_ticks: servo.clamped_ticks,
            watchdog_fades: servo.watchdog_fades,
            engaged: servo.engaged,
        };
        if let Ok(mut last) = self.last_stats.lock() {
            *last = stats;
        }
        stats
    }

    /// The servo thread's telemetry snapshot.
    pub fn servo_stats(&self) -> ServoStats {
        self.link
            .lock()
            .ok()
            .and_then(|l| l.stats.lock().ok().map(|s| *s))
            .unwrap_or_default()
    }

    fn claim(&self, key: Option<SessionKey>) -> Option<Arc<HotState>> {
        let mut active = self.active.lock().ok()?;
        if active.is_some() {
            return None;
        }
        let mut id = [0u8; 4];
        let _ = getrandom::fill(&mut id);
        let session = u32::from_le_bytes(id);
        let hot = Arc::new(HotState {
            session,
            inbound: Mutex::new(Inbound::new(session, key)),
            packets_in: AtomicU64::new(0),
            last_activity_ns: AtomicU64::new(self.clock.now_ns()),
            ended: AtomicBool::new(false),
            peer: Mutex::new(None),
        });
        *active = Some(Arc::clone(&hot));
        Some(hot)
    }

    fn release(&self, hot: &Arc<HotState>) {
        hot.ended.store(true, Ordering::Release);
        self.stats(Some(hot));
        if let Ok(mut active) = self.active.lock()
            && active.as_ref().is_some_and(|a| Arc::ptr_eq(a, hot))
        {
            *active = None;
        }
        self.servo(ServoMsg::End);
    }
}

impl HotState {
    /// The session has ended.
    pub fn ended(&self) -> bool {
        self.ended.load(Ordering::Acquire)
    }

    /// Record `addr` as the client's hot-path address; `true` if it changed.
    pub fn set_peer(&self, addr: std::net::SocketAddr) -> bool {
        match self.peer.lock() {
            Ok(mut p) if *p != Some(addr) => {
                *p = Some(addr);
                true
            }
            _ => false,
        }
    }
}

/// Write one control message.
pub async fn write_control<W: AsyncWrite + Unpin>(
    wr: &mut W,
    msg: &Control,
) -> std::io::Result<()> {
    wr.write_all(&msg.to_frame()).await?;
    wr.flush().await
}

/// Read the next control message; `Ok(None)` when the stream closed cleanly.
pub async fn read_control<R: AsyncRead + Unpin>(
    rd: &mut R,
    dec: &mut FrameDecoder,
) -> Result<Option<Control>, TransportError> {
    let mut buf = [0u8; 4096];
    loop {
        if let Some(msg) = dec.next_message()? {
            return Ok(Some(msg));
        }
        let n = rd.read(&mut buf).await?;
        if n == 0 {
            return Ok(None);
        }
        dec.push(&buf[..n]);
    }
}

fn error(code: ErrorCode, message: impl Into<String>) -> Control {
    Control::Error(ErrorMessage {
        code,
        message: message.into(),
    })
}

/// How a session's hot path is keyed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HotKind {
    /// UDP: MAC'd with a fresh session key.
    Udp,
    /// QUIC datagrams: no MAC (TLS protects them).
    Quic,
}

/// Run one control conversation (see the module doc). `on_start` is called once the session
/// is up (QUIC spawns its datagram reader there). Returns the session's hot state, if one
/// was started, after it ended.
pub async fn serve_control<R, W>(
    shared: &Arc<Shared>,
    rd: &mut R,
    wr: &mut W,
    kind: HotKind,
    on_start: impl FnOnce(Arc<HotState>),
) -> Result<Option<Arc<HotState>>, TransportError>
where
    R: AsyncRead + Unpin,
    W: AsyncWrite + Unpin,
{
    let mut dec = FrameDecoder::new();
    let hello =
        match tokio::time::timeout(shared.net.hello_timeout, read_control(rd, &mut dec)).await {
            Err(_) => return Err(TransportError::Timeout("Hello")),
            Ok(Err(TransportError::Control(e))) => {
                write_control(wr, &error(ErrorCode::InvalidMessage, e.to_string())).await?;
                return Err(e.into());
            }
            Ok(r) => r?,
        };
    let hello = match hello {
        Some(Control::Hello(h)) => h,
        None => return Ok(None),
        Some(other) => {
            let msg = format!("expected Hello, got {}", name(&other));
            write_control(wr, &error(ErrorCode::UnexpectedMessage, msg)).await?;
            return Ok(None);
        }
    };
    if hello.protocol_version != PROTOCOL_VERSION {
        let msg = format!(
            "server speaks protocol version {PROTOCOL_VERSION}, client {}",
            hello.protocol_version
        );
        write_control(wr, &error(ErrorCode::VersionMismatch, msg)).await?;
        return Ok(None);
    }
    let key = match kind {
        HotKind::Udp => {
            let mut k = [0u8; 32];
            getrandom::fill(&mut k).map_err(|e| std::io::Error::other(e.to_string()))?;
            Some(SessionKey::from_bytes(k))
        }
        HotKind::Quic => None,
    };
    let Some(hot) = shared.claim(key.clone()) else {
        shared.refused_busy.fetch_add(1, Ordering::Relaxed);
        tracing::warn!(client = %hello.client_name, "refused: another workstation holds the session");
        let msg = "busy: another workstation holds the session; one at a time";
        write_control(wr, &error(ErrorCode::Busy, msg)).await?;
        return Ok(None);
    };
    let d = &shared.device;
    let welcome = Welcome {
        protocol_version: PROTOCOL_VERSION,
        device_name: d.name.chars().take(100).collect(),
        dof_input: d.dof_input,
        dof_output: d.dof_output,
        workspace_min: d.workspace_min.to_array(),
        workspace_max: d.workspace_max.to_array(),
        max_force_n: shared.max_force_n,
        max_stiffness_n_per_m: d.max_stiffness_n_per_m,
        servo_rate_hz: shared.servo_rate_hz,
        session_id: hot.session,
        session_key: key.as_ref().map_or([0; 32], |k| *k.as_bytes()),
    };
    shared.sessions_started.fetch_add(1, Ordering::Relaxed);
    shared.servo(ServoMsg::Start {
        session: hot.session,
        key,
    });
    tracing::info!(client = %hello.client_name, session = format_args!("{:#010x}", hot.session), "session started");
    let result = async {
        write_control(wr, &Control::Welcome(welcome)).await?;
        on_start(Arc::clone(&hot));
        session_loop(shared, rd, wr, &hot, dec).await
    }
    .await;
    let s = shared.stats(Some(&hot));
    shared.release(&hot);
    let rejected: Vec<_> = s.rejected.nonzero().collect();
    match &result {
        Ok(reason) => tracing::info!(
            session = format_args!("{:#010x}", hot.session),
            packets_in = s.packets_in,
            packets_out = s.packets_out,
            ?rejected,
            "session ended: {reason}"
        ),
        Err(e) => tracing::warn!(
            session = format_args!("{:#010x}", hot.session),
            packets_in = s.packets_in,
            ?rejected,
            "session ended: {e}"
        ),
    }
    result.map(|_| Some(hot))
}

async fn session_loop<R, W>(
    shared: &Arc<Shared>,
    rd: &mut R,
    wr: &mut W,
    hot: &Arc<HotState>,
    mut dec: FrameDecoder,
) -> Result<String, TransportError>
where
    R: AsyncRead + Unpin,
    W: AsyncWrite + Unpin,
{
    let mut buf = [0u8; 4096];
    let mut check = tokio::time::interval(Duration::from_millis(20));
    let mut last_stats = tokio::time::Instant::now();
    loop {
        loop {
            let msg = match dec.next_message() {
                Ok(Some(m)) => m,
                Ok(None) => break,
                Err(e @ ControlError::FrameTooLarge { .. }) => return Err(e.into()),
                Err(e) => {
                    write_control(wr, &error(ErrorCode::InvalidMessage, e.to_string())).await?;
                    continue;
                }
            };
            let t1 = shared.clock.now_ns();
            hot.last_activity_ns.store(t1, Ordering::Release);
            match msg {
                Control::ClockPing(p) => {
                    let pong = ClockPong {
                        id: p.id,
                        t0_ns: p.t0_ns,
                        t1_ns: t1,
                        t2_ns: shared.clock.now_ns(),
                    };
                    write_control(wr, &Control::ClockPong(pong)).await?;
                }
                Control::Config(c) => shared.servo(ServoMsg::Core(SessionEvent::Config(c))),
                Control::EmergencyStop(e) => {
                    tracing::warn!(engage = e.engage, "emergency stop from the workstation");
                    shared.servo(ServoMsg::Core(SessionEvent::EmergencyStop(e.engage)));
                }
                Control::Bye(b) => return Ok(format!("bye from client: {}", b.reason)),
                other => {
                    let msg = format!("{} is not expected during a session", name(&other));
                    write_control(wr, &error(ErrorCode::UnexpectedMessage, msg)).await?;
                }
            }
        }
        tokio::select! {
            n = rd.read(&mut buf) => {
                let n = n?;
                if n == 0 {
                    return Ok("control channel closed by the client".into());
                }
                dec.push(&buf[..n]);
            }
            _ = check.tick() => {
                let idle = shared.clock.now_ns().saturating_sub(hot.last_activity_ns.load(Ordering::Acquire));
                if idle > u64::try_from(shared.net.idle_timeout.as_nanos()).unwrap_or(u64::MAX) {
                    let reason = format!("idle timeout: nothing from the workstation for {} ms", idle / 1_000_000);
                    let bye = Control::Bye(protocol::control::Bye { reason: reason.clone() });
                    let _ = tokio::time::timeout(Duration::from_millis(200), write_control(wr, &bye)).await;
                    return Ok(reason);
                }
                if last_stats.elapsed() >= shared.net.stats_interval {
                    last_stats = tokio::time::Instant::now();
                    write_control(wr, &Control::Stats(shared.stats(Some(hot)))).await?;
                }
            }
        }
    }
}

fn name(msg: &Control) -> &'static str {
    match msg {
        Control::Hello(_) => "Hello",
        Control::Welcome(_) => "Welcome",
        Control::ClockPing(_) => "ClockPing",
        Control::ClockPong(_) => "ClockPong",
        Control::Config(_) => "Config",
        Control::Stats(_) => "Stats",
        Control::EmergencyStop(_) => "EmergencyStop",
        Control::Bye(_) => "Bye",
        Control::Error(_) => "Error",
    }
}
