//! The network side: a tokio runtime on its own thread that keeps one session with the server.
//!
//! Connect through `haptics-client` with the pinned certificate and the workstation's client
//! identity (handshake, `Welcome`; an unauthorized identity stops the workstation with the
//! server's reason instead of retrying), wait for
//! the first cursor (the UDP opener is re-sent until it arrives), split the hot path and hand
//! it to the force thread ([`HotLink`]): on UDP the sender and the socket itself, which the
//! force thread waits on (one wake-up from a cursor's arrival to its answer; this task no longer
//! sees cursors and watches their silence through `NetStats::last_cursor_ns`); on QUIC this
//! thread answers every cursor quinn delivers itself ([`Answer::Inline`]: quinn's drivers run
//! on its runtime, so the cursor's arrival and the command's departure wake this thread alone). Then, concurrently: a `ClockPing` every 100 ms feeds
//! a [`ClockEstimator`] (offset and its bound in [`NetStats`]); the
//! server's periodic `Stats` give the cursor → force round trip it measured. When the session
//! ends (server gone or restarted, connection lost, no cursor for [`CURSOR_SILENCE`]) the force
//! thread is told to drop its sender and the loop reconnects with backoff (100 ms doubling to
//! 2 s; reset after a session that lasted) until the workstation stops; then it says `Bye`.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::Thread;
use std::time::{Duration, Instant};

use haptics_client::client::ClientError;
use haptics_client::tls::Identity;
use haptics_client::{Client, ClientConfig, TransportKind};
use protocol::control::{ClockPing, ErrorCode, Stats};
use protocol::{ClockEstimator, ClockSample, Control};
use rustls::pki_types::CertificateDer;

use super::force::{ForceLoop, HotLink};
use super::shared::{CursorMsg, NetStats, PercentilesUs, Shared};

/// A session whose cursor stream stops this long is over (the server streams at 1 kHz; UDP
/// has no connection to notice a vanished peer).
pub const CURSOR_SILENCE: Duration = Duration::from_millis(500);

/// Where and how to connect.
#[derive(Debug, Clone)]
pub struct NetConfig {
    /// The server.
    pub server: SocketAddr,
    /// Transport.
    pub transport: TransportKind,
    /// The server's certificate, pinned.
    pub cert: CertificateDer<'static>,
    /// The workstation's client certificate and key, which the server must authorize.
    pub identity: Option<Identity>,
}

impl NetConfig {
    /// From the `--server`, `--cert` and `--transport` flags: `None` without `--server`;
    /// `--server` without `--cert` is an error naming both. The client identity is the one next
    /// to the certificate ([`client_identity`]).
    pub fn from_flags(
        server: Option<SocketAddr>,
        cert: Option<&std::path::Path>,
        transport: TransportKind,
    ) -> anyhow::Result<Option<Self>> {
        match (server, cert) {
            (Some(server), Some(cert)) => Ok(Some(Self {
                server,
                transport,
                cert: haptics_client::tls::read_cert(cert)?,
                identity: client_identity(cert, None, None)?,
            })),
            (Some(_), None) => anyhow::bail!("--server needs --cert (the server's certificate)"),
            (None, _) => Ok(None),
        }
    }
}

#[cfg(feature = "demo-server")]
impl NetConfig {
    /// The connection to a server started in this process (`demo`, `latency`): its address,
    /// certificate and the client identity it created for this machine.
    pub fn to_in_process(
        server: &haptics_server::server::Server,
        transport: TransportKind,
    ) -> Self {
        Self {
            server: server.local_addr(),
            transport,
            cert: server.certificate(),
            identity: server.local_client(),
        }
    }
}

/// The workstation's side of the connection as a file (`workstation run --config FILE`,
/// `workstation latency --config FILE`); flags given on the command line override it.
///
/// ```toml
/// [server]
/// address = "192.168.10.2:7700"   # the haptics PC
/// transport = "udp"               # must match the server's network.transport
/// cert = "server-cert.pem"        # the server's certificate, pinned
/// client_cert = "client.pem"      # this workstation's identity, listed in the server's
/// client_key = "client.key"       #   network.authorized_clients
/// ```
///
/// Relative paths are relative to the file. Unknown fields are errors.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConnectionFile {
    /// `[server]`.
    pub server: ServerSection,
}

