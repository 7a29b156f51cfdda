//! A running server: a device, the servo and telemetry threads, and one transport on a tokio
//! runtime of its own. [`Server::start`] works the same from `main` and from tests (which use
//! [`ServerOptions::for_tests`]: loopback, port 0, a fresh certificate, a fresh authorized
//! client identity, no real-time requests).

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use protocol::control::Stats;
use rustls::pki_types::CertificateDer;
use tokio::sync::watch;

use crate::clock::MonoClock;
use crate::device::Device;
use crate::servo::driver::{self, CursorSink, DriverConfig, RingWaker, ServoThreads};
use crate::servo::hot_socket::HotSocket;
use crate::servo::rt::RtRequest;
use crate::servo::{SafetyParams, ServoParams};
use crate::telemetry::ServoStats;
use crate::tls::{self, AuthorizedClients, Identity};
use crate::transport::{NetSettings, Shared, quic, udp};

pub use haptics_client::TransportKind;

/// Everything [`Server::start`] needs besides the device.
#[derive(Debug, Clone)]
pub struct ServerOptions {
    /// Transport.
    pub transport: TransportKind,
    /// Listen address (UDP: TCP and UDP on the same port).
    pub listen: SocketAddr,
    /// The certificate the workstation pins.
    pub identity: Identity,
    /// The client certificates that may open a session.
    pub authorized: AuthorizedClients,
    /// A client identity on this machine that `authorized` lists (tests, the in-process demo,
    /// a server that created one on first start), handed to local workstations.
    pub local_client: Option<Identity>,
    /// Servo loop settings (device limits are applied on top by `start`).
    pub driver: DriverConfig,
    /// Network timeouts.
    pub net: NetSettings,
}

impl ServerOptions {
    /// Loopback on a free port, a fresh certificate and authorized client identity, no
    /// real-time requests, no log summaries.
    pub fn for_tests(transport: TransportKind) -> Result<Self, ServerError> {
        let client = tls::generate_client()?;
        Ok(Self {
            transport,
            listen: SocketAddr::from(([127, 0, 0, 1], 0)),
            identity: tls::generate()?,
            authorized: AuthorizedClients::new(vec![client.cert.clone()]),
            local_client: Some(client),
            driver: DriverConfig {
                params: ServoParams {
                    rate_hz: 1000,
                    safety: SafetyParams::default(),
                    smoothing_alpha: 0.0,
                    device_max_force_n: f32::INFINITY,
                    max_stiffness_n_per_m: f32::INFINITY,
                    max_damping_n_s_per_m: f32::INFINITY,
                    estop_button_mask: 0,
                    passivity: false,
                },
                rt: RtRequest {
                    fifo_priority: None,
                    cpu: None,
                    mlockall: false,
                },
                spin: Duration::from_micros(50),
                log_every: Duration::ZERO,
                record: None,
                cursor_deadband: 0.0,
            },
            net: NetSettings::default(),
        })
    }
}

