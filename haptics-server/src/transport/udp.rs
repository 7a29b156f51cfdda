//! The UDP transport: control over TLS-over-TCP, hot path as MAC'd UDP datagrams.
//!
//! Both listen on the same address and port (TCP for control, UDP for the hot path), so a
//! workstation needs one address and the pinned certificate. The session key travels in
//! `Welcome` inside TLS. The server learns the client's UDP address from its first authentic
//! packet (the client sends a zero `ForceCommand` right after `Welcome` to open the stream)
//! and follows it if it changes; cursor packets go there, sent by the servo thread itself
//! through a clone of the socket ([`crate::servo::driver::CursorSink::Udp`]).

use std::net::{SocketAddr, TcpListener, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::Ordering;

use protocol::packet::MAX_PACKET_BYTES;
use tokio::sync::watch;

use super::{HotKind, Shared, serve_control};
use crate::servo::driver::ServoMsg;

/// Bind TCP and UDP on one port of `listen` (port 0: a free port for both).
pub fn bind(listen: SocketAddr) -> std::io::Result<(TcpListener, UdpSocket)> {
    let mut last_err = None;
    for _ in 0..20 {
        let tcp = TcpListener::bind(listen)?;
        let addr = tcp.local_addr()?;
        match UdpSocket::bind(addr) {
            Ok(udp) => {
                tcp.set_nonblocking(true)?;
                udp.set_nonblocking(true)?;
                return Ok((tcp, udp));
            }
            Err(e) if listen.port() == 0 => last_err = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last_err.unwrap_or_else(|| std::io::Error::other("no free port for TCP and UDP")))
}

/// Start the hot-path receiver thread ([`receive`]); it ends within 100 ms of `shutdown`
/// turning true, and the server joins it so the port is free when shutdown returns.
///
/// With `fifo_priority` the thread asks for `SCHED_FIFO` at that priority (the servo's minus
/// one): a command then reaches the servo ring within microseconds of its arrival even when
/// ordinary threads keep both cores busy, instead of waiting for the fair scheduler's turn
/// (measured in docs/BENCHMARKS.md, "Latency runs"; [`crate::servo::rt::raise_hot_path_thread`]).
pub fn spawn_receiver(
    shared: Arc<Shared>,
    udp: UdpSocket,
    shutdown: watch::Receiver<bool>,
    fifo_priority: Option<i32>,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    std::thread::Builder::new()
        .name("udp-recv".into())
        .spawn(move || {
            crate::servo::rt::raise_hot_path_thread(fifo_priority, "hot-path receiver");
            receive(&shared, &udp, &shutdown)
        })
}

/// Serve the control connections until `shutdown` turns true.
pub async fn run(
    shared: Arc<Shared>,
    tcp: TcpListener,
    tls: rustls::ServerConfig,
    shutdown: watch::Receiver<bool>,
) -> std::io::Result<()> {
    let tcp = tokio::net::TcpListener::from_std(tcp)?;
    let acceptor = tokio_rustls::TlsAcceptor::from(Arc::new(tls));
    let mut stop = shutdown.clone();
    loop {
        tokio::select! {
            accepted = tcp.accept() => {
                let (stream, from) = match accepted {
                    Ok(a) => a,
                    Err(e) => {
                        tracing::warn!("accept failed: {e}");
                        continue;
                    }
                };
                let _ = stream.set_nodelay(true);
                let (shared, acceptor, shutdown) = (Arc::clone(&shared), acceptor.clone(), shutdown.clone());
                tokio::spawn(async move {
                    let tls = match tokio::time::timeout(shared.net.hello_timeout, acceptor.accept(stream)).await {
                        Ok(Ok(s)) => s,
                        Ok(Err(e)) => {
                            tracing::warn!(%from, "TLS handshake failed: {e}");
                            return;
                        }
                        Err(_) => {
                            tracing::warn!(%from, "TLS handshake timed out");
                            return;
                        }
                    };
                    let client_cert = tls.get_ref().1.peer_certificates().and_then(|c| c.first()).cloned();
                    let (mut rd, mut wr) = tokio::io::split(tls);
                    let mut shutdown = shutdown;
                    tokio::select! {
                        r = serve_control(&shared, &mut rd, &mut wr, HotKind::Udp, client_cert.as_ref(), |_| {}) => {
                            if let Err(e) = r {
                                tracing::warn!(%from, "control connection: {e}");
                            }
                        }
                        _ = shutdown.wait_for(|s| *s) => {}
                    }
                    let mut tls = rd.unsplit(wr);
                    let _ = tokio::io::AsyncWriteExt::shutdown(&mut tls).await;
                });
            }
            _ = stop.wait_for(|s| *s) => break,
        }
    }
    Ok(())
}

/// The hot-path receiver: a thread of its own that sleeps in `poll(2)` on the socket and
/// handles each datagram the moment it arrives (a wake-up through the async reactor and its
/// worker costs tens of µs per packet on a loaded machine; this is the latency-critical
/// direction of the force loop). The socket stays non-blocking because the servo thread sends
/// cursors through a clone of it and must never block.
fn receive(shared: &Shared, udp: &UdpSocket, shutdown: &watch::Receiver<bool>) {
    use std::os::fd::AsRawFd as _;
    let mut buf = [0u8; MAX_PACKET_BYTES + 1];
    // Ends on shutdown, or when the server that owns the sender is gone.
    while !*shutdown.borrow() && shutdown.has_changed().is_ok() {
        let mut pfd = libc::pollfd {
            fd: udp.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        // SAFETY: one valid pollfd for the duration of the call.
        let ready = unsafe { libc::poll(&mut pfd, 1, 100) };
        if ready <= 0 {
            continue;
        }
        loop {
            let (n, from) = match udp.recv_from(&mut buf) {
                Ok(r) => r,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
                // ICMP port unreachable from a vanished client surfaces here on Linux.
                Err(_) => continue,
            };
            let Some(hot) = shared.active() else {
                shared.unsolicited.fetch_add(1, Ordering::Relaxed);
                continue;
            };
            if shared.accept_hot(&hot, &buf[..n]) && hot.set_peer(from) {
                tracing::info!(%from, "hot path: streaming cursor samples to the workstation");
                shared.servo(ServoMsg::Peer(from));
            }
        }
    }
}