/// `[server]` of a [`ConnectionFile`].
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServerSection {
    /// host:port of the haptics server.
    pub address: SocketAddr,
    /// `udp` (default) or `quic`.
    #[serde(default = "udp")]
    pub transport: TransportKind,
    /// The server's certificate (PEM), pinned.
    pub cert: std::path::PathBuf,
    /// This workstation's client certificate (PEM) [default: client.pem next to `cert`].
    pub client_cert: Option<std::path::PathBuf>,
    /// Its private key (PEM) [default: client.key next to `cert`].
    pub client_key: Option<std::path::PathBuf>,
}

fn udp() -> TransportKind {
    TransportKind::Udp
}

impl ConnectionFile {
    /// Read and check `path`; errors name the file and the field.
    pub fn load(path: &std::path::Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        let mut file: Self =
            toml::from_str(&text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        let dir = path.parent().unwrap_or(std::path::Path::new("."));
        let s = &mut file.server;
        for p in [
            Some(&mut s.cert),
            s.client_cert.as_mut(),
            s.client_key.as_mut(),
        ]
        .into_iter()
        .flatten()
        {
            if p.is_relative() {
                *p = dir.join(&*p);
            }
        }
        if s.client_cert.is_some() != s.client_key.is_some() {
            anyhow::bail!(
                "{}: server.client_cert and server.client_key go together (give both or neither)",
                path.display()
            );
        }
        Ok(file)
    }
}

/// The connection flags `workstation run` and `workstation latency` share; a flag wins over
/// the `--config` file.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct ConnectArgs {
    /// The connection as a TOML file (`[server]` address, transport, cert, client_cert,
    /// client_key; see deploy/examples/lab-workstation.toml); flags override it.
    #[arg(long, value_name = "FILE")]
    pub config: Option<std::path::PathBuf>,
    /// The haptics server (host:port), unless --config gives it.
    #[arg(long, value_name = "ADDR")]
    pub server: Option<SocketAddr>,
    /// Transport; must match the server's [default: udp].
    #[arg(long, value_enum)]
    pub transport: Option<TransportKind>,
    /// The server's certificate (PEM), pinned: copy it from the haptics PC
    /// (`haptics-server gen-cert` prints where it is); required with --server.
    #[arg(long, value_name = "FILE")]
    pub cert: Option<std::path::PathBuf>,
    /// The workstation's client certificate (PEM), listed in the server's authorized clients
    /// [default: client.pem next to --cert, where a local server creates it].
    #[arg(long, value_name = "FILE", requires = "client_key")]
    pub client_cert: Option<std::path::PathBuf>,
    /// The client certificate's private key (PEM) [default: client.key next to --cert].
    #[arg(long, value_name = "FILE", requires = "client_cert")]
    pub client_key: Option<std::path::PathBuf>,
}

impl ConnectArgs {
    /// Where to connect: `None` when neither the flags nor the file name a server.
    pub fn resolve(&self) -> anyhow::Result<Option<NetConfig>> {
        let file = self
            .config
            .as_deref()
            .map(ConnectionFile::load)
            .transpose()?
            .map(|f| f.server);
        let Some(server) = self.server.or(file.as_ref().map(|f| f.address)) else {
            return Ok(None);
        };
        let transport = self
            .transport
            .or(file.as_ref().map(|f| f.transport))
            .unwrap_or(TransportKind::Udp);
        let cert = self
            .cert
            .clone()
            .or(file.as_ref().map(|f| f.cert.clone()))
            .ok_or_else(|| {
                anyhow::anyhow!("--server needs --cert (the server's certificate) or --config")
            })?;
        let (cc, ck) = match (&self.client_cert, &self.client_key) {
            (Some(c), Some(k)) => (Some(c.clone()), Some(k.clone())),
            _ => (
                file.as_ref().and_then(|f| f.client_cert.clone()),
                file.as_ref().and_then(|f| f.client_key.clone()),
            ),
        };
        Ok(Some(NetConfig {
            server,
            transport,
            cert: haptics_client::tls::read_cert(&cert)?,
            identity: client_identity(&cert, cc.as_deref(), ck.as_deref())?,
        }))
    }
}

