//! The UDP hot path as the servo thread reads it: drained at the top of every tick, each
//! datagram stamped with the kernel's receive time.
//!
//! No thread sits between the socket and the servo. A force command waits in the socket's
//! receive queue until the next tick takes it, which is when the servo would have taken it
//! from a receiver thread's ring anyway; so the workstation's `sendto` wakes nobody on the
//! server, and one thread fewer competes for the cores. The round trip is still measured at
//! the socket, not at the drain: `SO_TIMESTAMPNS` stamps each datagram as it arrives
//! (`CLOCK_REALTIME`), converted to the server clock with an offset read at the drain.
//!
//! Per datagram: [`Inbound`] (size, magic, MAC, session, replay window), then a command that
//! arrived after a newer one is counted and not applied. The first authentic packet names the
//! client's address and cursors go there; a later one from elsewhere moves them. At most
//! [`MAX_DRAIN_PER_TICK`] datagrams are read per tick, so a flood of forged packets cannot hold
//! the servo thread; the rest wait for the next tick. No allocation, no lock.

use std::net::{SocketAddr, UdpSocket};
use std::os::fd::AsRawFd as _;

use protocol::packet::MAX_PACKET_BYTES;
use protocol::{Body, ForceCommand, Inbound, Packet, SessionKey};

use crate::clock::MonoClock;
use crate::telemetry::HotTick;

/// Datagrams read per tick at most (a forged-packet flood at 50× the command rate is 50).
pub const MAX_DRAIN_PER_TICK: usize = 64;

/// The servo thread's hot-path socket and its session's inbound state.
#[derive(Debug)]
pub struct HotSocket {
    socket: UdpSocket,
    inbound: Option<Inbound>,
    /// Where cursors go: the client's address, learned from its first authentic packet.
    pub peer: Option<SocketAddr>,
    stamps: bool,
    tick: HotTick,
    buf: [u8; MAX_PACKET_BYTES + 1],
}

impl HotSocket {
    /// Take `socket` (non-blocking) and ask the kernel to stamp arrivals; where it refuses,
    /// arrivals are stamped at the drain (a warning says so).
    pub fn new(socket: UdpSocket) -> std::io::Result<Self> {
        socket.set_nonblocking(true)?;
        let stamps = match enable_receive_stamps(&socket) {
            Ok(()) => true,
            Err(e) => {
                tracing::warn!(
                    "SO_TIMESTAMPNS refused ({e}): command arrivals are stamped when the servo \
                     reads them, up to one period late"
                );
                false
            }
        };
        Ok(Self {
            socket,
            inbound: None,
            peer: None,
            stamps,
            tick: HotTick::default(),
            buf: [0; MAX_PACKET_BYTES + 1],
        })
    }

    /// A session started: accept its packets (MAC'd with `key` when `Some`).
    pub fn start(&mut self, session: u32, key: Option<SessionKey>, now_ns: u64) {
        self.inbound = Some(Inbound::new(session, key));
        self.peer = None;
        self.tick = HotTick {
            session: Some(session),
            last_activity_ns: now_ns,
            unsolicited: self.tick.unsolicited,
            ..HotTick::default()
        };
    }

    /// The session ended: its packets are unsolicited from now on.
    pub fn end(&mut self) {
        self.inbound = None;
        self.peer = None;
        self.tick.session = None;
    }

    /// Send one cursor packet to the peer; `false` if there is none yet or the send failed.
    pub fn send(&self, packet: &[u8]) -> bool {
        self.peer
            .is_some_and(|peer| self.socket.send_to(packet, peer).is_ok())
    }

    /// Read what arrived since the last tick; each accepted command goes to `apply` with its
    /// header sequence and arrival (server clock, ns), oldest first. Returns this tick's
    /// hot-path record for telemetry.
    pub fn drain(
        &mut self,
        clock: &MonoClock,
        apply: impl FnMut(ForceCommand, u32, u64),
    ) -> HotTick {
        let offset = realtime_offset(clock);
        self.drain_with_offset(clock, offset, apply)
    }

