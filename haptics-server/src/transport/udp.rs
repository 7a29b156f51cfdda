//! The UDP transport: control over TLS-over-TCP, hot path as MAC'd UDP datagrams.
//!
//! Both listen on the same address and port (TCP for control, UDP for the hot path), so a
//! workstation needs one address and the pinned certificate. The session key travels in
//! `Welcome` inside TLS. The UDP socket belongs to the servo thread
//! ([`crate::servo::hot_socket::HotSocket`]): it drains and checks the commands at the top of
//! each tick, learns the client's address from its first authentic packet (the client sends a
//! zero `ForceCommand` right after `Welcome` to open the stream), follows it if it changes,
//! and sends the cursor packets there.

use std::net::{SocketAddr, TcpListener, UdpSocket};
use std::sync::Arc;

use tokio::sync::watch;

use super::{HotKind, Shared, serve_control};

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
