//! Helpers: an in-process server on a fake device, a connected client, polling waits, the C
//! stand-ins of vendor libraries.

use std::path::{Path, PathBuf};
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

/// Compile the stand-in `tests/stand-ins/{source}` into `dir/name` as a shared library with
/// the `cc` crate's compiler detection; `defines` adds `-D` flags.
pub fn build_standin(source: &str, dir: &Path, name: &str, defines: &[&str]) -> PathBuf {
    let src = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/stand-ins")
        .join(source);
    let out = dir.join(name);
    let target = format!("{}-unknown-linux-gnu", std::env::consts::ARCH);
    let compiler = cc::Build::new()
        .cargo_metadata(false)
        .target(&target)
        .host(&target)
        .opt_level(1)
        .out_dir(dir)
        .try_get_compiler()
        .expect("a C compiler");
    let mut cmd = compiler.to_command();
    cmd.args(["-shared", "-fPIC", "-std=c11", "-D_GNU_SOURCE", "-o"])
        .arg(&out)
        .arg(&src)
        .args(["-lpthread", "-lm"]);
    for d in defines {
        cmd.arg(format!("-D{d}"));
    }
    let status = cmd.status().expect("run the C compiler");
    assert!(status.success(), "building the stand-in failed: {cmd:?}");
    out
}
