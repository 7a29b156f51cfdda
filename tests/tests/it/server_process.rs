//! The `haptics-server` executable, as a lab runs it: a fake stylus, a pinned certificate made
//! by `gen-cert`, a client identity made and authorized by `gen-cert --client`, a workstation client over UDP and over QUIC. Force reaches the device only
//! through the safety stages (engage small, then clamp keeping direction), a second workstation
//! is refused, a workstation restart is survived, and Ctrl-C stops the server cleanly.

use std::process::Command;
use std::time::{Duration, Instant};

use e2e_tests::{ChildGuard, binary, free_port, loopback};
use glam::Vec3;
use haptics_server::client::{Client, ClientConfig, ClientError};
use haptics_server::server::TransportKind;
use haptics_server::tls::{read_cert, read_identity};
use protocol::control::ErrorCode;
use protocol::{CursorSample, ForceCommand, LocalModel};

/// Device force limit of the default config (Phantom Omni peak), N.
const DEFAULT_LIMIT_N: f32 = 3.3;

struct Running {
    server: ChildGuard,
    config: ClientConfig,
    _dir: tempfile::TempDir,
}

fn start(transport: &str) -> Running {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = Command::new(binary("haptics-server"))
        .args(["gen-cert", "--out"])
        .arg(dir.path())
        .output()
        .expect("run gen-cert");
    assert!(
        out.status.success(),
        "gen-cert: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = Command::new(binary("haptics-server"))
        .args(["gen-cert", "--client", "--out"])
        .arg(dir.path().join("ws"))
        .arg("--authorize")
        .arg(dir.path().join("authorized_clients.pem"))
        .output()
        .expect("run gen-cert --client");
    assert!(
        out.status.success(),
        "gen-cert --client: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let port = free_port();
    let mut cmd = Command::new(binary("haptics-server"));
    cmd.args(["--device", "fake", "--fake-path", "idle", "--no-realtime"])
        .args([
            "--transport",
            transport,
            "--listen",
            &format!("127.0.0.1:{port}"),
        ])
        .arg("--cert")
        .arg(dir.path().join("cert.pem"))
        .arg("--key")
        .arg(dir.path().join("key.pem"))
        .env("RUST_LOG", "info");
    let server = ChildGuard::spawn(cmd);
    let kind = if transport == "quic" {
        TransportKind::Quic
    } else {
        TransportKind::Udp
    };
    let cert = read_cert(&dir.path().join("cert.pem")).expect("read cert");
    let mut config = ClientConfig::new(loopback(port), kind, cert);
    config.timeout = Duration::from_secs(5);
    config.identity = Some(
        read_identity(
            &dir.path().join("ws/client.pem"),
            &dir.path().join("ws/client.key"),
        )
        .expect("read the client identity"),
    );
    Running {
        server,
        config,
        _dir: dir,
    }
}

/// Connect, retrying while the server process starts up (up to 30 s).
async fn connect(config: &ClientConfig) -> Client {
    let start = Instant::now();
    loop {
        match Client::connect(config).await {
            Ok(client) => return client,
            Err(_) if start.elapsed() < Duration::from_secs(30) => {
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
            Err(e) => panic!("could not connect within 30 s: {e}"),
        }
    }
}

fn holding(force: Vec3) -> ForceCommand {
    ForceCommand {
        force,
        torque: None,
        answers_sequence: 0,
        answers_timestamp_ns: 0,
        model: LocalModel {
            lifetime_us: 1_000_000,
            ..LocalModel::default()
        },
    }
}

/// Answer cursor samples with `force` until `done(cursor)` or 20 s pass; returns the last sample.
async fn drive(
    client: &mut Client,
    force: Vec3,
    mut done: impl FnMut(&CursorSample) -> bool,
) -> CursorSample {
    let start = Instant::now();
    loop {
        let (packet, cursor) =
            tokio::time::timeout(Duration::from_secs(10), client.hot.recv_cursor())
                .await
                .expect("a cursor sample within 10 s")
                .expect("cursor stream");
        assert!(
            cursor.output_force.length() <= DEFAULT_LIMIT_N * 1.0001,
            "device force {} exceeds the limit",
            cursor.output_force
        );
        let mut cmd = holding(force);
        cmd.answers_sequence = packet.sequence;
        cmd.answers_timestamp_ns = packet.timestamp_ns;
        client.hot.send_force(&cmd).expect("send force");
        if done(&cursor) {
            return cursor;
        }
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "condition not reached: last {cursor:?}"
        );
    }
}

async fn forces_reach_the_device_through_the_safety_stages(transport: &str) {
    let running = start(transport);
    let mut client = connect(&running.config).await;
    assert_eq!(client.welcome.max_force_n, DEFAULT_LIMIT_N);

    // A small command engages and ramps in to exactly the commanded force.
    let small = Vec3::new(0.0, 0.3, 0.0);
    drive(&mut client, small, |c| {
        c.engaged && (c.output_force - small).length() < 1e-3
    })
    .await;

    // A command far over the limit is clamped to it, direction kept.
    let huge = Vec3::new(30.0, 40.0, 0.0);
    let c = drive(&mut client, huge, |c| {
        c.output_force.length() > DEFAULT_LIMIT_N * 0.999
    })
    .await;
    let dir = c.output_force.normalize();
    assert!(
        (dir - huge.normalize()).length() < 1e-3,
        "direction lost: {}",
        c.output_force
    );

    // A second workstation is refused while this one holds the session.
    match Client::connect(&running.config).await {
        Err(ClientError::Refused { code, .. }) => assert_eq!(code, ErrorCode::Busy),
        Err(other) => panic!("second client: expected Busy, got {other}"),
        Ok(_) => panic!("second client was accepted while a session is active"),
    }

    // The workstation restarts: its sockets close, and a new one gets the device.
    drop(client);
    let mut client = connect(&running.config).await;
    let small = Vec3::new(0.0, 0.0, -0.2);
    drive(&mut client, small, |c| {
        c.engaged && (c.output_force - small).length() < 1e-3
    })
    .await;
    drop(client);

    let (status, stderr) = running.server.interrupt();
    assert!(status.success(), "server exit {status}; stderr:\n{stderr}");
}

/// The tests' runtime: two workers, as `#[tokio::test(flavor = "multi_thread")]` would make,
/// built inside a synchronous test so it can hold its slot (a lock) without an await over it.
fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("tokio runtime")
}

#[test]
fn udp_server_process_serves_forces_safely() {
    let _slot = e2e_tests::busy_slot();
    runtime().block_on(forces_reach_the_device_through_the_safety_stages("udp"));
}

#[test]
fn quic_server_process_serves_forces_safely() {
    let _slot = e2e_tests::busy_slot();
    runtime().block_on(forces_reach_the_device_through_the_safety_stages("quic"));
}
