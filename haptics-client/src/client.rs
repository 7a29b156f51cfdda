//! The workstation side of a session, over either transport: handshake, control channel and
//! hot path. The `workstation` crate connects through this; tests drive servers with it.
//! `haptics-server` re-exports this module as `haptics_server::client`.
//!
//! ```no_run
//! # async fn demo(cert: rustls::pki_types::CertificateDer<'static>) -> Result<(), haptics_client::ClientError> {
//! use haptics_client::{Client, ClientConfig, TransportKind};
//! let cfg = ClientConfig::new("127.0.0.1:7700".parse().unwrap(), TransportKind::Udp, cert);
//! let mut client = Client::connect(&cfg).await?;
//! let cursor = client.hot.recv_cursor().await?;        // one CursorSample per servo tick
//! // … compute a ForceCommand answering `cursor` …
//! # let cmd: protocol::ForceCommand = todo!();
//! client.hot.send_force(&cmd)?;                         // never blocks
//! client.control.close("done").await?;
//! # Ok(()) }
//! ```
//!
//! [`Client::connect`] sends `Hello`, waits for `Welcome` (or the server's `Error`, e.g.
//! `Busy`, as [`ClientError::Refused`]), then on UDP sends one zero `ForceCommand` (no model)
//! so the server learns where to stream. [`HotPath::recv_cursor`] skips (and counts) packets
//! that fail [`protocol::Inbound`]; [`ControlChannel`] carries everything else.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use glam::Vec3;
use protocol::control::{Bye, ErrorCode, Hello, Welcome};
use protocol::packet::MAX_PACKET_BYTES;
use protocol::{
    Body, Control, CursorSample, ForceCommand, FrameDecoder, Inbound, LocalModel, Outbound,
    PROTOCOL_VERSION, Packet, RejectCounts, SessionKey,
};
use rustls::pki_types::CertificateDer;
use tokio::io::{AsyncRead, AsyncWrite};

use crate::TransportKind;
use crate::clock::MonoClock;
use crate::framing::{TransportError, read_control, write_control};
use crate::{quic, tls};

/// How to reach a server.
#[derive(Debug, Clone)]
pub struct ClientConfig {
    /// Server address (UDP transport: TCP control and UDP hot path share it).
    pub server: SocketAddr,
    /// Transport.
    pub transport: TransportKind,
    /// The server's certificate, pinned.
    pub pinned_cert: CertificateDer<'static>,
    /// Name for the server's logs.
    pub client_name: String,
    /// Cursor rate asked for, Hz.
    pub requested_rate_hz: u32,
    /// Limit on connect + handshake.
    pub timeout: Duration,
    /// QUIC idle timeout (keep-alives at a quarter of it).
    pub idle_timeout: Duration,
    /// The workstation's client certificate and key, which the server must list as
    /// authorized; without one the server answers `Error { Unauthenticated }`.
    pub identity: Option<tls::Identity>,
}

impl ClientConfig {
    /// Defaults: name `workstation`, 1000 Hz, 5 s handshake timeout, 2 s idle timeout.
    pub fn new(
        server: SocketAddr,
        transport: TransportKind,
        pinned_cert: CertificateDer<'static>,
    ) -> Self {
        Self {
            server,
            transport,
            pinned_cert,
            client_name: "workstation".into(),
            requested_rate_hz: 1000,
            timeout: Duration::from_secs(5),
            idle_timeout: Duration::from_secs(2),
            identity: None,
        }
    }

    /// The same, presenting `identity` as the client certificate.
    pub fn with_identity(mut self, identity: tls::Identity) -> Self {
        self.identity = Some(identity);
        self
    }
}

