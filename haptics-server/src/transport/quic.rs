//! The QUIC transport (quinn): unreliable datagrams for cursor/force, one bidirectional
//! stream (opened by the client) for control.
//!
//! Tuned for latency: datagram send and receive buffers hold only a few packets, so when the
//! path stalls stale samples are dropped, not queued. Cursor packets reach quinn through a
//! sender task on the network runtime's one worker, beside quinn's own drivers: the servo
//! pushes each to a wait-free ring and wakes the task with one byte on a datagram socket the
//! runtime watches ([`crate::servo::driver::RingWaker`]), so the cursor's way out wakes one
//! thread (it was a sender thread, then the worker: two); quinn's `send_datagram` (which locks
//! the connection) never runs on the servo thread.

use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use quinn::crypto::rustls::QuicServerConfig;
use rustls::pki_types::CertificateDer;
use tokio::sync::watch;

use super::{HotKind, Shared, TransportError, serve_control};
use crate::servo::driver::Datagram;

pub use haptics_client::quic::{DATAGRAM_BUFFER_BYTES, transport_config};

/// A QUIC server endpoint on `listen`.
pub fn endpoint(
    listen: SocketAddr,
    tls: rustls::ServerConfig,
    idle: Duration,
) -> Result<quinn::Endpoint, TransportError> {
    let crypto =
        QuicServerConfig::try_from(tls).map_err(|e| TransportError::Quic(e.to_string()))?;
    let mut cfg = quinn::ServerConfig::with_crypto(Arc::new(crypto));
    cfg.transport_config(Arc::new(transport_config(idle)));
    Ok(quinn::Endpoint::server(cfg, listen)?)
}

/// The connection cursor packets currently go to.
pub type Current = Arc<Mutex<Option<quinn::Connection>>>;

/// The sender task: each time the servo's byte arrives on `wake`, drains the servo's cursor
/// ring into the current connection. Runs until the socket fails (the servo's end dropped) or
/// the runtime shuts down.
pub async fn sender(
    mut rx: rtrb::Consumer<Datagram>,
    wake: std::os::unix::net::UnixDatagram,
    current: Current,
) {
    let wake = match tokio::net::UnixDatagram::from_std(wake) {
        Ok(w) => w,
        Err(e) => {
            tracing::error!("QUIC cursor sender: {e}");
            return;
        }
    };
    // Each datagram's `Bytes` is cut from a reused block: no allocation per cursor.
    let mut arena = haptics_client::quic::DatagramArena::new();
    let mut byte = [0u8; 64];
    loop {
        if wake.readable().await.is_err() {
            return;
        }
        // Take every pending wake-up byte, then every queued cursor.
        loop {
            match wake.try_recv(&mut byte) {
                Ok(_) => {}
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
                Err(_) => return,
            }
        }
        while let Ok(d) = rx.pop() {
            let conn = current.lock().ok().and_then(|c| c.clone());
            if let Some(conn) = conn {
                // Fails only when the peer disabled datagrams or the connection is gone.
                let _ = conn.send_datagram(arena.bytes(&d.bytes[..d.len]));
            }
        }
    }
}

/// Serve until `shutdown` turns true.
pub async fn run(
    shared: Arc<Shared>,
    endpoint: quinn::Endpoint,
    current: Current,
    mut shutdown: watch::Receiver<bool>,
) {
    loop {
        let incoming = tokio::select! {
            i = endpoint.accept() => match i {
                Some(i) => i,
                None => break,
            },
            _ = shutdown.wait_for(|s| *s) => break,
        };
        let (shared, current, mut shutdown) =
            (Arc::clone(&shared), Arc::clone(&current), shutdown.clone());
        tokio::spawn(async move {
            tokio::select! {
                r = connection(&shared, incoming, &current) => if let Err(e) = r {
                    tracing::warn!("QUIC connection: {e}");
                },
                _ = shutdown.wait_for(|s| *s) => {}
            }
        });
    }
    endpoint.close(0u8.into(), b"server shutting down");
}

async fn connection(
    shared: &Arc<Shared>,
    incoming: quinn::Incoming,
    current: &Current,
) -> Result<(), TransportError> {
    let conn = tokio::time::timeout(shared.net.hello_timeout, incoming)
        .await
        .map_err(|_| TransportError::Timeout("QUIC handshake"))?
        .map_err(|e| TransportError::Quic(e.to_string()))?;
    let from = conn.remote_address();
    let (mut wr, mut rd) = tokio::time::timeout(shared.net.hello_timeout, conn.accept_bi())
        .await
        .map_err(|_| TransportError::Timeout("control stream"))?
        .map_err(|e| TransportError::Quic(e.to_string()))?;
    let reader = {
        let (conn, current, shared) = (conn.clone(), Arc::clone(current), Arc::clone(shared));
        move |hot: Arc<super::HotState>| {
            if let Ok(mut c) = current.lock() {
                *c = Some(conn.clone());
            }
            tracing::info!(%from, "hot path: QUIC datagrams");
            tokio::spawn(async move {
                while let Ok(d) = conn.read_datagram().await {
                    if hot.ended() {
                        break;
                    }
                    shared.accept_hot(&hot, &d);
                }
            });
        }
    };
    let client_cert = conn
        .peer_identity()
        .and_then(|id| id.downcast::<Vec<CertificateDer<'static>>>().ok())
        .and_then(|certs| certs.first().cloned());
    let result = serve_control(
        shared,
        &mut rd,
        &mut wr,
        HotKind::Quic,
        client_cert.as_ref(),
        reader,
    )
    .await;
    if let Ok(mut c) = current.lock()
        && c.as_ref()
            .is_some_and(|c| c.stable_id() == conn.stable_id())
    {
        *c = None;
    }
    let started = matches!(result, Ok(Some(_)));
    let _ = wr.finish();
    if !started {
        // Refused (busy, version): let the client read the error before closing.
        let _ = tokio::time::timeout(Duration::from_secs(1), conn.closed()).await;
    }
    conn.close(
        0u8.into(),
        if started {
            b"session ended"
        } else {
            b"refused"
        },
    );
    result.map(|_| ())
}
