//! The bare-socket peer every latency figure is a ratio against: a UDP ping-pong of the same
//! size and rate, measured in the same run, plus the reflector that answers it (a thread here,
//! or `workstation udp-echo` on the server's machine for two hosts).
//!
//! The pinger sends one datagram every `1/rate` s carrying its sequence number and send time,
//! and waits for the echo until the next send is due; a late or missing echo is lost. The
//! reflector sends every datagram straight back. Both use blocking std sockets, the fastest
//! path a user could write.

use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Largest datagram the baseline sends (an Ethernet MTU's UDP payload).
pub const MAX_PAYLOAD_BYTES: usize = 1472;
/// Smallest: sequence (8 bytes) and send time (8 bytes).
pub const MIN_PAYLOAD_BYTES: usize = 16;

/// A reflector thread on an ephemeral port of `bind`'s address; stops when dropped.
#[derive(Debug)]
pub struct Reflector {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Reflector {
    /// Start reflecting on `bind` (port 0 picks one).
    pub fn start(bind: SocketAddr) -> std::io::Result<Self> {
        let socket = UdpSocket::bind(bind)?;
        socket.set_read_timeout(Some(Duration::from_millis(50)))?;
        let addr = socket.local_addr()?;
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let stop = Arc::clone(&stop);
            std::thread::Builder::new()
                .name("udp-echo".into())
                .spawn(move || reflect(&socket, &stop))?
        };
        Ok(Self {
            addr,
            stop,
            thread: Some(thread),
        })
    }

    /// Where it listens.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }
}

impl Drop for Reflector {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Echo every datagram on `socket` to its sender until `stop` (checked at least every read
/// timeout).
pub fn reflect(socket: &UdpSocket, stop: &AtomicBool) {
    let mut buf = [0u8; MAX_PAYLOAD_BYTES + 1];
    while !stop.load(Ordering::Acquire) {
        if let Ok((n, from)) = socket.recv_from(&mut buf) {
            let _ = socket.send_to(&buf[..n], from);
        }
    }
}

/// What the ping-pong measured.
#[derive(Debug, Clone, Default)]
pub struct PingPong {
    /// Round trips of answered pings, ns, in send order.
    pub rtt_ns: Vec<u64>,
    /// Pings sent.
    pub sent: u64,
    /// Pings whose echo did not come back before the next send.
    pub lost: u64,
}

/// Ping `peer` with `payload`-byte datagrams at `rate_hz` for `duration`; `tick` is called
/// about every 100 ms with the fraction done (progress bars).
pub fn ping_pong(
    peer: SocketAddr,
    payload: usize,
    rate_hz: u32,
    duration: Duration,
    mut tick: impl FnMut(f64),
) -> std::io::Result<PingPong> {
    let bind: SocketAddr = if peer.is_ipv4() {
        ([0, 0, 0, 0], 0).into()
    } else {
        (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
    };
    let socket = UdpSocket::bind(bind)?;
    socket.connect(peer)?;
    let period = Duration::from_secs_f64(1.0 / f64::from(rate_hz.max(1)));
    let mut out = PingPong {
        rtt_ns: Vec::with_capacity((duration.as_secs_f64() * f64::from(rate_hz)) as usize + 1),
        ..PingPong::default()
    };
    let mut buf = vec![0u8; payload.clamp(MIN_PAYLOAD_BYTES, MAX_PAYLOAD_BYTES)];
    let mut echo = vec![0u8; MAX_PAYLOAD_BYTES + 1];
    let start = Instant::now();
    let mut next = start;
    let mut last_tick = start;
    while start.elapsed() < duration {
        let seq = out.sent;
        let sent_at = start.elapsed().as_nanos() as u64;
        buf[..8].copy_from_slice(&seq.to_le_bytes());
        buf[8..16].copy_from_slice(&sent_at.to_le_bytes());
        socket.send(&buf)?;
        out.sent += 1;
        next += period;
        let mut answered = false;
        // Wait for this ping's echo until the next one is due (late echoes of earlier pings
        // are skipped).
        loop {
            let left = next.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            socket.set_read_timeout(Some(left))?;
            match socket.recv(&mut echo) {
                Ok(n) if n >= 16 && echo[..8] == seq.to_le_bytes() => {
                    let now = start.elapsed().as_nanos() as u64;
                    out.rtt_ns.push(now.saturating_sub(sent_at));
                    answered = true;
                    break;
                }
                Ok(_) => {}
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    break;
                }
                Err(e) => return Err(e),
            }
        }
        out.lost += u64::from(!answered);
        let now = Instant::now();
        if now < next {
            std::thread::sleep(next - now);
        }
        if last_tick.elapsed() >= Duration::from_millis(100) {
            last_tick = Instant::now();
            tick(start.elapsed().as_secs_f64() / duration.as_secs_f64());
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ping_pong_against_the_reflector_answers_every_ping() {
        let r = Reflector::start(([127, 0, 0, 1], 0).into()).unwrap();
        // An echo later than the next send counts as lost, so on a loaded machine (the test
        // suite runs beside this) a fast rate would count scheduling stalls as loss: at 50 Hz
        // each echo has 20 ms, and only a datagram really lost on loopback counts.
        let p = ping_pong(r.addr(), 118, 50, Duration::from_secs(2), |_| {}).unwrap();
        assert!(p.sent >= 50, "{p:?}");
        assert!(p.lost <= 2, "loopback loses nothing: {p:?}");
        assert_eq!(p.rtt_ns.len() as u64, p.sent - p.lost);
        assert!(p.rtt_ns.iter().all(|&r| r > 0 && r < 1_000_000_000));
    }

    #[test]
    fn a_silent_peer_is_all_loss() {
        // A bound socket that never answers.
        let silent = UdpSocket::bind("127.0.0.1:0").unwrap();
        let p = ping_pong(
            silent.local_addr().unwrap(),
            64,
            200,
            Duration::from_millis(100),
            |_| {},
        )
        .unwrap();
        assert!(
            p.sent > 0 && p.lost == p.sent && p.rtt_ns.is_empty(),
            "{p:?}"
        );
    }
}