/// Why a client operation failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ClientError {
    /// Socket I/O.
    #[error("I/O: {0}")]
    Io(#[from] std::io::Error),
    /// TLS setup.
    #[error(transparent)]
    Tls(#[from] tls::TlsError),
    /// Control-channel protocol error.
    #[error(transparent)]
    Transport(#[from] TransportError),
    /// QUIC connect or connection error.
    #[error("QUIC: {0}")]
    Quic(String),
    /// The server refused (e.g. `Busy`: another workstation holds the session).
    #[error("server refused the session ({code:?}): {message}")]
    Refused {
        /// Machine-readable cause.
        code: ErrorCode,
        /// The server's explanation.
        message: String,
    },
    /// The server said something unexpected.
    #[error("protocol: {0}")]
    Protocol(String),
    /// The handshake took too long.
    #[error("timed out: {0}")]
    Timeout(&'static str),
    /// The control channel or connection is closed.
    #[error("connection closed")]
    Closed,
}

type Reader = Box<dyn AsyncRead + Send + Unpin>;
type Writer = Box<dyn AsyncWrite + Send + Unpin>;

/// A connected session.
#[derive(Debug)]
pub struct Client {
    /// The server's `Welcome` (device limits, session id).
    pub welcome: Welcome,
    /// Control messages (clock pings, config, stats, bye).
    pub control: ControlChannel,
    /// Cursor samples in, force commands out.
    pub hot: HotPath,
}

/// The reliable control channel of a session.
pub struct ControlChannel {
    rd: Reader,
    wr: Writer,
    dec: FrameDecoder,
    conn: Option<quinn::Connection>,
}

impl std::fmt::Debug for ControlChannel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ControlChannel")
            .field("quic", &self.conn.is_some())
            .finish()
    }
}

impl ControlChannel {
    /// Send one message.
    pub async fn send(&mut self, msg: &Control) -> Result<(), ClientError> {
        Ok(write_control(&mut self.wr, msg).await?)
    }

    /// The next message; [`ClientError::Closed`] when the server closed the channel.
    pub async fn recv(&mut self) -> Result<Control, ClientError> {
        read_control(&mut self.rd, &mut self.dec)
            .await?
            .ok_or(ClientError::Closed)
    }

    /// Send raw bytes (tests: malformed frames).
    pub async fn send_raw(&mut self, bytes: &[u8]) -> Result<(), ClientError> {
        tokio::io::AsyncWriteExt::write_all(&mut self.wr, bytes).await?;
        Ok(tokio::io::AsyncWriteExt::flush(&mut self.wr).await?)
    }

    /// Say `Bye` and close.
    pub async fn close(mut self, reason: &str) -> Result<(), ClientError> {
        self.send(&Control::Bye(Bye {
            reason: reason.into(),
        }))
        .await?;
        let _ = tokio::io::AsyncWriteExt::shutdown(&mut self.wr).await;
        if let Some(c) = &self.conn {
            // Give the Bye a moment to leave before the connection goes.
            let _ = tokio::time::timeout(Duration::from_millis(200), c.closed()).await;
        }
        Ok(())
    }
}

/// The hot path of a session: a [`HotReceiver`] and a [`HotSender`] over the same socket
/// (UDP) or connection (QUIC), plus the UDP opener until the stream is up.
pub struct HotPath {
    rx: HotReceiver,
    tx: HotSender,
    key: Option<SessionKey>,
    streaming: bool,
}

impl std::fmt::Debug for HotPath {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HotPath")
            .field("session", &self.rx.inbound.session())
            .finish()
    }
}

impl HotPath {
    /// The next authentic cursor packet (rejected ones are counted in [`HotPath::rejects`]).
    pub async fn recv_cursor(&mut self) -> Result<(Packet, CursorSample), ClientError> {
        if !self.streaming && matches!(self.rx.socket, ReceiverSocket::Udp(_)) {
            // Until the first cursor arrives, re-send the opener every 100 ms: the server
            // learns our address from it, and UDP may lose it. (Receiving is cancel-safe.)
            loop {
                match tokio::time::timeout(Duration::from_millis(100), self.rx.recv_cursor()).await
                {
                    Ok(r) => {
                        self.streaming = r.is_ok();
                        return r;
                    }
                    Err(_) => self.send_force(&zero_command())?,
                }
            }
        }
        let r = self.rx.recv_cursor().await;
        self.streaming |= r.is_ok();
        r
    }

