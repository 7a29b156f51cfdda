//! `workstation relay`: a user-space link emulator between a workstation and a haptics server,
//! for machines whose kernel has no `sch_netem` (and for anyone who wants a delayed link
//! without root).
//!
//! It listens on `--listen` for both the UDP hot path (and QUIC, which is UDP too) and the TCP
//! control connection, and forwards them to `--to`, so the two ends talk through it without
//! knowing it:
//! - **UDP**, datagram by datagram, through one [`SimLink`] per direction (the same seeded core
//!   the delay study uses): fixed delay, plus jitter drawn uniformly from `[0, jitter]`, loss,
//!   deliberate reordering (a packet held back 2 ms + the jitter so later ones overtake it) and
//!   duplication. Each client address gets its own upstream socket, so several workstations
//!   can share one relay.
//! - **TCP** (the UDP transport's TLS control channel) with the same fixed delay per direction,
//!   never lost, reordered or jittered: TCP would recover those itself, and the bytes must stay
//!   in order.
//!
//! Every impairment takes one value for both directions or `UP/DOWN`: `--delay 5/20` delays the
//! workstation → server direction ("up") 5 ms and server → workstation ("down") 20 ms.
//!
//! Threads: a reader per socket hands each datagram with its arrival time to its direction's
//! scheduler thread, which owns that direction's [`SimLink`] and sends each copy when it is due
//! (it sleeps on its channel until then). Not a real-time path: a datagram costs one heap
//! buffer, fine for a test link at the servo's 1 kHz.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use protocol::{LinkCounters, LinkParams, SimLink};
use serde::Serialize;

/// Largest datagram forwarded (UDP's payload limit).
const MAX_DATAGRAM: usize = 65_535;
/// Longest one-way delay or jitter a user may set: an emulated link of more than 10 s is a typo.
pub const MAX_DELAY_MS: f64 = 10_000.0;

/// Arguments of `workstation relay`.
#[derive(Debug, Clone, clap::Args)]
pub struct RelayArgs {
    /// Where the workstation connects (UDP and TCP), e.g. 127.0.0.1:7800.
    #[arg(long, value_name = "ADDR")]
    pub listen: SocketAddr,
    /// The haptics server (UDP and TCP), e.g. 127.0.0.1:7700.
    #[arg(long, value_name = "ADDR")]
    pub to: SocketAddr,
    /// One-way delay in ms, both directions or UP/DOWN (up: workstation → server).
    #[arg(long, default_value = "0", value_name = "MS[/MS]")]
    pub delay: String,
    /// Extra delay drawn uniformly from [0, MS] per datagram (UDP only), or UP/DOWN.
    #[arg(long, default_value = "0", value_name = "MS[/MS]")]
    pub jitter: String,
    /// Probability a datagram is lost, 0..1 (UDP only), or UP/DOWN.
    #[arg(long, default_value = "0", value_name = "P[/P]")]
    pub loss: String,
    /// Probability a datagram is held back so later ones overtake it (UDP only), or UP/DOWN.
    #[arg(long, default_value = "0", value_name = "P[/P]")]
    pub reorder: String,
    /// Probability a datagram arrives twice (UDP only), or UP/DOWN.
    #[arg(long, default_value = "0", value_name = "P[/P]")]
    pub duplicate: String,
    /// Seed of the impairments' random streams (the same seed, the same decisions).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Stop after this many seconds and print the counters as JSON (default: run until killed,
    /// logging the counters every 10 s).
    #[arg(long, value_name = "S")]
    pub seconds: Option<f64>,
}

/// The two directions' link parameters, parsed from the flags.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Impairments {
    /// Workstation → server.
    pub up: LinkParams,
    /// Server → workstation.
    pub down: LinkParams,
}