/// The workstation's client identity: `client_cert` and `client_key` when given (both or
/// neither), else `client.pem`/`client.key` next to the server's certificate (where a server on
/// this machine creates them on first start), else none (the server will refuse the session
/// and say so).
pub fn client_identity(
    server_cert: &std::path::Path,
    client_cert: Option<&std::path::Path>,
    client_key: Option<&std::path::Path>,
) -> anyhow::Result<Option<Identity>> {
    let pair = match (client_cert, client_key) {
        (Some(c), Some(k)) => Some((c.to_path_buf(), k.to_path_buf())),
        (None, None) => haptics_client::tls::identity_beside(server_cert),
        _ => anyhow::bail!("--client-cert and --client-key go together (give both or neither)"),
    };
    match pair {
        Some((c, k)) => Ok(Some(haptics_client::tls::read_identity(&c, &k)?)),
        None => {
            tracing::warn!(
                "no client identity (--client-cert/--client-key, or client.pem/client.key next to {}): the server will refuse the session",
                server_cert.display()
            );
            Ok(None)
        }
    }
}

/// The ends of the network side's hand-offs.
#[derive(Debug)]
pub struct NetPorts {
    /// Who answers the cursors.
    pub answer: Answer,
}

/// Who answers the session's cursors.
#[derive(Debug)]
pub enum Answer {
    /// The force-mapping thread: on UDP it waits on the session's socket itself (handed over in
    /// a [`HotLink`]); cursors this thread receives (the first one) go through its ring.
    Thread {
        /// Cursors to the force thread.
        cursors: rtrb::Producer<CursorMsg>,
        /// A hot path per session to the force thread, `None` when the session ended.
        senders: rtrb::Producer<Option<HotLink>>,
        /// The force thread, unparked on every cursor.
        force_thread: Thread,
    },
    /// This thread (QUIC): quinn's drivers run on this thread's runtime, so a cursor is
    /// answered where it arrives, one thread woken per direction on the workstation (through a
    /// force thread it was three: this runtime, the force thread, this runtime again to send).
    /// The thread then runs at the force thread's priority.
    Inline(Box<ForceLoop>),
}

impl Answer {
    /// The session ended: nothing more goes to it.
    fn end_session(&mut self) {
        match self {
            Answer::Thread { senders, .. } => {
                let _ = senders.push(None);
            }
            Answer::Inline(force) => force.set_session(None),
        }
    }
}

/// The thread body.
pub fn run(cfg: NetConfig, mut ports: NetPorts, shared: Arc<Shared>) {
    if matches!(ports.answer, Answer::Inline(_)) {
        let priority = super::force::raise_priority();
        tracing::info!(priority, "network thread maps forces itself (QUIC)");
    }
    let rt = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            tracing::error!("cannot start the network runtime: {e}");
            shared.request_stop();
            return;
        }
    };
    rt.block_on(async move {
        let mut backoff = Duration::from_millis(100);
        let mut said: Option<String> = None;
        while !shared.stopping() {
            let mut ccfg = ClientConfig::new(cfg.server, cfg.transport, cfg.cert.clone());
            ccfg.identity = cfg.identity.clone();
            ccfg.client_name = format!("workstation {}", std::process::id());
            match Client::connect(&ccfg).await {
                Ok(client) => {
                    let began = Instant::now();
                    shared.net.connect_error.store(None);
                    said = None;
                    shared.net.sessions.fetch_add(1, Ordering::Relaxed);
                    tracing::info!(
                        server = %cfg.server,
                        device = %client.welcome.device_name,
                        session = client.welcome.session_id,
                        "session up"
                    );
                    let result = session(client, &mut ports, &shared).await;
                    shared.net.connected.store(false, Ordering::Release);
                    // The force loop drops its sender: nothing more goes to a dead session.
                    ports.answer.end_session();
                    match result {
                        Ok(()) => tracing::info!("session closed"),
                        Err(e) => {
                            tracing::warn!("session lost: {e}; reconnecting");
                            // Back off unless the session had been healthy for a while, so a
                            // session that fails right after its handshake cannot spin.
                            if began.elapsed() > Duration::from_secs(2) {
                                backoff = Duration::from_millis(100);
                            }
                            tokio::time::sleep(backoff).await;
                            backoff = (backoff * 2).min(Duration::from_secs(2));
                        }
                    }
                }
                Err(ClientError::Refused {
                    code: ErrorCode::Unauthenticated,
                    message,
                }) => {
                    // Retrying cannot help: the server's list or our identity must change.
                    let reason = format!(
                        "{}: the server refused this workstation: {message}",
                        cfg.server
                    );
                    tracing::error!("{reason}");
                    shared.net.connect_error.store(Some(Arc::new(reason)));
                    shared.request_stop();
                    return;
                }
                Err(e) => {
                    let reason = format!("{}: {}", cfg.server, why_not_connected(&e));
                    // Said on the console when the reason changes, not at every retry.
                    if said.as_deref() != Some(reason.as_str()) {
                        tracing::warn!("cannot connect to {reason}; retrying");
                        said = Some(reason.clone());
                    }
                    shared.net.connect_error.store(Some(Arc::new(reason)));
                    tokio::time::sleep(backoff).await;
                    backoff = (backoff * 2).min(Duration::from_secs(2));
                }
            }
        }
    });
}