    /// UDP only, without the async runtime: wait in `poll(2)` up to `timeout` for the next
    /// authentic cursor (`Ok(None)` when none came). A thread that does nothing but answer
    /// cursors (`workstation latency`) saves the reactor's wake-up hop this way. After the
    /// stream is up (the opener is not re-sent here).
    pub fn recv_cursor_blocking(
        &mut self,
        timeout: Duration,
    ) -> Result<Option<(Packet, CursorSample)>, ClientError> {
        let SenderSocket::Udp(socket) = &self.tx.socket else {
            return Err(ClientError::Protocol(
                "blocking receive is for the UDP transport".into(),
            ));
        };
        recv_cursor_polling(socket, &mut self.rx.inbound, timeout)
    }

    /// Send a force command now (non-blocking; dropped if the socket buffer is full: a newer
    /// command will follow, and the server's watchdog covers a gap).
    pub fn send_force(&mut self, cmd: &ForceCommand) -> Result<(), ClientError> {
        self.tx.send_force(cmd)
    }

    /// Send arbitrary bytes on the hot path (tests: forged and malformed packets). Unlike
    /// [`HotPath::send_force`], a full socket buffer is an error (`WouldBlock`), not a drop.
    pub fn send_raw(&self, bytes: &[u8]) -> Result<(), ClientError> {
        self.tx.send_raw(bytes)
    }

    /// Rejected incoming packets by reason.
    pub fn rejects(&self) -> &RejectCounts {
        self.rx.rejects()
    }

    /// The session's MAC key (UDP only).
    pub fn session_key(&self) -> Option<&SessionKey> {
        self.key.as_ref()
    }

    /// The client clock that stamps force commands; use it for `ClockPing.t0_ns` and the
    /// pong's receive time so [`protocol::ClockEstimator`] relates the same clocks.
    pub fn clock(&self) -> MonoClock {
        self.tx.clock
    }

    /// See [`HotSender::last_sent`].
    pub fn last_sent(&self) -> Option<(u32, u64)> {
        self.tx.last_sent()
    }

    /// The sequence number the next force command will carry.
    pub fn next_sequence(&self) -> u32 {
        self.tx.outbound.next_sequence()
    }

    /// Split into a receiver for the network task and a sender a force-mapping thread owns
    /// (call once the stream is up: after the first [`HotPath::recv_cursor`], so the UDP opener
    /// is no longer needed). Sequence numbers continue from this hot path's.
    pub fn split(self) -> (HotReceiver, HotSender) {
        (self.rx, self.tx)
    }
}

enum ReceiverSocket {
    Udp(tokio::net::UdpSocket),
    // The endpoint is held so its socket lives as long as the connection.
    Quic(quinn::Connection, #[allow(dead_code)] quinn::Endpoint),
}

enum SenderSocket {
    /// A clone of the receiving socket used with a plain non-blocking `send`, which (unlike
    /// tokio's `try_send`) does not depend on the reactor having seen the socket writable yet:
    /// under load that made the first packet vanish.
    Udp(std::net::UdpSocket),
    Quic(quinn::Connection),
}

/// The receiving half of a [`HotPath`] (async, for the network task).
pub struct HotReceiver {
    socket: ReceiverSocket,
    inbound: Inbound,
}

impl std::fmt::Debug for HotReceiver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HotReceiver")
            .field("session", &self.inbound.session())
            .finish()
    }
}