impl RelayArgs {
    /// Parse and check every impairment flag; errors name the flag and the reason.
    pub fn impairments(&self) -> anyhow::Result<Impairments> {
        let ms = |flag: &str, v: &str| -> anyhow::Result<(u64, u64)> {
            let (a, b) = split_pair(flag, v, 0.0..=MAX_DELAY_MS, "milliseconds")?;
            Ok(((a * 1e6).round() as u64, (b * 1e6).round() as u64))
        };
        let p = |flag: &str, v: &str| split_pair(flag, v, 0.0..=1.0, "a probability");
        let (delay, jitter) = (ms("--delay", &self.delay)?, ms("--jitter", &self.jitter)?);
        let (loss, reorder) = (p("--loss", &self.loss)?, p("--reorder", &self.reorder)?);
        let duplicate = p("--duplicate", &self.duplicate)?;
        let link = |pick: fn((u64, u64)) -> u64, pickf: fn((f64, f64)) -> f64, seed| LinkParams {
            delay_ns: pick(delay),
            jitter_ns: pick(jitter),
            loss: pickf(loss),
            reorder: pickf(reorder),
            reorder_hold_ns: 2_000_000 + pick(jitter),
            duplicate: pickf(duplicate),
            seed,
        };
        Ok(Impairments {
            up: link(|p| p.0, |p| p.0, self.seed),
            down: link(|p| p.1, |p| p.1, self.seed ^ 0x5EED_D0A1),
        })
    }
}

/// `"X"` → `(X, X)`, `"X/Y"` → `(X, Y)`, each finite and in `range`.
fn split_pair(
    flag: &str,
    v: &str,
    range: std::ops::RangeInclusive<f64>,
    what: &str,
) -> anyhow::Result<(f64, f64)> {
    let one = |s: &str| -> anyhow::Result<f64> {
        let x: f64 = s
            .trim()
            .parse()
            .with_context(|| format!("{flag} `{v}`: `{s}` is not a number"))?;
        anyhow::ensure!(
            x.is_finite() && range.contains(&x),
            "{flag} `{v}`: {x} is not {what} in {}..={}",
            range.start(),
            range.end()
        );
        Ok(x)
    };
    match v.split_once('/') {
        Some((a, b)) => Ok((one(a)?, one(b)?)),
        None => one(v).map(|x| (x, x)),
    }
}

/// Counters of one run, per direction (what the links did to UDP datagrams) and TCP.
#[derive(Debug, Clone, Default, Serialize)]
pub struct RelayCounters {
    /// Workstation → server datagrams.
    pub up: Counters,
    /// Server → workstation datagrams.
    pub down: Counters,
    /// TCP connections relayed.
    pub tcp_connections: u64,
}

/// [`LinkCounters`] as JSON.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Counters {
    /// Datagrams received.
    pub received: u64,
    /// Dropped by the emulated loss.
    pub lost: u64,
    /// Held back so later ones overtake them.
    pub reordered: u64,
    /// Extra copies sent.
    pub duplicated: u64,
    /// Copies sent on.
    pub forwarded: u64,
}

impl From<LinkCounters> for Counters {
    fn from(c: LinkCounters) -> Self {
        Self {
            received: c.sent,
            lost: c.lost,
            reordered: c.reordered,
            duplicated: c.duplicated,
            forwarded: c.delivered,
        }
    }
}

/// A datagram on its way: the socket to send it from and, for the way back, to whom.
#[derive(Debug, Clone)]
struct Datagram {
    socket: Arc<UdpSocket>,
    to: Option<SocketAddr>,
    bytes: Vec<u8>,
}

/// A running relay; stops (and joins nothing: its threads end with the process or at the
/// next datagram after [`Relay::stop`]) when dropped.
#[derive(Debug)]
pub struct Relay {
    /// The address it listens on (with the port the OS chose for port 0).
    pub local: SocketAddr,
    up: Arc<Mutex<LinkCounters>>,
    down: Arc<Mutex<LinkCounters>>,
    tcp: Arc<Mutex<u64>>,
    stop: Arc<AtomicBool>,
}

