//! Forged, replayed and malformed input is counted by reason and never reaches the device.

use std::time::Duration;

use glam::Vec3;
use haptics_server::server::TransportKind;
use protocol::packet::{MAX_PACKET_BYTES, Packet};
use protocol::{Body, Control, Outbound, Reject, SessionKey};

use crate::common::{connect, constant, eventually, server};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn udp_forged_and_malformed_packets_are_counted_and_ignored() {
    let (server, monitor) = server(TransportKind::Udp, Duration::from_secs(120));
    let mut client = connect(&server, TransportKind::Udp).await;
    // Wait for the stream to open (the server has our address, opener seq 0 accepted).
    tokio::time::timeout(Duration::from_secs(20), client.hot.recv_cursor())
        .await
        .unwrap()
        .unwrap();
    let session = client.welcome.session_id;
    let key = client.hot.session_key().unwrap().clone();
    let big = Body::Force(constant(Vec3::new(3.0, 0.0, 0.0), (0, 0)));
    let mut buf = [0u8; MAX_PACKET_BYTES];
    let mut sealed = |out: &mut Outbound, body: Body| {
        let n = out.encode(1, body, &mut buf);
        buf[..n].to_vec()
    };

    let send = |bytes: &[u8]| client.hot.send_raw(bytes).unwrap();
    // Bad MAC: sealed with another key.
    send(&sealed(
        &mut Outbound::new(session, Some(SessionKey::from_bytes([7; 32]))),
        big,
    ));
    // Wrong session: right key, other session id.
    send(&sealed(
        &mut Outbound::new(session ^ 1, Some(key.clone())),
        big,
    ));
    // Replayed: sequence 0 was the client's opener.
    send(&sealed(&mut Outbound::new(session, Some(key.clone())), big));
    // A valid packet whose MAC was broken in transit.
    let mut forged = sealed(&mut Outbound::new(session, Some(key.clone())), big);
    forged[30] ^= 0x40;
    send(&forged);
    // Non-finite and out-of-range values, correctly sealed.
    for (seq, force) in [
        (10_000u32, Vec3::new(f32::NAN, 0.0, 0.0)),
        (10_001, Vec3::new(5_000.0, 0.0, 0.0)),
    ] {
        let p = Packet {
            session,
            sequence: seq,
            timestamp_ns: 1,
            body: Body::Force(constant(force, (0, 0))),
        };
        let n = p.encode(&mut buf);
        let tag = key.tag(&buf[..n]);
        let mut v = buf[..n].to_vec();
        v.extend_from_slice(&tag);
        send(&v);
    }
    // Malformed: truncated, foreign, oversized.
    send(b"HP\x01\x02");
    send(b"GET / HTTP/1.1\r\n\r\n");
    send(&[0x48; MAX_PACKET_BYTES + 1]);

    let want = [
        (Reject::BadMac, 2),
        (Reject::UnknownSession, 1),
        (Reject::Replayed, 1),
        (Reject::NonFinite, 1),
        (Reject::OutOfRange, 1),
        (Reject::Truncated, 1),
        (Reject::BadMagic, 1),
        (Reject::TrailingBytes, 1),
    ];
    eventually("every forged packet counted", || {
        let r = server.stats().rejected;
        let done = want.iter().all(|&(reason, n)| r.get(reason) == n);
        if !done {
            let st = server.stats();
            eprintln!(
                "so far: {:?} in {} seq {:?} next {}",
                r.nonzero().collect::<Vec<_>>(),
                st.packets_in,
                st.force_sequence,
                client.hot.next_sequence()
            );
        }
        done
    })
    .await;
    assert_eq!(server.stats().rejected.total(), 9);
    // None of them moved the device (only the zero opener was ever accepted).
    tokio::time::sleep(Duration::from_millis(100)).await;
    assert_eq!(monitor.nonzero_writes(), 0);
    assert_eq!(monitor.nonfinite_writes(), 0);
    assert_eq!(server.stats().packets_in, 1, "only the opener was accepted");

    // A malformed control frame is answered with an error; the session survives.
    client
        .control
        .send_raw(&[3, 0, 0, 0, 0xff, 0xff, 0xff])
        .await
        .unwrap();
    loop {
        match tokio::time::timeout(Duration::from_secs(20), client.control.recv())
            .await
            .unwrap()
            .unwrap()
        {
            Control::Error(e) => {
                assert_eq!(e.code, protocol::control::ErrorCode::InvalidMessage);
                break;
            }
            Control::Stats(_) => {}
            other => panic!("unexpected {other:?}"),
        }
    }
    assert_eq!(server.active_session(), Some(session));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn quic_malformed_datagrams_are_counted_and_ignored() {
    let (server, monitor) = server(TransportKind::Quic, Duration::from_secs(120));
    let mut client = connect(&server, TransportKind::Quic).await;
    tokio::time::timeout(Duration::from_secs(20), client.hot.recv_cursor())
        .await
        .unwrap()
        .unwrap();
    let session = client.welcome.session_id;
    let mut buf = [0u8; MAX_PACKET_BYTES];
    let big = Body::Force(constant(Vec3::new(3.0, 0.0, 0.0), (0, 0)));
    let mut other = Outbound::new(session ^ 1, None);
    let n = other.encode(1, big, &mut buf);
    client.hot.send_raw(&buf[..n]).unwrap();
    let mut mine = Outbound::new(session, None);
    let n = mine.encode(1, big, &mut buf);
    let mut wrong_kind = buf[..n].to_vec();
    wrong_kind[3] = 9;
    client.hot.send_raw(&wrong_kind).unwrap();
    client.hot.send_raw(b"HP").unwrap();
    eventually("counted", || {
        let r = server.stats().rejected;
        r.get(Reject::UnknownSession) == 1
            && r.get(Reject::UnknownKind) == 1
            && r.get(Reject::Truncated) == 1
    })
    .await;
    tokio::time::sleep(Duration::from_millis(100)).await;
    assert_eq!(monitor.nonzero_writes(), 0);
    assert_eq!(server.stats().packets_in, 0);
}

/// Only a workstation presenting an authorized client certificate gets a session: without a
/// certificate, or with one the server does not list, `Hello` is answered with a named
/// `Unauthenticated` error on both transports, the device never sees a force, and the slot
/// stays free for the authorized workstation.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unauthenticated_clients_get_a_named_error_and_never_a_session() {
    use haptics_server::client::{Client, ClientError};
    use protocol::control::ErrorCode;

    for kind in [TransportKind::Udp, TransportKind::Quic] {
        let (server, monitor) = server(kind, Duration::from_secs(120));
        let stranger = haptics_server::tls::generate_client().unwrap();
        let fingerprint = haptics_server::tls::fingerprint(&stranger.cert);
        for (who, identity) in [("no certificate", None), ("unlisted", Some(stranger))] {
            let mut cfg = crate::common::config(&server, kind);
            cfg.identity = identity;
            match Client::connect(&cfg).await {
                Err(ClientError::Refused {
                    code: ErrorCode::Unauthenticated,
                    message,
                }) => {
                    if who == "unlisted" {
                        assert!(message.contains(&fingerprint), "{kind:?}: {message}");
                    }
                    assert!(message.contains("authorized"), "{kind:?}: {message}");
                }
                other => panic!("{kind:?} {who}: expected Unauthenticated, got {other:?}"),
            }
        }
        assert_eq!(server.refused_unauthenticated(), 2, "{kind:?}");
        assert_eq!(
            server.sessions_started(),
            0,
            "{kind:?}: no session was started"
        );
        assert_eq!(
            monitor.nonzero_writes(),
            0,
            "{kind:?}: the device never saw a force"
        );
        // The authorized workstation still gets the (free) session.
        let mut client = connect(&server, kind).await;
        tokio::time::timeout(Duration::from_secs(20), client.hot.recv_cursor())
            .await
            .expect("cursor within 20 s")
            .expect("cursor");
        assert_eq!(server.sessions_started(), 1, "{kind:?}");
    }
}

