//! The control conversation of one session (see the parent module's doc for the sequence):
//! `Hello` → `Welcome` or `Error`, then pings, config, emergency stops, periodic `Stats`,
//! until `Bye`, a closed channel or the idle timeout.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use protocol::control::{ClockPong, ControlError, ErrorCode, ErrorMessage, Welcome};
use protocol::{Control, FrameDecoder, PROTOCOL_VERSION, SessionKey};
use rustls::pki_types::CertificateDer;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite};

use super::{HotState, Shared, TransportError};
use crate::servo::SessionEvent;
use crate::servo::driver::ServoMsg;
pub use haptics_client::framing::{read_control, write_control};

fn error(code: ErrorCode, message: impl Into<String>) -> Control {
    Control::Error(ErrorMessage {
        code,
        message: message.into(),
    })
}

/// How a session's hot path is keyed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HotKind {
    /// UDP: MAC'd with a fresh session key.
    Udp,
    /// QUIC datagrams: no MAC (TLS protects them).
    Quic,
}

/// Run one control conversation (see the module doc). `client_cert` is the certificate the
/// client presented in the TLS handshake (its key checked there), if any. `on_start` is called
/// once the session is up (QUIC spawns its datagram reader there). Returns the session's hot
/// state, if one was started, after it ended.
pub async fn serve_control<R, W>(
    shared: &Arc<Shared>,
    rd: &mut R,
    wr: &mut W,
    kind: HotKind,
    client_cert: Option<&CertificateDer<'_>>,
    on_start: impl FnOnce(Arc<HotState>),
) -> Result<Option<Arc<HotState>>, TransportError>
where
    R: AsyncRead + Unpin,
    W: AsyncWrite + Unpin,
{
    let mut dec = FrameDecoder::new();
    let hello =
        match tokio::time::timeout(shared.net.hello_timeout, read_control(rd, &mut dec)).await {
            Err(_) => return Err(TransportError::Timeout("Hello")),
            Ok(Err(TransportError::Control(e))) => {
                write_control(wr, &error(ErrorCode::InvalidMessage, e.to_string())).await?;
                return Err(e.into());
            }
            Ok(r) => r?,
        };
    let hello = match hello {
        Some(Control::Hello(h)) => h,
        None => return Ok(None),
        Some(other) => {
            let msg = format!("expected Hello, got {}", name(&other));
            write_control(wr, &error(ErrorCode::UnexpectedMessage, msg)).await?;
            return Ok(None);
        }
    };
    if hello.protocol_version != PROTOCOL_VERSION {
        let msg = format!(
            "server speaks protocol version {PROTOCOL_VERSION}, client {}",
            hello.protocol_version
        );
        write_control(wr, &error(ErrorCode::VersionMismatch, msg)).await?;
        return Ok(None);
    }
    if !client_cert.is_some_and(|c| shared.authorized.contains(c)) {
        shared
            .refused_unauthenticated
            .fetch_add(1, Ordering::Relaxed);
        let msg = match client_cert {
            None => "no client certificate: the server accepts only workstations listed in its \
                     authorized clients (network.authorized_clients); give the workstation \
                     --client-cert/--client-key"
                .to_string(),
            Some(c) => format!(
                "client certificate {} is not authorized: append the workstation's client.pem \
                 to the server's authorized clients file (network.authorized_clients)",
                crate::tls::fingerprint(c)
            ),
        };
        tracing::warn!(client = %hello.client_name, "refused: {msg}");
        write_control(wr, &error(ErrorCode::Unauthenticated, msg)).await?;
        return Ok(None);
    }
    let key = match kind {
        HotKind::Udp => {
            let mut k = [0u8; 32];
            getrandom::fill(&mut k).map_err(|e| std::io::Error::other(e.to_string()))?;
            Some(SessionKey::from_bytes(k))
        }
        HotKind::Quic => None,
    };
    let Some(hot) = shared.claim(key.clone()) else {
        shared.refused_busy.fetch_add(1, Ordering::Relaxed);
        tracing::warn!(client = %hello.client_name, "refused: another workstation holds the session");
        let msg = "busy: another workstation holds the session; one at a time";
        write_control(wr, &error(ErrorCode::Busy, msg)).await?;
        return Ok(None);
    };
    let d = &shared.device;
    let welcome = Welcome {
        protocol_version: PROTOCOL_VERSION,
        device_name: d.name.chars().take(100).collect(),
        dof_input: d.dof_input,
        dof_output: d.dof_output,
        workspace_min: d.workspace_min.to_array(),
        workspace_max: d.workspace_max.to_array(),
        max_force_n: shared.max_force_n,
        max_stiffness_n_per_m: d.max_stiffness_n_per_m,
        servo_rate_hz: shared.servo_rate_hz,
        session_id: hot.session,
        session_key: key.as_ref().map_or([0; 32], |k| *k.as_bytes()),
    };
    shared.sessions_started.fetch_add(1, Ordering::Relaxed);
    shared.servo(ServoMsg::Start {
        session: hot.session,
        key,
    });
    tracing::info!(client = %hello.client_name, session = format_args!("{:#010x}", hot.session), "session started");
    let result = async {
        write_control(wr, &Control::Welcome(welcome)).await?;
        on_start(Arc::clone(&hot));
        session_loop(shared, rd, wr, &hot, dec).await
    }
    .await;
    let s = shared.stats(Some(&hot));
    shared.release(&hot);
    let rejected: Vec<_> = s.rejected.nonzero().collect();
    match &result {
        Ok(reason) => tracing::info!(
            session = format_args!("{:#010x}", hot.session),
            packets_in = s.packets_in,
            packets_out = s.packets_out,
            ?rejected,
            "session ended: {reason}"
        ),
        Err(e) => tracing::warn!(
            session = format_args!("{:#010x}", hot.session),
            packets_in = s.packets_in,
            ?rejected,
            "session ended: {e}"
        ),
    }
    result.map(|_| Some(hot))
}

