//! `--record` writes the session; the `replay` device plays it back with its timing.

use std::time::Duration;

use glam::Vec3;
use haptics_server::device::Device;
use haptics_server::device::fake::{FakeDevice, FakeParams, HandPath};
use haptics_server::device::replay::ReplayDevice;
use haptics_server::server::{Server, ServerOptions, TransportKind};
use haptics_server::telemetry::record;

use crate::common::{config, constant, eventually, stream};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recorded_session_replays_positions_buttons_and_timing() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("session.csv");
    let dev = FakeDevice::new(FakeParams {
        path: HandPath::Press {
            at: Vec3::ZERO,
            depth: 0.01,
            approach_s: 0.05,
            hold_s: 0.05,
        },
        ..FakeParams::default()
    });
    let mut opts = ServerOptions::for_tests(TransportKind::Udp).unwrap();
    opts.driver.record = Some(file.clone());
    let server = Server::start(dev, opts).unwrap();
    let mut client = haptics_server::client::Client::connect(&config(&server, TransportKind::Udp))
        .await
        .unwrap();
    stream(&mut client, 300, |_| constant(Vec3::ZERO, (0, 0))).await;
    eventually("ticks recorded", || server.servo_stats().ticks > 300).await;
    drop(client);
    server.shutdown();

    let ticks = record::load(&file).expect("recording parses");
    assert!(ticks.len() > 300, "{}", ticks.len());
    assert!(
        ticks.iter().any(|t| t.sample.buttons == 1),
        "the press held button 0"
    );
    assert!(ticks.windows(2).all(|w| w[0].t_ns <= w[1].t_ns));

    // Replay at the recorded times gives back the recorded samples.
    let mut replay = ReplayDevice::from_ticks(ticks.clone(), false, "session".into());
    let t0 = ticks[0].t_ns;
    for t in ticks.iter().step_by(37) {
        let s = replay.read(1_000 + t.t_ns - t0).unwrap();
        assert_eq!(s, t.sample);
    }
    // Past the end it holds the last sample.
    let last = ticks.last().unwrap();
    assert_eq!(
        replay.read(1_000 + last.t_ns - t0 + 5_000_000_000).unwrap(),
        last.sample
    );

    // And the replay device serves a session like any other.
    let server = Server::start(
        ReplayDevice::open(&file, true).unwrap(),
        ServerOptions::for_tests(TransportKind::Udp).unwrap(),
    )
    .unwrap();
    let mut client = haptics_server::client::Client::connect(&config(&server, TransportKind::Udp))
        .await
        .unwrap();
    let c = stream(&mut client, 100, |_| constant(Vec3::ZERO, (0, 0))).await;
    assert!(
        ticks
            .iter()
            .any(|t| t.sample.position == c.position && t.sample.buttons == c.buttons),
        "the served cursor is a recorded sample: {c:?}"
    );
    assert_eq!(client.welcome.dof_output, 0, "a replay outputs no force");
    tokio::time::sleep(Duration::from_millis(1)).await;
}