    /// [`HotSocket::drain`] with `CLOCK_REALTIME − server clock` already read. Each arrival is
    /// bounded by a clock read taken after its own `recvmsg`, never by the drain's start: a
    /// datagram can arrive after the offset was read (the servo thread preempted in between),
    /// and the start would then stamp it before it was sent: a loaded CI run's latency test
    /// measured a one-way delay of −211 µs, against a stated bound of ±37 µs.
    fn drain_with_offset(
        &mut self,
        clock: &MonoClock,
        offset: i128,
        mut apply: impl FnMut(ForceCommand, u32, u64),
    ) -> HotTick {
        self.tick.drained = 0;
        self.tick.applied_rtt_ns = 0;
        self.tick.peer_changed = false;
        self.tick.capped = true;
        for _ in 0..MAX_DRAIN_PER_TICK {
            let (n, from, stamp) = match recv_stamped(&self.socket, &mut self.buf) {
                Ok(Some(r)) => r,
                Ok(None) => {
                    self.tick.capped = false;
                    break;
                }
                // ICMP port unreachable from a vanished client surfaces here on Linux.
                Err(_) => continue,
            };
            self.tick.drained += 1;
            let read_ns = clock.now_ns();
            let arrived = match stamp {
                Some(rt) if self.stamps => {
                    u64::try_from((rt - offset).clamp(0, i128::from(read_ns))).unwrap_or(read_ns)
                }
                _ => read_ns,
            };
            let Some(inbound) = &mut self.inbound else {
                self.tick.unsolicited += 1;
                continue;
            };
            let Ok(packet) = inbound.accept(&self.buf[..n]) else {
                continue;
            };
            let newest = inbound.newest_sequence();
            self.tick.packets_in += 1;
            self.tick.last_activity_ns = self.tick.last_activity_ns.max(arrived);
            if self.peer != Some(from) {
                self.peer = Some(from);
                self.tick.peer = Some(from);
                self.tick.peer_changed = true;
            }
            if let Some((cmd, rtt)) = command_to_apply(&packet, newest, arrived) {
                if let Some(rtt) = rtt {
                    self.tick.applied_rtt_ns = rtt;
                }
                apply(cmd, packet.sequence, arrived);
            }
        }
        if let Some(inbound) = &self.inbound {
            self.tick.rejected = *inbound.rejects();
            self.tick.force_sequence = inbound.sequence_stats();
        }
        self.tick
    }
}

/// What an accepted hot-path packet asks of the servo, the same on both transports: its force
/// command, unless a newer one was accepted before it (`newest`: superseded, counted, not
/// applied), with the cursor → arrival round trip when it echoes one of our cursor stamps
/// (those are from our clock; 0 answers nothing). A cursor sample sent to the server is
/// authentic but meaningless: `None`.
pub fn command_to_apply(
    packet: &Packet,
    newest: Option<u32>,
    arrived_ns: u64,
) -> Option<(ForceCommand, Option<u64>)> {
    match packet.body {
        Body::Force(cmd) if newest == Some(packet.sequence) => {
            let echoed = cmd.answers_timestamp_ns;
            let rtt = (echoed != 0 && echoed <= arrived_ns).then(|| arrived_ns - echoed);
            Some((cmd, rtt))
        }
        Body::Force(_) | Body::Cursor(_) => None,
    }
}

/// `CLOCK_REALTIME − server clock` (ns), which converts the kernel's stamps. The realtime
/// read is bracketed by two server-clock reads and taken from the narrowest of a few tries: a
/// thread preempted between the reads would otherwise shift every stamp of the tick by the
/// preemption (seen: 60 µs under load, a command "arriving" before it was sent).
fn realtime_offset(clock: &MonoClock) -> i128 {
    let mut best: Option<(u64, i128)> = None;
    for _ in 0..4 {
        let before = clock.now_ns();
        let realtime = realtime_ns();
        let after = clock.now_ns();
        let width = after.saturating_sub(before);
        let mid = before + width / 2;
        if best.is_none_or(|(w, _)| width < w) {
            best = Some((width, realtime - i128::from(mid)));
        }
        if width < 1_000 {
            break;
        }
    }
    best.map_or(0, |(_, offset)| offset)
}