impl HotReceiver {
    /// The next authentic cursor packet; [`ClientError::Closed`] when a QUIC connection ends.
    /// Cancel-safe: a packet is either returned or was never taken from the socket.
    pub async fn recv_cursor(&mut self) -> Result<(Packet, CursorSample), ClientError> {
        let mut buf = [0u8; MAX_PACKET_BYTES + 1];
        loop {
            let n = match &self.socket {
                ReceiverSocket::Udp(s) => s.recv(&mut buf).await?,
                ReceiverSocket::Quic(c, _) => {
                    let d = c.read_datagram().await.map_err(|_| ClientError::Closed)?;
                    let n = d.len().min(buf.len());
                    buf[..n].copy_from_slice(&d[..n]);
                    n
                }
            };
            if let Ok(p) = self.inbound.accept(&buf[..n])
                && let Body::Cursor(c) = p.body
            {
                return Ok((p, c));
            }
        }
    }

    /// Rejected incoming packets by reason.
    pub fn rejects(&self) -> &RejectCounts {
        self.inbound.rejects()
    }

    /// UDP: this receiver without the async runtime (the socket leaves the reactor), for a
    /// force-mapping thread that waits on the socket itself: one wake-up between a cursor's
    /// arrival and its answer instead of two. QUIC datagrams need quinn's driver task: an
    /// error (check [`HotReceiver::is_udp`] first). Call inside the runtime.
    pub fn into_blocking(self) -> Result<BlockingReceiver, ClientError> {
        match self.socket {
            ReceiverSocket::Udp(s) => Ok(BlockingReceiver {
                socket: s.into_std()?,
                inbound: self.inbound,
            }),
            ReceiverSocket::Quic(..) => Err(ClientError::Protocol(
                "blocking receive is for the UDP transport".into(),
            )),
        }
    }

    /// Whether this is the UDP transport's receiver (see [`HotReceiver::into_blocking`]).
    pub fn is_udp(&self) -> bool {
        matches!(self.socket, ReceiverSocket::Udp(_))
    }
}

/// The UDP hot path's receiving half without a runtime ([`HotReceiver::into_blocking`]): the
/// thread that answers cursors waits in `poll(2)` on the socket itself.
pub struct BlockingReceiver {
    socket: std::net::UdpSocket,
    inbound: Inbound,
}

impl std::fmt::Debug for BlockingReceiver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BlockingReceiver")
            .field("session", &self.inbound.session())
            .finish()
    }
}

impl BlockingReceiver {
    /// Wait up to `timeout` for the next authentic cursor (`Ok(None)` when none came; a zero
    /// timeout only takes what is already queued). Rejected packets are counted and skipped.
    pub fn recv_cursor(
        &mut self,
        timeout: Duration,
    ) -> Result<Option<(Packet, CursorSample)>, ClientError> {
        recv_cursor_polling(&self.socket, &mut self.inbound, timeout)
    }

    /// Rejected incoming packets by reason.
    pub fn rejects(&self) -> &RejectCounts {
        self.inbound.rejects()
    }
}