/// Why the server could not start.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ServerError {
    /// Binding sockets or spawning threads failed.
    #[error("I/O: {0}")]
    Io(#[from] std::io::Error),
    /// Certificate or TLS configuration.
    #[error(transparent)]
    Tls(#[from] tls::TlsError),
    /// Transport setup.
    #[error(transparent)]
    Transport(#[from] crate::transport::TransportError),
}

/// A running server; dropping it shuts it down (force to zero first).
/// `SCHED_FIFO` priority of the network worker on QUIC, where quinn's endpoint (receiving,
/// decrypting, acknowledging) and the cursor sender run: below the servo (80) and below the
/// workstation's force-mapping thread (60), so on one machine neither waits for it, and above
/// every ordinary thread. In the one-machine demo (a simulation and a renderer busy on both
/// cores) an ordinary worker held commands past their servo tick: 98.6–99.0 % of ticks
/// applied the answer to the previous cursor, p99 round trip 1.0–1.1 ms, against 99.97–100 %
/// and 0.17–0.22 ms real-time. An idle machine's latency runs pay for it at the median (75–92
/// → 100–124 µs: woken real-time, the worker is pushed to the other CPU, a cold wake-up on
/// this VM), not at the tick.
pub const QUIC_NETWORK_FIFO_PRIORITY: i32 = 50;

#[derive(Debug)]
pub struct Server {
    local_addr: SocketAddr,
    cert: CertificateDer<'static>,
    local_client: Option<Identity>,
    shared: Arc<Shared>,
    shutdown: watch::Sender<bool>,
    runtime: Option<std::thread::JoinHandle<()>>,
    servo: ServoThreads,
}

impl Server {
    /// Start serving `device`.
    pub fn start<D: Device + 'static>(
        device: D,
        opts: ServerOptions,
    ) -> Result<Server, ServerError> {
        let info = device.info().clone();
        let mut driver_cfg = opts.driver.clone();
        driver_cfg.params = driver_cfg.params.limited_to(&info);
        let params = driver_cfg.params;
        // The network worker runs every task: the TLS control channel on UDP (the servo reads
        // the UDP hot path itself); on QUIC also quinn's endpoint (receiving, decrypting,
        // acknowledging) and the cursor sender, so a datagram's arrival or a cursor's departure
        // wakes this one thread. On QUIC it runs real-time ([`QUIC_NETWORK_FIFO_PRIORITY`]).
        // A current-thread runtime instead was slower (QUIC round trip p50 117–142 µs against
        // 75–92 µs, same session): woken tasks wait behind the queue instead of running next.
        let mut builder = tokio::runtime::Builder::new_multi_thread();
        builder
            .worker_threads(1)
            .thread_name("network")
            .enable_all();
        if opts.transport == TransportKind::Quic && opts.driver.rt.fifo_priority.is_some() {
            builder.on_thread_start(|| {
                if let Err(e) = crate::servo::rt::set_fifo(QUIC_NETWORK_FIFO_PRIORITY) {
                    tracing::warn!("the QUIC network worker stays SCHED_OTHER: {e}");
                }
            });
        }
        let runtime = builder.build()?;
        let tls_cfg = tls::server_config(&opts.identity)?;
        let clock = MonoClock::new();
        let (shutdown, shutdown_rx) = watch::channel(false);
        let (local_addr, shared, servo) = match opts.transport {
            TransportKind::Udp => {
                let (tcp, sock) = udp::bind(opts.listen)?;
                let local_addr = tcp.local_addr()?;
                let sink = CursorSink::Udp(Box::new(HotSocket::new(sock)?));
                let (link, servo) = driver::spawn(device, sink, driver_cfg, clock)?;
                let shared = Arc::new(Shared::new(
                    clock,
                    link,
                    info,
                    params.rate_hz,
                    params.safety.max_force_n,
                    opts.net,
                    opts.authorized.clone(),
                ));
                let _guard = runtime.enter();
                runtime.spawn(udp::run(Arc::clone(&shared), tcp, tls_cfg, shutdown_rx));
                (local_addr, shared, servo)
            }
            TransportKind::Quic => {
                let endpoint = {
                    let _guard = runtime.enter();
                    quic::endpoint(opts.listen, tls_cfg, opts.net.idle_timeout)?
                };
                let local_addr = endpoint.local_addr()?;
                let current: quic::Current = Arc::default();
                let (tx, rx) = rtrb::RingBuffer::new(64);
                let (waker, wake) = RingWaker::pair()?;
                {
                    let _guard = runtime.enter();
                    runtime.spawn(quic::sender(rx, wake, Arc::clone(&current)));
                }
                let sink = CursorSink::Ring(tx, waker);
                let (link, servo) = driver::spawn(device, sink, driver_cfg, clock)?;
                let shared = Arc::new(Shared::new(
                    clock,
                    link,
                    info,
                    params.rate_hz,
                    params.safety.max_force_n,
                    opts.net,
                    opts.authorized.clone(),
                ));
                runtime.spawn(quic::run(
                    Arc::clone(&shared),
                    endpoint,
                    current,
                    shutdown_rx,
                ));
                (local_addr, shared, servo)
            }
        };
        // The runtime lives on a thread of its own, so a server can be dropped anywhere
        // (including inside another runtime, as in async tests).
        let mut wait = shutdown.subscribe();
        let runtime = std::thread::Builder::new()
            .name("network-rt".into())
            .spawn(move || {
                runtime.block_on(async move {
                    let _ = wait.wait_for(|s| *s).await;
                });
                runtime.shutdown_timeout(Duration::from_secs(1));
            })?;
        Ok(Server {
            local_addr,
            cert: opts.identity.cert.clone(),
            local_client: opts.local_client.clone(),
            shared,
            shutdown,
            runtime: Some(runtime),
            servo,
        })
    }

    /// The bound address (UDP transport: TCP control and UDP hot path share it).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The certificate clients must pin.
    pub fn certificate(&self) -> CertificateDer<'static> {
        self.cert.clone()
    }

    /// The client identity on this machine that the server authorizes, if it has one
    /// ([`ServerOptions::local_client`]): what a local workstation presents.
    pub fn local_client(&self) -> Option<Identity> {
        self.local_client.clone()
    }

    /// Clients refused so far because they presented no authorized certificate.
    pub fn refused_unauthenticated(&self) -> u64 {
        self.shared.refused_unauthenticated.load(Ordering::Relaxed)
    }

    /// `Stats` of the active session, or of the last one.
    pub fn stats(&self) -> Stats {
        let hot = self.shared.active();
        self.shared.stats(hot.as_deref())
    }

    /// The servo thread's telemetry snapshot.
    pub fn servo_stats(&self) -> ServoStats {
        self.shared.servo_stats()
    }

    /// Start a new telemetry mark window: `servo_stats().lateness_since_mark_ns` covers the
    /// ticks from now on (within the telemetry thread's 10 ms period).
    pub fn mark_telemetry(&self) {
        self.shared.mark_telemetry();
    }

    /// Id of the active session.
    pub fn active_session(&self) -> Option<u32> {
        self.shared.active().map(|h| h.session)
    }

    /// Sessions started since the server started.
    pub fn sessions_started(&self) -> u64 {
        self.shared.sessions_started.load(Ordering::Relaxed)
    }

    /// Clients refused as busy.
    pub fn refused_busy(&self) -> u64 {
        self.shared.refused_busy.load(Ordering::Relaxed)
    }

    /// Stop: network first, then the servo loop (device left at zero force).
    pub fn shutdown(mut self) {
        self.stop();
    }

    fn stop(&mut self) {
        let _ = self.shutdown.send(true);
        if let Some(rt) = self.runtime.take() {
            let _ = rt.join();
        }
        self.servo.stop();
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.stop();
    }
}