async fn session_loop<R, W>(
    shared: &Arc<Shared>,
    rd: &mut R,
    wr: &mut W,
    hot: &Arc<HotState>,
    mut dec: FrameDecoder,
) -> Result<String, TransportError>
where
    R: AsyncRead + Unpin,
    W: AsyncWrite + Unpin,
{
    let mut buf = [0u8; 4096];
    let mut check = tokio::time::interval(Duration::from_millis(20));
    let mut last_stats = tokio::time::Instant::now();
    let mut rejected_logged = 0u64;
    loop {
        loop {
            let msg = match dec.next_message() {
                Ok(Some(m)) => m,
                Ok(None) => break,
                Err(e @ ControlError::FrameTooLarge { .. }) => return Err(e.into()),
                Err(e) => {
                    write_control(wr, &error(ErrorCode::InvalidMessage, e.to_string())).await?;
                    continue;
                }
            };
            let t1 = shared.clock.now_ns();
            hot.last_activity_ns.store(t1, Ordering::Release);
            match msg {
                Control::ClockPing(p) => {
                    let pong = ClockPong {
                        id: p.id,
                        t0_ns: p.t0_ns,
                        t1_ns: t1,
                        t2_ns: shared.clock.now_ns(),
                    };
                    write_control(wr, &Control::ClockPong(pong)).await?;
                }
                Control::Config(c) => shared.servo(ServoMsg::Core(SessionEvent::Config(c))),
                Control::EmergencyStop(e) => {
                    tracing::warn!(engage = e.engage, "emergency stop from the workstation");
                    shared.servo(ServoMsg::Core(SessionEvent::EmergencyStop(e.engage)));
                }
                Control::Bye(b) => return Ok(format!("bye from client: {}", b.reason)),
                other => {
                    let msg = format!("{} is not expected during a session", name(&other));
                    write_control(wr, &error(ErrorCode::UnexpectedMessage, msg)).await?;
                }
            }
        }
        tokio::select! {
            n = rd.read(&mut buf) => {
                let n = n?;
                if n == 0 {
                    return Ok("control channel closed by the client".into());
                }
                dec.push(&buf[..n]);
            }
            _ = check.tick() => {
                let idle = shared.clock.now_ns().saturating_sub(shared.last_activity_ns(hot));
                if idle > u64::try_from(shared.net.idle_timeout.as_nanos()).unwrap_or(u64::MAX) {
                    let reason = format!("idle timeout: nothing from the workstation for {} ms", idle / 1_000_000);
                    let bye = Control::Bye(protocol::control::Bye { reason: reason.clone() });
                    let _ = tokio::time::timeout(Duration::from_millis(200), write_control(wr, &bye)).await;
                    return Ok(reason);
                }
                if last_stats.elapsed() >= shared.net.stats_interval {
                    last_stats = tokio::time::Instant::now();
                    let stats = shared.stats(Some(hot));
                    if stats.rejected.total() > rejected_logged {
                        rejected_logged = stats.rejected.total();
                        let by_reason: Vec<_> = stats.rejected.nonzero().collect();
                        tracing::warn!(?by_reason, "hot-path packets rejected so far (none reached the device)");
                    }
                    tracing::debug!(packets_in = stats.packets_in, packets_out = stats.packets_out, ticks = stats.ticks, "session stats");
                    write_control(wr, &Control::Stats(stats)).await?;
                }
            }
        }
    }
}

fn name(msg: &Control) -> &'static str {
    match msg {
        Control::Hello(_) => "Hello",
        Control::Welcome(_) => "Welcome",
        Control::ClockPing(_) => "ClockPing",
        Control::ClockPong(_) => "ClockPong",
        Control::Config(_) => "Config",
        Control::Stats(_) => "Stats",
        Control::EmergencyStop(_) => "EmergencyStop",
        Control::Bye(_) => "Bye",
        Control::Error(_) => "Error",
    }
}