/// A client written from docs/PROTOCOL.md alone (`docs/examples/hp_hello.py`, Python's
/// standard `ssl`) gets a session with the client identity and a named `Unauthenticated`
/// error without it.
#[test]
fn a_python_client_from_the_doc_authenticates_with_its_certificate() {
    let (server, _monitor) = server(TransportKind::Udp, Duration::from_secs(120));
    let dir = tempfile::tempdir().unwrap();
    let cert = dir.path().join("cert.pem");
    haptics_server::tls::append_certificate(&cert, &server.certificate()).unwrap();
    let client = server.local_client().unwrap();
    let (cc, ck) = (dir.path().join("client.pem"), dir.path().join("client.key"));
    haptics_server::tls::write_pem(&client, &cc, &ck).unwrap();
    let script =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/examples/hp_hello.py");
    let port = server.local_addr().port().to_string();
    let run = |with_identity: bool| {
        let mut cmd = std::process::Command::new("python3");
        cmd.arg(&script).args(["127.0.0.1", &port]).arg(&cert);
        if with_identity {
            cmd.arg(&cc).arg(&ck);
        }
        let out = cmd.output().expect("python3 is on every project machine");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let refused = run(false);
    assert!(
        refused.contains("\"Error\"") && refused.contains("\"code\": 6"),
        "no certificate: {refused}"
    );
    let welcome = run(true);
    assert!(
        welcome.contains("\"Welcome\"") && welcome.contains("\"servo_rate_hz\": 1000"),
        "with the client certificate: {welcome}"
    );
}
