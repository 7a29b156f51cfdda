//! Helpers: an in-process server on a fake device, a connected client, polling waits.

use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::Vec3;
use haptics_server::client::{Client, ClientConfig};
use haptics_server::device::fake::{FakeDevice, FakeMonitor, FakeParams, HandPath};
use haptics_server::server::{Server, ServerOptions, TransportKind};
use protocol::{CursorSample, ForceCommand, LocalModel};

/// A server on a still fake stylus at the origin (no tremor), and its force monitor.
pub fn server(kind: TransportKind, idle: Duration) -> (Server, Arc<FakeMonitor>) {
    let dev = FakeDevice::new(FakeParams {
        path: HandPath::Idle { at: Vec3::ZERO },
        tremor_m: 0.0,
        ..FakeParams::default()
    });
    let monitor = dev.monitor();
    let mut opts = ServerOptions::for_tests(kind).expect("options");
    opts.net.idle_timeout = idle;
    opts.net.stats_interval = Duration::from_millis(200);
    (Server::start(dev, opts).expect("server starts"), monitor)
}

pub fn config(server: &Server, kind: TransportKind) -> ClientConfig {
    let mut cfg = ClientConfig::new(server.local_addr(), kind, server.certificate());
    cfg.identity = server.local_client();
    cfg.timeout = Duration::from_secs(20);
    cfg
}

pub async fn connect(server: &Server, kind: TransportKind) -> Client {
    Client::connect(&config(server, kind))
        .await
        .expect("client connects")
}

/// Wait until `cond` holds (polling every 10 ms), panicking with `what` after 20 s.
pub async fn eventually(what: &str, mut cond: impl FnMut() -> bool) {
    let start = Instant::now();
    while !cond() {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "timed out waiting for {what}"
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

/// A command holding `force` (no model) for 1 s.
pub fn constant(force: Vec3, answering: (u32, u64)) -> ForceCommand {
    ForceCommand {
        force,
        torque: None,
        answers_sequence: answering.0,
        answers_timestamp_ns: answering.1,
        model: LocalModel {
            lifetime_us: 1_000_000,
            ..LocalModel::default()
        },
    }
}

/// Answer `n` cursor samples with `make(cursor)`; returns the last sample.
pub async fn stream(
    client: &mut Client,
    n: usize,
    make: impl Fn(&CursorSample) -> ForceCommand,
) -> CursorSample {
    let mut last = None;
    for _ in 0..n {
        let (p, c) = tokio::time::timeout(Duration::from_secs(20), client.hot.recv_cursor())
            .await
            .expect("cursor within 20 s")
            .expect("cursor");
        let mut cmd = make(&c);
        cmd.answers_sequence = p.sequence;
        cmd.answers_timestamp_ns = p.timestamp_ns;
        client.hot.send_force(&cmd).expect("send");
        last = Some(c);
    }
    last.expect("n > 0")
}

/// Answer cursor samples with `make(cursor)` until `done(cursor)` holds for a received sample
/// (a command stream keeps the watchdog fed while waiting), panicking with `what` after 20 s.
pub async fn stream_until(
    client: &mut Client,
    what: &str,
    make: impl Fn(&CursorSample) -> ForceCommand,
    mut done: impl FnMut(&CursorSample) -> bool,
) -> CursorSample {
    let start = Instant::now();
    loop {
        let c = stream(client, 1, &make).await;
        if done(&c) {
            return c;
        }
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "timed out waiting for {what}; last {c:?}"
        );
    }
}