/// A connection attempt's failure in the words a person at the workstation needs: what is
/// wrong and what to do about it.
pub fn why_not_connected(e: &ClientError) -> String {
    use std::io::ErrorKind;
    let io_kind = |e: &ClientError| match e {
        ClientError::Io(io) => Some(io.kind()),
        ClientError::Transport(haptics_client::framing::TransportError::Io(io)) => Some(io.kind()),
        _ => None,
    };
    let text = e.to_string();
    match e {
        _ if text.contains("does not match the pinned certificate") => {
            format!("certificate mismatch: {text}")
        }
        ClientError::Refused { code, message } => match code {
            ErrorCode::Unauthenticated => format!(
                "unauthenticated: {message} (add this workstation's client certificate to the \
                 server's authorized_clients)"
            ),
            ErrorCode::Busy => format!("busy: another workstation holds the session ({message})"),
            ErrorCode::VersionMismatch => format!(
                "protocol version mismatch: {message} (update the older of server and \
                 workstation)"
            ),
            _ => format!("refused ({code:?}): {message}"),
        },
        ClientError::Timeout(what) => format!("timed out waiting for {what}"),
        _ if matches!(io_kind(e), Some(ErrorKind::ConnectionRefused)) => {
            "connection refused: no haptics server is listening there".to_owned()
        }
        _ if matches!(io_kind(e), Some(ErrorKind::TimedOut)) => "timed out".to_owned(),
        _ => text,
    }
}

async fn session(client: Client, ports: &mut NetPorts, shared: &Shared) -> Result<(), ClientError> {
    let Client {
        mut control,
        mut hot,
        ..
    } = client;
    let clock = hot.clock();
    let first = tokio::time::timeout(Duration::from_secs(3), hot.recv_cursor())
        .await
        .map_err(|_| ClientError::Timeout("the first cursor sample"))??;
    let (rx, sender) = hot.split();
    // UDP: the force thread waits on the socket; QUIC: cursors come through this task, and
    // are answered here (`Answer::Inline`) or by the force thread.
    let (mut rx, receiver) = if rx.is_udp() {
        (None, Some(rx.into_blocking()?))
    } else {
        (Some(rx), None)
    };
    shared
        .net
        .last_cursor_ns
        .store(clock.now_ns(), Ordering::Relaxed);
    match &mut ports.answer {
        Answer::Thread { senders, .. } => {
            // One link per session; the ring has room for a few (the force thread takes them
            // at once).
            if senders.push(Some(HotLink { sender, receiver })).is_err() {
                return Err(ClientError::Protocol(
                    "force thread not taking senders".into(),
                ));
            }
        }
        Answer::Inline(force) => force.set_session(Some(sender)),
    }
    shared.net.connected.store(true, Ordering::Release);
    answer(
        ports,
        shared,
        CursorMsg::new(&first.0, first.1, Instant::now()),
    );
    let mut estimator = ClockEstimator::new(200.0);
    let mut ping = tokio::time::interval(Duration::from_millis(100));
    let mut ping_id = 0u32;
    loop {
        if shared.stopping() {
            let _ = control.close("workstation stopping").await;
            return Ok(());
        }
        let silent = || ClientError::Timeout("cursor samples (the server went silent)");
        tokio::select! {
            r = async {
                match &mut rx {
                    Some(rx) => Some(tokio::time::timeout(CURSOR_SILENCE, rx.recv_cursor()).await),
                    None => std::future::pending().await,
                }
            } => {
                let (packet, cursor) = r.expect("pending without a receiver").map_err(|_| silent())??;
                shared.net.last_cursor_ns.store(clock.now_ns(), Ordering::Relaxed);
                shared.net.applied.on_cursor(&cursor);
                answer(ports, shared, CursorMsg::new(&packet, cursor, Instant::now()));
            }
            msg = control.recv() => match msg? {
                Control::ClockPong(p) => {
                    let sample = ClockSample { t0_ns: p.t0_ns, t1_ns: p.t1_ns, t2_ns: p.t2_ns, t3_ns: clock.now_ns() };
                    if estimator.add(sample).is_ok() && let Some(e) = estimator.estimate() {
                        shared.net.clock_offset_ns.set(e.offset_ns as f64);
                        shared.net.clock_uncertainty_ns.set(e.uncertainty_ns as f64);
                        shared.net.ping_rtt_ns.store(e.rtt_ns, Ordering::Relaxed);
                    }
                }
                Control::Stats(s) => record_stats(&shared.net, &s),
                Control::Bye(b) => {
                    tracing::info!("server said bye: {}", b.reason);
                    return Err(ClientError::Closed);
                }
                Control::Error(e) => {
                    return Err(ClientError::Refused { code: e.code, message: e.message });
                }
                _ => {}
            },
            _ = ping.tick() => {
                let last = shared.net.last_cursor_ns.load(Ordering::Relaxed);
                if clock.now_ns().saturating_sub(last) > CURSOR_SILENCE.as_nanos() as u64 {
                    return Err(silent());
                }
                ping_id = ping_id.wrapping_add(1);
                control.send(&Control::ClockPing(ClockPing { id: ping_id, t0_ns: clock.now_ns() })).await?;
            }
        }
    }
}

