//! Transports: what both share (one session at a time, the control conversation, hot-path
//! acceptance) and the two wire bindings, [`udp`] and [`quic`].
//!
//! A session: the client sends `Hello` on the control channel; if its TLS client certificate
//! is not one of the [`AuthorizedClients`](crate::tls::AuthorizedClients) the server answers
//! `Error { Unauthenticated }` and closes; if no other session is active it answers `Welcome` (fresh random session id and key) and tells the servo thread
//! ([`ServoMsg::Start`]); otherwise it answers `Error { Busy }` and closes. During the session
//! it answers `ClockPing`s, forwards `Config` and `EmergencyStop` to the servo thread, sends
//! `Stats` every `stats_interval`, and ends the session on `Bye`, on a closed control channel,
//! or when nothing authentic arrived for `idle_timeout` (the workstation vanished). Ending
//! sends [`ServoMsg::End`] (output falls to zero) and frees the slot for the next client.
//! Hot-path packets pass [`protocol::Inbound`] (MAC on UDP, session, replay window, ranges);
//! only accepted `ForceCommand`s reach the servo (not one that arrived after a newer one),
//! rejects are counted by reason. On UDP the servo thread reads and checks the socket itself
//! ([`crate::servo::hot_socket`]); on QUIC [`Shared::accept_hot`] does, on quinn's side.

pub mod quic;
pub mod session;
pub mod udp;

pub use session::{HotKind, read_control, serve_control, write_control};

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use hdrhistogram::Histogram;
use protocol::control::Stats;
use protocol::{Body, Inbound, SessionKey};

use crate::clock::MonoClock;
use crate::device::DeviceInfo;
use crate::servo::driver::{ServoLink, ServoMsg};
use crate::servo::hot_socket::command_to_apply;
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

pub use haptics_client::framing::TransportError;

