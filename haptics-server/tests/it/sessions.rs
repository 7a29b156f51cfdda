//! One session at a time; a vanished or restarted workstation is survived.

use std::time::Duration;

use glam::Vec3;
use haptics_server::client::{Client, ClientError};
use haptics_server::server::TransportKind;
use protocol::control::ErrorCode;

use crate::common::{config, connect, constant, eventually, server, stream, stream_until};

async fn second_client_is_refused_then_restart_survived(kind: TransportKind) {
    let (server, monitor) = server(kind, Duration::from_millis(600));
    let mut a = connect(&server, kind).await;
    stream(&mut a, 50, |_| constant(Vec3::ZERO, (0, 0))).await;
    // Keep A streaming while B tries, so A is never idle, however slow the handshake is.
    let (stop, mut stopped) = tokio::sync::watch::channel(false);
    let keep = tokio::spawn(async move {
        while !*stopped.borrow_and_update() {
            stream(&mut a, 1, |_| constant(Vec3::ZERO, (0, 0))).await;
        }
        a
    });
    match Client::connect(&config(&server, kind)).await {
        Err(ClientError::Refused {
            code: ErrorCode::Busy,
            message,
        }) => assert!(message.contains("busy"), "{message}"),
        other => panic!("expected Busy, got {other:?}"),
    }
    stop.send(true).unwrap();
    let mut a = keep.await.unwrap();
    assert_eq!(server.refused_busy(), 1);
    stream(&mut a, 50, |_| constant(Vec3::ZERO, (0, 0))).await;

    // The workstation crashes (sockets dropped without Bye): a new one connects.
    drop(a);
    eventually("crashed session dropped", || {
        server.active_session().is_none()
    })
    .await;
    let mut b = connect(&server, kind).await;
    let f = Vec3::new(0.0, 0.2, 0.0);
    let at_device = |_: &protocol::CursorSample| (monitor.last_force() - f).length() < 1e-5;
    stream_until(
        &mut b,
        "force from the new session",
        |_| constant(f, (0, 0)),
        at_device,
    )
    .await;

    // The workstation hangs (control open, hot path silent): the watchdog fades the force,
    // the idle timeout ends the session, and a third client gets in.
    let hung = b;
    eventually("watchdog fades to zero", || {
        monitor.last_force() == Vec3::ZERO
    })
    .await;
    eventually("idle session dropped", || server.active_session().is_none()).await;
    let mut c = connect(&server, kind).await;
    stream(&mut c, 20, |_| constant(Vec3::ZERO, (0, 0))).await;
    assert_eq!(server.sessions_started(), 3);
    assert!(server.servo_stats().watchdog_fades >= 1);
    drop(hung);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn udp_one_session_at_a_time_and_restart() {
    second_client_is_refused_then_restart_survived(TransportKind::Udp).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn quic_one_session_at_a_time_and_restart() {
    second_client_is_refused_then_restart_survived(TransportKind::Quic).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_wrong_pinned_certificate_is_refused() {
    for kind in [TransportKind::Udp, TransportKind::Quic] {
        let (server, _m) = server(kind, Duration::from_secs(5));
        let mut cfg = config(&server, kind);
        cfg.pinned_cert = haptics_server::tls::generate().unwrap().cert;
        assert!(Client::connect(&cfg).await.is_err(), "{kind:?}");
        assert_eq!(server.sessions_started(), 0);
    }
}

/// A server that shut down frees its port at once, with a session up: a new one binds the
/// same address.
#[test]
fn a_shut_down_server_frees_its_port() {
    let rt = tokio::runtime::Runtime::new().unwrap();
    use haptics_server::server::{Server, ServerOptions};
    let port = {
        let s = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        s.local_addr().unwrap().port()
    };
    for kind in [TransportKind::Udp, TransportKind::Quic] {
        let mut opts = ServerOptions::for_tests(kind).unwrap();
        opts.listen = std::net::SocketAddr::from(([127, 0, 0, 1], port));
        let dev = || {
            haptics_server::device::fake::FakeDevice::new(
                haptics_server::device::fake::FakeParams::default(),
            )
        };
        let first = Server::start(dev(), opts.clone()).unwrap();
        let _client = rt.block_on(async {
            let mut client = connect(&first, kind).await;
            tokio::time::timeout(Duration::from_secs(20), client.hot.recv_cursor())
                .await
                .unwrap()
                .unwrap();
            client
        });
        first.shutdown();
        let second = Server::start(dev(), opts)
            .unwrap_or_else(|e| panic!("{kind:?}: the port is not free again: {e}"));
        second.shutdown();
    }
}