/// A cursor this thread received: mapped here, or handed to the force thread.
fn answer(ports: &mut NetPorts, shared: &Shared, msg: CursorMsg) {
    shared.net.cursors.fetch_add(1, Ordering::Relaxed);
    match &mut ports.answer {
        Answer::Thread {
            cursors,
            force_thread,
            ..
        } => {
            if cursors.push(msg).is_err() {
                shared.net.cursors_dropped.fetch_add(1, Ordering::Relaxed);
            }
            force_thread.unpark();
        }
        Answer::Inline(force) => force.step(msg, 0, shared),
    }
}

fn record_stats(net: &NetStats, s: &Stats) {
    let us = |ns: u64| ns as f64 / 1e3;
    let p = |x: &protocol::control::Percentiles| PercentilesUs {
        p50: us(x.p50),
        p99: us(x.p99),
        p999: us(x.p999),
        max: us(x.max),
    };
    net.force_rtt_us.set(p(&s.force_rtt_ns));
    net.server_period_p99_us.set(us(s.period_ns.p99));
    let [ticks, uptime] = &net.server_ticks;
    let (t0, u0) = (
        ticks.swap(s.ticks, Ordering::Relaxed),
        uptime.swap(s.uptime_ns, Ordering::Relaxed),
    );
    if s.uptime_ns > u0 && s.ticks >= t0 && u0 > 0 {
        net.servo_hz
            .set((s.ticks - t0) as f64 / ((s.uptime_ns - u0) as f64 * 1e-9));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn connection_files_resolve_relative_paths_and_name_bad_fields() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ws.toml");
        std::fs::write(
            &path,
            "[server]\naddress = \"10.0.0.2:7700\"\ntransport = \"quic\"\ncert = \"s.pem\"\n\
             client_cert = \"/etc/c.pem\"\nclient_key = \"c.key\"\n",
        )
        .unwrap();
        let f = ConnectionFile::load(&path).unwrap();
        assert_eq!(f.server.address, "10.0.0.2:7700".parse().unwrap());
        assert_eq!(f.server.transport, TransportKind::Quic);
        assert_eq!(f.server.cert, dir.path().join("s.pem"));
        assert_eq!(
            f.server.client_cert.as_deref(),
            Some(std::path::Path::new("/etc/c.pem"))
        );
        assert_eq!(f.server.client_key, Some(dir.path().join("c.key")));
        for (text, want) in [
            ("[server]\naddress = \"x\"\ncert = \"a\"\n", "address"),
            (
                "[server]\naddress = \"1.2.3.4:5\"\ncert = \"a\"\nport = 3\n",
                "port",
            ),
            (
                "[server]\naddress = \"1.2.3.4:5\"\ncert = \"a\"\nclient_cert = \"c\"\n",
                "server.client_key",
            ),
        ] {
            std::fs::write(&path, text).unwrap();
            let e = ConnectionFile::load(&path).unwrap_err().to_string();
            assert!(e.contains("ws.toml") && e.contains(want), "{e}");
        }
        // Flags win over the file; with neither naming a server there is nothing to connect.
        assert!(ConnectArgs::default().resolve().unwrap().is_none());
        let e = ConnectArgs {
            server: Some("1.2.3.4:5".parse().unwrap()),
            ..ConnectArgs::default()
        }
        .resolve()
        .unwrap_err()
        .to_string();
        assert!(e.contains("--cert"), "{e}");
    }
}