impl Relay {
    /// Bind `listen` (UDP and TCP on the same port) and start forwarding to `to`.
    pub fn start(listen: SocketAddr, to: SocketAddr, imp: Impairments) -> anyhow::Result<Self> {
        let udp = UdpSocket::bind(listen).with_context(|| format!("UDP {listen}"))?;
        udp.set_read_timeout(Some(Duration::from_millis(200)))?;
        let local = udp.local_addr()?;
        let udp = Arc::new(udp);
        let tcp = TcpListener::bind(local).with_context(|| format!("TCP {local}"))?;
        let stop = Arc::new(AtomicBool::new(false));
        let relay = Self {
            local,
            up: Arc::default(),
            down: Arc::default(),
            tcp: Arc::default(),
            stop: Arc::clone(&stop),
        };
        let up_tx = scheduler("relay up", imp.up, Arc::clone(&relay.up), &stop)?;
        let down_tx = scheduler("relay down", imp.down, Arc::clone(&relay.down), &stop)?;
        // Datagrams from clients: each client gets an upstream socket and a reader for the way
        // back.
        let s = Arc::clone(&stop);
        spawn("relay udp", move || {
            let mut clients: Vec<(SocketAddr, Arc<UdpSocket>)> = Vec::new();
            let mut buf = vec![0u8; MAX_DATAGRAM];
            while !s.load(Ordering::Relaxed) {
                let Ok((n, from)) = udp.recv_from(&mut buf) else {
                    continue;
                };
                let upstream = match clients.iter().find(|c| c.0 == from) {
                    Some(c) => Arc::clone(&c.1),
                    None => match upstream_socket(to, from, &udp, &down_tx, &s) {
                        Ok(u) => {
                            clients.push((from, Arc::clone(&u)));
                            u
                        }
                        Err(e) => {
                            tracing::warn!("relay: no upstream socket for {from}: {e:#}");
                            continue;
                        }
                    },
                };
                let _ = up_tx.send((
                    Instant::now(),
                    Datagram {
                        socket: upstream,
                        to: None,
                        bytes: buf[..n].to_vec(),
                    },
                ));
            }
        })?;
        let (delay_up, delay_down) = (imp.up.delay_ns, imp.down.delay_ns);
        let (s, count) = (Arc::clone(&stop), Arc::clone(&relay.tcp));
        spawn("relay tcp", move || {
            for conn in tcp.incoming() {
                if s.load(Ordering::Relaxed) {
                    return;
                }
                let Ok(client) = conn else { continue };
                match TcpStream::connect(to) {
                    Ok(server) => {
                        *count.lock().unwrap_or_else(|e| e.into_inner()) += 1;
                        let pumps = [
                            (client.try_clone(), server.try_clone(), delay_up),
                            (server.try_clone(), client.try_clone(), delay_down),
                        ];
                        for (from, into, delay_ns) in pumps {
                            if let (Ok(from), Ok(into)) = (from, into) {
                                let _ = pump(from, into, delay_ns);
                            }
                        }
                    }
                    Err(e) => tracing::warn!("relay: TCP connect to {to}: {e}"),
                }
            }
        })?;
        Ok(relay)
    }

    /// What the links have done so far.
    pub fn counters(&self) -> RelayCounters {
        let read = |c: &Mutex<LinkCounters>| *c.lock().unwrap_or_else(|e| e.into_inner());
        RelayCounters {
            up: read(&self.up).into(),
            down: read(&self.down).into(),
            tcp_connections: *self.tcp.lock().unwrap_or_else(|e| e.into_inner()),
        }
    }

    /// Stop forwarding (threads end at their next wake-up).
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.stop();
    }
}

fn spawn(name: &str, f: impl FnOnce() + Send + 'static) -> anyhow::Result<()> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn(f)
        .with_context(|| format!("starting the {name} thread"))?;
    Ok(())
}