/// The next authentic cursor on a non-blocking UDP `socket`, waiting in `poll(2)` up to
/// `timeout`; no allocation.
fn recv_cursor_polling(
    socket: &std::net::UdpSocket,
    inbound: &mut Inbound,
    timeout: Duration,
) -> Result<Option<(Packet, CursorSample)>, ClientError> {
    use std::os::fd::AsRawFd as _;
    let deadline = std::time::Instant::now() + timeout;
    let mut buf = [0u8; MAX_PACKET_BYTES + 1];
    loop {
        match socket.recv(&mut buf) {
            Ok(n) => {
                if let Ok(p) = inbound.accept(&buf[..n])
                    && let Body::Cursor(c) = p.body
                {
                    return Ok(Some((p, c)));
                }
                continue;
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            // ICMP errors from an earlier send surface here; the next read goes on.
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => continue,
            Err(e) => return Err(e.into()),
        }
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        if left.is_zero() {
            return Ok(None);
        }
        let mut pfd = libc::pollfd {
            fd: socket.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        let ms = i32::try_from(left.as_millis().max(1)).unwrap_or(i32::MAX);
        // SAFETY: one valid pollfd for the duration of the call.
        unsafe { libc::poll(&mut pfd, 1, ms) };
    }
}

/// The sending half of a [`HotPath`]: synchronous and non-blocking, so a force-mapping thread
/// owns it and sends without a runtime. Encoding reuses one buffer, and on QUIC each
/// datagram's `Bytes` is cut from a reused block ([`quic::DatagramArena`]): no allocation per
/// command on either transport.
pub struct HotSender {
    socket: SenderSocket,
    outbound: Outbound,
    clock: MonoClock,
    buf: [u8; MAX_PACKET_BYTES],
    last_sent: Option<(u32, u64)>,
    /// QUIC: where each datagram's `Bytes` is cut from (no allocation per datagram).
    arena: quic::DatagramArena,
}

impl std::fmt::Debug for HotSender {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HotSender")
            .field("next_sequence", &self.outbound.next_sequence())
            .finish()
    }
}

impl HotSender {
    /// Send a force command now; a full socket buffer drops it (a newer one follows, and the
    /// server's watchdog covers a gap). [`ClientError::Closed`] when a QUIC connection is gone
    /// (UDP has no connection: a vanished server shows as silence on the receiving side).
    pub fn send_force(&mut self, cmd: &ForceCommand) -> Result<(), ClientError> {
        let (sequence, now) = (self.outbound.next_sequence(), self.clock.now_ns());
        let len = self.outbound.encode(now, Body::Force(*cmd), &mut self.buf);
        self.last_sent = Some((sequence, now));
        let sent = match &self.socket {
            SenderSocket::Quic(c) => c
                .send_datagram(self.arena.bytes(&self.buf[..len]))
                .map_err(quic_send_error),
            SenderSocket::Udp(_) => self.send_raw(&self.buf[..len]),
        };
        match sent {
            Err(ClientError::Io(e)) if e.kind() == std::io::ErrorKind::WouldBlock => Ok(()),
            other => other,
        }
    }

    /// Send arbitrary bytes (tests: forged and malformed packets); a full socket buffer is an
    /// error (`WouldBlock`), not a drop.
    pub fn send_raw(&self, bytes: &[u8]) -> Result<(), ClientError> {
        match &self.socket {
            SenderSocket::Udp(s) => s.send(bytes).map(|_| ()).map_err(ClientError::Io),
            SenderSocket::Quic(c) => c
                .send_datagram(bytes::Bytes::copy_from_slice(bytes))
                .map_err(quic_send_error),
        }
    }

    /// The clock that stamps the commands.
    pub fn clock(&self) -> MonoClock {
        self.clock
    }

    /// Header `sequence` and `timestamp_ns` of the last command [`HotSender::send_force`]
    /// encoded (sent, or dropped by a full socket buffer): match them with the cursors'
    /// [`protocol::ForceAck`] to time round trips.
    pub fn last_sent(&self) -> Option<(u32, u64)> {
        self.last_sent
    }
}

fn quic_send_error(e: quinn::SendDatagramError) -> ClientError {
    match e {
        quinn::SendDatagramError::ConnectionLost(_) => ClientError::Closed,
        e => ClientError::Quic(e.to_string()),
    }
}

/// A force command with no model and zero force (the UDP stream opener).
pub fn zero_command() -> ForceCommand {
    ForceCommand {
        force: Vec3::ZERO,
        torque: None,
        answers_sequence: 0,
        answers_timestamp_ns: 0,
        model: LocalModel::default(),
    }
}

impl Client {
    /// Connect, handshake and open the hot path; see the module doc.
    pub async fn connect(cfg: &ClientConfig) -> Result<Client, ClientError> {
        tokio::time::timeout(cfg.timeout, Self::connect_inner(cfg))
            .await
            .map_err(|_| ClientError::Timeout("connect and handshake"))?
    }

    async fn connect_inner(cfg: &ClientConfig) -> Result<Client, ClientError> {
        let tls_cfg = tls::client_config(cfg.pinned_cert.clone(), cfg.identity.as_ref())?;
        let (rd, wr, conn): (Reader, Writer, Option<(quinn::Connection, quinn::Endpoint)>) =
            match cfg.transport {
                TransportKind::Udp => {
                    let tcp = tokio::net::TcpStream::connect(cfg.server).await?;
                    tcp.set_nodelay(true)?;
                    let connector = tokio_rustls::TlsConnector::from(Arc::new(tls_cfg));
                    let stream = connector.connect(tls::server_name(), tcp).await?;
                    let (rd, wr) = tokio::io::split(stream);
                    (Box::new(rd), Box::new(wr), None)
                }
                TransportKind::Quic => {
                    let crypto = quinn::crypto::rustls::QuicClientConfig::try_from(tls_cfg)
                        .map_err(|e| ClientError::Quic(e.to_string()))?;
                    let mut qc = quinn::ClientConfig::new(Arc::new(crypto));
                    qc.transport_config(Arc::new(quic::transport_config(cfg.idle_timeout)));
                    let bind: SocketAddr = if cfg.server.is_ipv4() {
                        ([0, 0, 0, 0], 0).into()
                    } else {
                        (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
                    };
                    let mut endpoint = quinn::Endpoint::client(bind)?;
                    endpoint.set_default_client_config(qc);
                    let conn = endpoint
                        .connect(cfg.server, tls::SERVER_NAME)
                        .map_err(|e| ClientError::Quic(e.to_string()))?
                        .await
                        .map_err(|e| ClientError::Quic(e.to_string()))?;
                    let (wr, rd) = conn
                        .open_bi()
                        .await
                        .map_err(|e| ClientError::Quic(e.to_string()))?;
                    (Box::new(rd), Box::new(wr), Some((conn, endpoint)))
                }
            };
        let mut control = ControlChannel {
            rd,
            wr,
            dec: FrameDecoder::new(),
            conn: conn.as_ref().map(|(c, _)| c.clone()),
        };
        control
            .send(&Control::Hello(Hello {
                protocol_version: PROTOCOL_VERSION,
                client_name: cfg.client_name.clone(),
                requested_rate_hz: cfg.requested_rate_hz,
            }))
            .await?;
        let welcome = match control.recv().await? {
            Control::Welcome(w) => w,
            Control::Error(e) => {
                if let Some((c, _)) = &conn {
                    c.close(0u8.into(), b"refused");
                }
                return Err(ClientError::Refused {
                    code: e.code,
                    message: e.message,
                });
            }
            other => {
                return Err(ClientError::Protocol(format!(
                    "expected Welcome, got {other:?}"
                )));
            }
        };
        let (rx_socket, tx_socket, key) = match conn {
            None => {
                let bind: SocketAddr = if cfg.server.is_ipv4() {
                    ([0, 0, 0, 0], 0).into()
                } else {
                    (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
                };
                let send = std::net::UdpSocket::bind(bind)?;
                send.connect(cfg.server)?;
                send.set_nonblocking(true)?;
                let recv = tokio::net::UdpSocket::from_std(send.try_clone()?)?;
                (
                    ReceiverSocket::Udp(recv),
                    SenderSocket::Udp(send),
                    Some(SessionKey::from_bytes(welcome.session_key)),
                )
            }
            Some((c, e)) => (
                ReceiverSocket::Quic(c.clone(), e),
                SenderSocket::Quic(c),
                None,
            ),
        };
        let mut hot = HotPath {
            rx: HotReceiver {
                socket: rx_socket,
                inbound: Inbound::new(welcome.session_id, key.clone()),
            },
            tx: HotSender {
                socket: tx_socket,
                outbound: Outbound::new(welcome.session_id, key.clone()),
                clock: MonoClock::new(),
                buf: [0; MAX_PACKET_BYTES],
                last_sent: None,
                arena: quic::DatagramArena::new(),
            },
            key,
            streaming: false,
        };
        if cfg.transport == TransportKind::Udp {
            hot.send_force(&zero_command())?;
        }
        Ok(Client {
            welcome,
            control,
            hot,
        })
    }
}
