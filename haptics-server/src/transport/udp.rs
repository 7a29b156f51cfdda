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

/// Serve until `shutdown` turns true.
pub async fn run(
    shared: Arc<Shared>,
    tcp: TcpListener,
    udp: UdpSocket,
    tls: rustls::ServerConfig,
    shutdown: watch::Receiver<bool>,
) -> std::io::Result<()> {
    let tcp = tokio::net::TcpListener::from_std(tcp)?;
    let udp = tokio::net::UdpSocket::from_std(udp)?;
    let acceptor = tokio_rustls::TlsAcceptor::from(Arc::new(tls));
    let recv = tokio::spawn(receive(Arc::clone(&shared), udp, shutdown.clone()));
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
                    let (mut rd, mut wr) = tokio::io::split(tls);
                    let mut shutdown = shutdown;
                    tokio::select! {
                        r = serve_control(&shared, &mut rd, &mut wr, HotKind::Udp, |_| {}) => {
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
    recv.abort();
    Ok(())
}

async fn receive(
    shared: Arc<Shared>,
    udp: tokio::net::UdpSocket,
    mut shutdown: watch::Receiver<bool>,
) {
    let mut buf = [0u8; MAX_PACKET_BYTES + 1];
    loop {
        let (n, from) = tokio::select! {
            r = udp.recv_from(&mut buf) => match r {
                Ok(r) => r,
                // ICMP port unreachable from a vanished client surfaces here on Linux.
                Err(_) => continue,
            },
            _ = shutdown.wait_for(|s| *s) => return,
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