/// A socket connected to `to` for client `from`, with a thread that sends the server's answers
/// back to `from` from the listening socket through the down link.
fn upstream_socket(
    to: SocketAddr,
    from: SocketAddr,
    listening: &Arc<UdpSocket>,
    down: &mpsc::Sender<(Instant, Datagram)>,
    stop: &Arc<AtomicBool>,
) -> anyhow::Result<Arc<UdpSocket>> {
    let bind: SocketAddr = if to.is_ipv4() {
        ([0, 0, 0, 0], 0).into()
    } else {
        (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
    };
    let socket = UdpSocket::bind(bind)?;
    socket.connect(to)?;
    socket.set_read_timeout(Some(Duration::from_millis(200)))?;
    let socket = Arc::new(socket);
    let (rx, back, down, stop) = (
        Arc::clone(&socket),
        Arc::clone(listening),
        down.clone(),
        Arc::clone(stop),
    );
    spawn("relay udp back", move || {
        let mut buf = vec![0u8; MAX_DATAGRAM];
        while !stop.load(Ordering::Relaxed) {
            if let Ok(n) = rx.recv(&mut buf) {
                let d = Datagram {
                    socket: Arc::clone(&back),
                    to: Some(from),
                    bytes: buf[..n].to_vec(),
                };
                if down.send((Instant::now(), d)).is_err() {
                    return;
                }
            }
        }
    })?;
    Ok(socket)
}

/// One direction's scheduler thread: datagrams in (with their arrival time), each copy sent
/// when its link says it is due. Empty link: it sleeps until the next datagram (at most 200 ms,
/// to notice a stop).
fn scheduler(
    name: &str,
    params: LinkParams,
    counters: Arc<Mutex<LinkCounters>>,
    stop: &Arc<AtomicBool>,
) -> anyhow::Result<mpsc::Sender<(Instant, Datagram)>> {
    let (tx, rx) = mpsc::channel::<(Instant, Datagram)>();
    let stop = Arc::clone(stop);
    spawn(name, move || {
        let epoch = Instant::now();
        let ns = |t: Instant| t.saturating_duration_since(epoch).as_nanos() as u64;
        let mut link = SimLink::with_capacity(params, 4096);
        let mut due = Vec::with_capacity(64);
        let mut waker = EarlyWake::default();
        while !stop.load(Ordering::Relaxed) {
            let next = link.next_due();
            let wait = next.map_or(Duration::from_millis(200), |due| {
                Duration::from_nanos(due.saturating_sub(ns(Instant::now()) + waker.margin_ns))
            });
            let asked = Instant::now() + wait;
            match rx.recv_timeout(wait) {
                Ok((arrived, d)) => link.send(ns(arrived), d),
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    waker.woke(Instant::now().saturating_duration_since(asked));
                    if let Some(due) = next {
                        // Woken early by the margin: yield the processor until the copy is due.
                        while ns(Instant::now()) < due {
                            std::thread::yield_now();
                        }
                    }
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => return,
            }
            due.extend(link.deliver(ns(Instant::now())));
            // Counted before sent, so whoever sees a copy arrive also sees it counted.
            *counters.lock().unwrap_or_else(|e| e.into_inner()) = link.counters();
            for d in due.drain(..) {
                let _ = match d.to {
                    Some(to) => d.socket.send_to(&d.bytes, to),
                    None => d.socket.send(&d.bytes),
                };
            }
        }
    })?;
    Ok(tx)
}

/// How early a scheduler asks to be woken, learnt from how late its timed waits return: a
/// sleeping thread wakes 50–250 µs late on a loaded 2-core machine, which on every datagram
/// both ways added a millisecond to a 10 ms emulated round trip. The margin follows the wake
/// latency (a slow average up, a fast one down), capped at 1 ms so a stall does not turn the
/// scheduler into a spinner.
#[derive(Debug, Clone, Copy)]
struct EarlyWake {
    margin_ns: u64,
}

impl Default for EarlyWake {
    fn default() -> Self {
        Self { margin_ns: 100_000 }
    }
}

impl EarlyWake {
    const MAX_NS: u64 = 1_000_000;

    /// A timed wait returned `late` after the time asked.
    fn woke(&mut self, late: Duration) {
        let late = (late.as_nanos() as u64).min(Self::MAX_NS);
        // Aim a little past the typical lateness: wakes later than the margin send late.
        let target = late + late / 4;
        self.margin_ns = if target > self.margin_ns {
            self.margin_ns + (target - self.margin_ns) / 4
        } else {
            self.margin_ns - (self.margin_ns - target) / 32
        };
    }
}

/// Copy `from` → `into`, each chunk `delay_ns` after it was read (a reader and a writer
/// thread; the stream ends when either side closes).
fn pump(mut from: TcpStream, mut into: TcpStream, delay_ns: u64) -> anyhow::Result<()> {
    let _ = from.set_nodelay(true);
    let _ = into.set_nodelay(true);
    let (tx, rx) = mpsc::channel::<(Instant, Vec<u8>)>();
    spawn("relay tcp read", move || {
        let mut buf = vec![0u8; 64 * 1024];
        while let Ok(n @ 1..) = from.read(&mut buf) {
            if tx.send((Instant::now(), buf[..n].to_vec())).is_err() {
                return;
            }
        }
    })?;
    spawn("relay tcp write", move || {
        let delay = Duration::from_nanos(delay_ns);
        for (read_at, chunk) in rx {
            let due = read_at + delay;
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
            if into.write_all(&chunk).is_err() {
                break;
            }
        }
        let _ = into.shutdown(std::net::Shutdown::Both);
    })?;
    Ok(())
}

/// `workstation relay`: start, say what it does, run until killed or `--seconds`.
pub fn run(args: &RelayArgs) -> anyhow::Result<()> {
    let imp = args.impairments()?;
    if let Some(s) = args.seconds {
        anyhow::ensure!(
            s.is_finite() && s > 0.0 && s <= 1e6,
            "--seconds {s}: must be in (0, 1000000]"
        );
    }
    let relay = Relay::start(args.listen, args.to, imp)?;
    let describe = |p: &LinkParams| {
        format!(
            "delay {} ms, jitter 0..{} ms, loss {}, reorder {}, duplicate {}",
            p.delay_ns as f64 / 1e6,
            p.jitter_ns as f64 / 1e6,
            p.loss,
            p.reorder,
            p.duplicate
        )
    };
    println!(
        "relay: {} (UDP and TCP) -> {}\n  up   (workstation -> server): {}\n  down (server -> workstation): {}\n  TCP: delay only; seed {}",
        relay.local,
        args.to,
        describe(&imp.up),
        describe(&imp.down),
        args.seed
    );
    let started = Instant::now();
    let mut last_log = started;
    loop {
        std::thread::sleep(Duration::from_millis(100));
        if args
            .seconds
            .is_some_and(|s| started.elapsed().as_secs_f64() >= s)
        {
            break;
        }
        if last_log.elapsed() >= Duration::from_secs(10) {
            last_log = Instant::now();
            let c = relay.counters();
            tracing::info!(
                "relay: up {}/{} forwarded ({} lost), down {}/{} ({} lost), {} TCP connections",
                c.up.forwarded,
                c.up.received,
                c.up.lost,
                c.down.forwarded,
                c.down.received,
                c.down.lost,
                c.tcp_connections
            );
        }
    }
    println!("{}", serde_json::to_string(&relay.counters())?);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(extra: &[&str]) -> RelayArgs {
        use clap::Parser;
        #[derive(Parser)]
        struct Cli {
            #[command(flatten)]
            relay: RelayArgs,
        }
        let mut v = vec!["relay", "--listen", "127.0.0.1:0", "--to", "127.0.0.1:9"];
        v.extend_from_slice(extra);
        Cli::parse_from(v).relay
    }

    #[test]
    fn impairments_take_one_value_or_up_and_down() {
        let i = args(&["--delay", "5", "--loss", "0.02/0.1", "--jitter", "1/0"])
            .impairments()
            .unwrap();
        assert_eq!((i.up.delay_ns, i.down.delay_ns), (5_000_000, 5_000_000));
        assert_eq!((i.up.loss, i.down.loss), (0.02, 0.1));
        assert_eq!((i.up.jitter_ns, i.down.jitter_ns), (1_000_000, 0));
        assert_ne!(i.up.seed, i.down.seed, "the directions draw independently");
    }

    #[test]
    fn bad_impairments_name_the_flag() {
        for (flag, value, says) in [
            ("--loss", "1.5", "probability"),
            ("--delay", "-1", "milliseconds"),
            ("--delay", "20000", "milliseconds"),
            ("--reorder", "x", "not a number"),
            ("--duplicate", "0.1/nan", "probability"),
        ] {
            let e = args(&[&format!("{flag}={value}")])
                .impairments()
                .unwrap_err()
                .to_string();
            assert!(e.contains(flag) && e.contains(says), "{flag} {value}: {e}");
        }
    }

    /// A UDP echo server on loopback; answers every datagram with itself.
    fn echo() -> SocketAddr {
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        let addr = s.local_addr().unwrap();
        std::thread::spawn(move || {
            let mut buf = [0u8; 2048];
            while let Ok((n, from)) = s.recv_from(&mut buf) {
                let _ = s.send_to(&buf[..n], from);
            }
        });
        addr
    }

    #[test]
    fn datagrams_take_the_configured_delay_each_way() {
        let imp = args(&["--delay", "3/5"]).impairments().unwrap();
        let relay = Relay::start("127.0.0.1:0".parse().unwrap(), echo(), imp).unwrap();
        let c = UdpSocket::bind("127.0.0.1:0").unwrap();
        c.connect(relay.local).unwrap();
        c.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
        let mut rtts = Vec::new();
        for i in 0..20u32 {
            let t = Instant::now();
            c.send(&i.to_le_bytes()).unwrap();
            let mut buf = [0u8; 16];
            let n = c.recv(&mut buf).unwrap();
            assert_eq!(&buf[..n], &i.to_le_bytes());
            rtts.push(t.elapsed().as_secs_f64() * 1e3);
        }
        rtts.sort_by(f64::total_cmp);
        let (min, p50) = (rtts[0], rtts[10]);
        assert!(
            min >= 8.0,
            "3 + 5 ms configured, fastest round trip {min} ms"
        );
        assert!(
            p50 < 12.0,
            "3 + 5 ms configured, median round trip {p50} ms"
        );
        let k = relay.counters();
        assert_eq!((k.up.forwarded, k.down.forwarded), (20, 20));
    }

    #[test]
    fn loss_and_duplication_match_their_probabilities_per_direction() {
        let imp = args(&["--loss", "0.1/0", "--duplicate", "0/0.2", "--seed", "7"])
            .impairments()
            .unwrap();
        let relay = Relay::start("127.0.0.1:0".parse().unwrap(), echo(), imp).unwrap();
        let c = UdpSocket::bind("127.0.0.1:0").unwrap();
        c.connect(relay.local).unwrap();
        const N: u64 = 2000;
        for i in 0..N {
            c.send(&i.to_le_bytes()).unwrap();
            if i % 10 == 0 {
                std::thread::sleep(Duration::from_millis(1)); // a 10 kHz stream, not one burst
            }
        }
        let t = Instant::now();
        while relay.counters().down.forwarded < relay.counters().down.received
            || relay.counters().down.received < relay.counters().up.forwarded
        {
            assert!(
                t.elapsed() < Duration::from_secs(5),
                "{:?}",
                relay.counters()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        let k = relay.counters();
        // The kernel may drop a datagram on a loaded machine before the relay reads it: the
        // relay's own decisions are measured against what it received.
        assert!(k.up.received >= N * 98 / 100, "{k:?}");
        // Binomial: 4 standard deviations either side.
        let within = |count: u64, n: u64, p: f64| {
            let sd = (n as f64 * p * (1.0 - p)).sqrt();
            (count as f64 - n as f64 * p).abs() <= 4.0 * sd
        };
        assert!(within(k.up.lost, k.up.received, 0.1), "{k:?}");
        assert_eq!(k.down.lost, 0, "{k:?}");
        assert!(within(k.down.duplicated, k.down.received, 0.2), "{k:?}");
        assert_eq!(k.up.duplicated, 0, "{k:?}");
    }

    #[test]
    fn tcp_is_delayed_and_kept_in_order() {
        let server = TcpListener::bind("127.0.0.1:0").unwrap();
        let to = server.local_addr().unwrap();
        std::thread::spawn(move || {
            let (mut s, _) = server.accept().unwrap();
            let mut buf = [0u8; 4096];
            while let Ok(n @ 1..) = s.read(&mut buf) {
                s.write_all(&buf[..n]).unwrap();
            }
        });
        let imp = args(&["--delay", "4", "--loss", "0.5", "--jitter", "3"])
            .impairments()
            .unwrap();
        let relay = Relay::start("127.0.0.1:0".parse().unwrap(), to, imp).unwrap();
        let mut c = TcpStream::connect(relay.local).unwrap();
        let msg: Vec<u8> = (0..20_000u32).map(|i| (i % 251) as u8).collect();
        let t = Instant::now();
        c.write_all(&msg).unwrap();
        let mut back = vec![0u8; msg.len()];
        c.read_exact(&mut back).unwrap();
        assert!(back == msg, "the control stream arrives whole and in order");
        assert!(t.elapsed() >= Duration::from_millis(8), "{:?}", t.elapsed());
        assert_eq!(relay.counters().tcp_connections, 1);
    }
}