/// One session's hot-path state, shared by the control task and the packet receiver (QUIC;
/// on UDP the servo thread keeps the inbound state and only `last_activity_ns` of control
/// messages is used here).
#[derive(Debug)]
pub struct HotState {
    /// The session id.
    pub session: u32,
    inbound: Mutex<Inbound>,
    packets_in: AtomicU64,
    last_activity_ns: AtomicU64,
    ended: AtomicBool,
    /// Cursor → force round trips of applied commands, ns (see `Stats::force_rtt_ns`).
    force_rtt: Mutex<Histogram<u64>>,
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
    /// The client certificates that may open a session.
    pub authorized: crate::tls::AuthorizedClients,
    /// Clients refused because they presented no authorized certificate.
    pub refused_unauthenticated: AtomicU64,
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
        authorized: crate::tls::AuthorizedClients,
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
            authorized,
            refused_unauthenticated: AtomicU64::new(0),
        }
    }

    /// Hand `msg` to the servo thread. The ring is drained every tick, so when a burst (say,
    /// of `Config`s) has filled it, wait for room instead of dropping the message: an
    /// emergency stop or an `End` must not be lost. Gives up after 1 s (no servo thread).
    fn servo(&self, mut msg: ServoMsg) {
        let give_up = std::time::Instant::now() + Duration::from_secs(1);
        loop {
            let Ok(mut link) = self.link.lock() else {
                return;
            };
            match link.events.push(msg) {
                Ok(()) => return,
                Err(rtrb::PushError::Full(m)) => msg = m,
            }
            drop(link);
            if std::time::Instant::now() >= give_up {
                tracing::error!("servo event ring full for 1 s; event dropped");
                return;
            }
            std::thread::sleep(Duration::from_micros(200));
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
        let (result, newest) = match hot.inbound.lock() {
            Ok(mut inbound) => (inbound.accept(datagram), inbound.newest_sequence()),
            Err(_) => return false,
        };
        match result {
            Ok(packet) => {
                hot.packets_in.fetch_add(1, Ordering::Relaxed);
                hot.last_activity_ns.store(now, Ordering::Release);
                let Some((cmd, rtt)) = command_to_apply(&packet, newest, now) else {
                    // Superseded commands count as accepted, cursor samples do not.
                    return matches!(packet.body, Body::Force(_));
                };
                if let Some(rtt) = rtt
                    && let Ok(mut h) = hot.force_rtt.lock()
                {
                    h.saturating_record(rtt);
                }
                if let Ok(mut link) = self.link.lock() {
                    // Drained every tick; full only if the servo thread is stuck.
                    let _ = link.commands.push((cmd, packet.sequence, now));
                }
                true
            }
            Err(e) => {
                tracing::debug!("hot-path packet rejected: {e}");
                false
            }
        }
    }

    /// `Stats` of `hot` (or the last session's, when `None`). On UDP the servo thread checks
    /// the hot path itself and its telemetry carries the counts; on QUIC they are `hot`'s.
    pub fn stats(&self, hot: Option<&HotState>) -> Stats {
        let Some(hot) = hot else {
            return self.last_stats.lock().map(|s| *s).unwrap_or_default();
        };
        let servo = self.servo_stats();
        let (packets_in, rejected, force_sequence, force_rtt_ns) =
            if servo.hot.session == Some(hot.session) {
                let h = &servo.hot;
                (h.packets_in, h.rejected, h.force_sequence, h.force_rtt_ns)
            } else {
                let (rejected, force_sequence) = match hot.inbound.lock() {
                    Ok(i) => (*i.rejects(), i.sequence_stats()),
                    Err(_) => Default::default(),
                };
                let rtt = hot
                    .force_rtt
                    .lock()
                    .map(|h| crate::telemetry::percentiles(&h))
                    .unwrap_or_default();
                (
                    hot.packets_in.load(Ordering::Relaxed),
                    rejected,
                    force_sequence,
                    rtt,
                )
            };
        let stats = Stats {
            uptime_ns: servo.uptime_ns,
            ticks: servo.ticks,
            overruns: servo.overruns,
            period_ns: servo.period_ns,
            tick_cost_ns: servo.tick_cost_ns,
            packets_in,
            packets_out: servo.packets_out,
            rejected,
            force_sequence,
            clamped_ticks: servo.clamped_ticks,
            watchdog_fades: servo.watchdog_fades,
            engaged: servo.engaged,
            force_rtt_ns,
        };
        if let Ok(mut last) = self.last_stats.lock() {
            *last = stats;
        }
        stats
    }

    /// When the workstation was last heard from in session `hot`: a control message, or an
    /// authentic hot-path packet (UDP: as the servo thread's telemetry last reported it).
    pub fn last_activity_ns(&self, hot: &HotState) -> u64 {
        let control = hot.last_activity_ns.load(Ordering::Acquire);
        let servo = self.servo_stats().hot;
        if servo.session == Some(hot.session) {
            control.max(servo.last_activity_ns)
        } else {
            control
        }
    }

    /// Start a new telemetry mark window (see `ServoStats::lateness_since_mark_ns`).
    pub fn mark_telemetry(&self) {
        if let Ok(l) = self.link.lock() {
            l.mark.store(true, Ordering::Release);
        }
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
            force_rtt: Mutex::new(rtt_histogram()),
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

/// 1 µs to 10 s at 3 significant digits; allocated once per session.
fn rtt_histogram() -> Histogram<u64> {
    Histogram::new_with_bounds(1_000, 10_000_000_000, 3).expect("static histogram bounds")
}

impl HotState {
    /// The session has ended.
    pub fn ended(&self) -> bool {
        self.ended.load(Ordering::Acquire)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use protocol::packet::MAX_PACKET_BYTES;
    use protocol::{ForceCommand, Outbound};

    #[test]
    fn a_reordered_older_command_does_not_replace_the_newer_one() {
        let (commands, mut command_rx) = rtrb::RingBuffer::new(8);
        let (events, _event_rx) = rtrb::RingBuffer::new(8);
        let link = ServoLink {
            commands,
            events,
            stats: Arc::default(),
            mark: Arc::default(),
        };
        let shared = Shared::new(
            MonoClock::new(),
            link,
            crate::device::DeviceInfo::phantom_class("test"),
            1000,
            3.3,
            NetSettings::default(),
            crate::tls::AuthorizedClients::default(),
        );
        let key = SessionKey::from_bytes([7; 32]);
        let hot = shared.claim(Some(key.clone())).unwrap();
        let mut out = Outbound::new(hot.session, Some(key));
        let command = |x: f32| ForceCommand {
            force: Vec3::new(x, 0.0, 0.0),
            torque: None,
            answers_sequence: 0,
            answers_timestamp_ns: 0,
            model: Default::default(),
        };
        let (mut older, mut newer) = ([0u8; MAX_PACKET_BYTES], [0u8; MAX_PACKET_BYTES]);
        let n_older = out.encode(1, Body::Force(command(0.1)), &mut older);
        let n_newer = out.encode(2, Body::Force(command(0.2)), &mut newer);
        // The newer packet overtakes the older one on the network.
        assert!(shared.accept_hot(&hot, &newer[..n_newer]));
        shared.accept_hot(&hot, &older[..n_older]);
        let mut last = None;
        while let Ok((cmd, ..)) = command_rx.pop() {
            last = Some(cmd.force.x);
        }
        assert_eq!(last, Some(0.2), "the servo must keep the newest command");
        let stats = shared.stats(Some(&hot));
        assert_eq!(stats.force_sequence.reordered, 1);
    }
}