/// Nanoseconds of `CLOCK_REALTIME` (the clock of `SO_TIMESTAMPNS`).
fn realtime_ns() -> i128 {
    match std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH) {
        Ok(d) => i128::try_from(d.as_nanos()).unwrap_or(i128::MAX),
        Err(e) => -i128::try_from(e.duration().as_nanos()).unwrap_or(i128::MAX),
    }
}

#[cfg(target_os = "linux")]
fn enable_receive_stamps(socket: &UdpSocket) -> std::io::Result<()> {
    let on: libc::c_int = 1;
    // SAFETY: a valid socket descriptor and a c_int option value of the stated size.
    let rc = unsafe {
        libc::setsockopt(
            socket.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_TIMESTAMPNS,
            (&raw const on).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        )
    };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

#[cfg(not(target_os = "linux"))]
fn enable_receive_stamps(_: &UdpSocket) -> std::io::Result<()> {
    Err(std::io::Error::other(
        "receive timestamps are implemented for Linux only",
    ))
}

/// One non-blocking `recvmsg`: length, sender and kernel arrival stamp (realtime ns), or
/// `None` when the queue is empty. A datagram longer than `buf` reports `buf.len()` bytes (the
/// buffer is one byte longer than any valid packet, so [`Inbound`] names it oversized).
fn recv_stamped(
    socket: &UdpSocket,
    buf: &mut [u8],
) -> std::io::Result<Option<(usize, SocketAddr, Option<i128>)>> {
    // SAFETY: all-zero is a valid sockaddr_storage / msghdr.
    let mut addr: libc::sockaddr_storage = unsafe { std::mem::zeroed() };
    let mut iov = libc::iovec {
        iov_base: buf.as_mut_ptr().cast(),
        iov_len: buf.len(),
    };
    // Room for one timespec control message, aligned for cmsghdr.
    let mut control = [0u64; 8];
    // SAFETY: as above.
    let mut msg: libc::msghdr = unsafe { std::mem::zeroed() };
    msg.msg_name = (&raw mut addr).cast();
    msg.msg_namelen = std::mem::size_of::<libc::sockaddr_storage>() as libc::socklen_t;
    msg.msg_iov = &raw mut iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control.as_mut_ptr().cast();
    msg.msg_controllen = std::mem::size_of_val(&control) as _;
    // SAFETY: `msg` points at live buffers of the lengths it states for the whole call.
    let n = unsafe { libc::recvmsg(socket.as_raw_fd(), &raw mut msg, libc::MSG_DONTWAIT) };
    if n < 0 {
        let e = std::io::Error::last_os_error();
        return match e.kind() {
            std::io::ErrorKind::WouldBlock => Ok(None),
            _ => Err(e),
        };
    }
    let Some(from) = socket_addr(&addr) else {
        return Err(std::io::Error::other("datagram from a non-IP address"));
    };
    let len = usize::try_from(n).unwrap_or(0).min(buf.len());
    Ok(Some((len, from, kernel_stamp(&msg))))
}

#[cfg(target_os = "linux")]
fn kernel_stamp(msg: &libc::msghdr) -> Option<i128> {
    // SAFETY: `msg` was filled by recvmsg; the CMSG_* walk stays inside msg_controllen.
    unsafe {
        let mut c = libc::CMSG_FIRSTHDR(msg);
        while !c.is_null() {
            if (*c).cmsg_level == libc::SOL_SOCKET && (*c).cmsg_type == libc::SCM_TIMESTAMPNS {
                let ts: libc::timespec = std::ptr::read_unaligned(libc::CMSG_DATA(c).cast());
                return Some(i128::from(ts.tv_sec) * 1_000_000_000 + i128::from(ts.tv_nsec));
            }
            c = libc::CMSG_NXTHDR(msg, c);
        }
    }
    None
}

#[cfg(not(target_os = "linux"))]
fn kernel_stamp(_: &libc::msghdr) -> Option<i128> {
    None
}

fn socket_addr(addr: &libc::sockaddr_storage) -> Option<SocketAddr> {
    match libc::c_int::from(addr.ss_family) {
        libc::AF_INET => {
            // SAFETY: the family says the storage holds a sockaddr_in.
            let a: &libc::sockaddr_in = unsafe { &*(&raw const *addr).cast() };
            let ip = std::net::Ipv4Addr::from(u32::from_be(a.sin_addr.s_addr));
            Some(SocketAddr::from((ip, u16::from_be(a.sin_port))))
        }
        libc::AF_INET6 => {
            // SAFETY: the family says the storage holds a sockaddr_in6.
            let a: &libc::sockaddr_in6 = unsafe { &*(&raw const *addr).cast() };
            let ip = std::net::Ipv6Addr::from(a.sin6_addr.s6_addr);
            Some(SocketAddr::V6(std::net::SocketAddrV6::new(
                ip,
                u16::from_be(a.sin6_port),
                a.sin6_flowinfo,
                a.sin6_scope_id,
            )))
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use std::time::Duration;

    fn command(x: f32, answers_timestamp_ns: u64) -> Body {
        Body::Force(ForceCommand {
            force: Vec3::new(x, 0.0, 0.0),
            torque: None,
            answers_sequence: 0,
            answers_timestamp_ns,
            model: Default::default(),
        })
    }

    /// A server socket and a client socket connected to it on loopback.
    fn pair() -> (HotSocket, UdpSocket) {
        let server = UdpSocket::bind("127.0.0.1:0").unwrap();
        let client = UdpSocket::bind("127.0.0.1:0").unwrap();
        client.connect(server.local_addr().unwrap()).unwrap();
        (HotSocket::new(server).unwrap(), client)
    }

    fn drain_all(hot: &mut HotSocket, clock: &MonoClock) -> (Vec<(f32, u64)>, HotTick) {
        let mut applied = Vec::new();
        let tick = hot.drain(clock, |cmd, _, arrived| {
            applied.push((cmd.force.x, arrived))
        });
        (applied, tick)
    }

    #[test]
    fn a_command_is_stamped_when_it_arrived_not_when_the_servo_read_it() {
        let clock = MonoClock::new();
        let (mut hot, client) = pair();
        let key = SessionKey::from_bytes([3; 32]);
        hot.start(9, Some(key.clone()), clock.now_ns());
        let mut out = protocol::Outbound::new(9, Some(key));
        let mut buf = [0u8; MAX_PACKET_BYTES];
        // The kernel turns receive stamping on for the whole host a moment after the first
        // socket asks (a deferred static key); until then it stamps at the read. So a few
        // tries: one must show the arrival, or stamping does not work.
        let mut seen = Vec::new();
        for _ in 0..20 {
            let cursor_ns = clock.now_ns();
            let n = out.encode(1, command(0.5, cursor_ns), &mut buf);
            client.send(&buf[..n]).unwrap();
            let sent_ns = clock.now_ns();
            // The servo reads it 30 ms later; the stamp must still say when it came in.
            std::thread::sleep(Duration::from_millis(30));
            let (applied, tick) = drain_all(&mut hot, &clock);
            let read_ns = clock.now_ns();
            assert_eq!(applied.len(), 1);
            let arrived = applied[0].1;
            assert!(arrived >= cursor_ns && arrived <= read_ns);
            assert_eq!(tick.applied_rtt_ns, arrived - cursor_ns);
            if arrived <= sent_ns && read_ns - arrived >= 30_000_000 {
                assert_eq!(hot.peer, Some(client.local_addr().unwrap()));
                return;
            }
            seen.push((read_ns - arrived) / 1_000);
        }
        panic!(
            "every command was stamped at the read, not on arrival (µs before the read: {seen:?})"
        );
    }

    #[test]
    fn a_command_arriving_after_the_drain_began_is_not_stamped_before_it_was_sent() {
        let clock = MonoClock::new();
        let (mut hot, client) = pair();
        let key = SessionKey::from_bytes([5; 32]);
        hot.start(7, Some(key.clone()), clock.now_ns());
        let mut out = protocol::Outbound::new(7, Some(key));
        let mut buf = [0u8; MAX_PACKET_BYTES];
        // The drain reads the clocks' offset, then its thread is held up (preempted) while the
        // command arrives. Stamped with the drain's start, it "arrived" 20 ms before it was
        // sent: the latency run saw a one-way delay of -211 µs that way.
        let offset = realtime_offset(&clock);
        std::thread::sleep(Duration::from_millis(20));
        let sent_ns = clock.now_ns();
        let n = out.encode(1, command(0.5, 0), &mut buf);
        client.send(&buf[..n]).unwrap();
        let mut arrivals = Vec::new();
        hot.drain_with_offset(&clock, offset, |_, _, arrived| arrivals.push(arrived));
        let read_ns = clock.now_ns();
        assert_eq!(arrivals.len(), 1);
        // 1 ms of slack for the offset's own error on a loaded machine (it is read in under 1 µs
        // when the thread is not preempted), a twentieth of what the defect shifted.
        let arrived = arrivals[0];
        assert!(
            arrived + 1_000_000 >= sent_ns && arrived <= read_ns,
            "sent {sent_ns}, arrived {arrived}, read by {read_ns} ns"
        );
    }

    #[test]
    fn forged_late_and_unsolicited_packets_never_reach_the_servo() {
        let clock = MonoClock::new();
        let (mut hot, client) = pair();
        let mut buf = [0u8; MAX_PACKET_BYTES];
        // Before any session: counted as unsolicited, dropped.
        let mut early = protocol::Outbound::new(4, None);
        let n = early.encode(1, command(1.0, 0), &mut buf);
        client.send(&buf[..n]).unwrap();
        let (applied, tick) = drain_all(&mut hot, &clock);
        assert!(applied.is_empty());
        assert_eq!(tick.unsolicited, 1);

        let key = SessionKey::from_bytes([5; 32]);
        hot.start(4, Some(key.clone()), clock.now_ns());
        let mut out = protocol::Outbound::new(4, Some(key));
        let (mut older, mut newer) = ([0u8; MAX_PACKET_BYTES], [0u8; MAX_PACKET_BYTES]);
        let n_older = out.encode(1, command(0.1, 0), &mut older);
        let n_newer = out.encode(2, command(0.2, 0), &mut newer);
        // The newer overtakes the older; a forged copy (wrong key) and an oversized datagram.
        client.send(&newer[..n_newer]).unwrap();
        client.send(&older[..n_older]).unwrap();
        let mut forged = protocol::Outbound::new(4, Some(SessionKey::from_bytes([6; 32])));
        let n = forged.encode(3, command(3.0, 0), &mut buf);
        client.send(&buf[..n]).unwrap();
        client.send(&[0x48; MAX_PACKET_BYTES + 40]).unwrap();
        let (applied, tick) = drain_all(&mut hot, &clock);
        let forces: Vec<f32> = applied.iter().map(|a| a.0).collect();
        assert_eq!(forces, [0.2], "only the newest authentic command");
        assert_eq!(tick.drained, 4);
        assert_eq!(tick.packets_in, 2);
        assert_eq!(tick.force_sequence.reordered, 1);
        assert_eq!(tick.rejected.get(protocol::Reject::BadMac), 1);
        assert_eq!(tick.rejected.get(protocol::Reject::TrailingBytes), 1);
        assert_eq!(tick.unsolicited, 1, "kept across the session start");

        // After the session: unsolicited again.
        hot.end();
        let n = out.encode(4, command(0.3, 0), &mut buf);
        client.send(&buf[..n]).unwrap();
        let (applied, tick) = drain_all(&mut hot, &clock);
        assert!(applied.is_empty());
        assert_eq!(tick.unsolicited, 2);
    }

    #[test]
    fn a_flood_is_read_at_most_a_cap_per_tick_and_the_rest_next_tick() {
        let clock = MonoClock::new();
        let (mut hot, client) = pair();
        hot.start(1, None, clock.now_ns());
        let total = MAX_DRAIN_PER_TICK + 10;
        for _ in 0..total {
            client.send(b"not a packet").unwrap();
        }
        let (_, first) = drain_all(&mut hot, &clock);
        assert_eq!(first.drained as usize, MAX_DRAIN_PER_TICK);
        assert!(first.capped);
        let (_, second) = drain_all(&mut hot, &clock);
        assert_eq!(second.drained, 10);
        assert!(!second.capped);
        assert_eq!(second.rejected.total() as usize, total);
    }
}
