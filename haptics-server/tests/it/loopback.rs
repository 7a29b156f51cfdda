//! Handshake, the cursor stream, forces reaching the device, control messages; both transports.

use std::time::Duration;

use glam::Vec3;
use haptics_server::server::TransportKind;
use protocol::control::{ClockPing, EmergencyStop};
use protocol::{Control, ForceCommand, LocalModel, ModelKind};

use crate::common::{connect, constant, eventually, server, stream, stream_until};

async fn handshake_stream_and_force(kind: TransportKind) {
    let (server, monitor) = server(kind, Duration::from_secs(5));
    let mut client = connect(&server, kind).await;
    let w = &client.welcome;
    assert_eq!((w.dof_input, w.dof_output, w.servo_rate_hz), (6, 3, 1000));
    assert!((w.max_force_n - 3.3).abs() < 1e-6);
    assert_eq!(server.active_session(), Some(w.session_id));

    // The cursor stream: consecutive servo ticks, one packet each.
    let first = stream(&mut client, 1, |_| constant(Vec3::ZERO, (0, 0))).await;
    let last = stream(&mut client, 300, |_| constant(Vec3::ZERO, (0, 0))).await;
    assert!(last.servo_tick.wrapping_sub(first.servo_tick) >= 300);
    assert!(last.engaged, "a small command engages the output");

    // A constant force reaches the device (after the ramp).
    let f = Vec3::new(0.3, 0.0, 0.0);
    let at_device = |_: &protocol::CursorSample| (monitor.last_force() - f).length() < 1e-5;
    stream_until(
        &mut client,
        "the force at the device",
        |_| constant(f, (0, 0)),
        at_device,
    )
    .await;

    // A plane model 2 mm above the stylus: the server renders k × penetration at the *current*
    // position every tick; the stylus (closed loop) settles where the hand and the wall balance.
    let plane = ForceCommand {
        model: LocalModel {
            kind: ModelKind::Plane,
            point: Vec3::new(0.0, 0.002, 0.0),
            normal: Vec3::Y,
            stiffness: 500.0,
            damping: 0.0,
            friction: 0.0,
            validity_radius: 0.05,
            lifetime_us: 1_000_000,
        },
        ..constant(Vec3::ZERO, (0, 0))
    };
    let k_times_d = |c: &protocol::CursorSample| 500.0 * (0.002 - c.position.y);
    let settled = |c: &protocol::CursorSample| {
        let f = c.output_force;
        c.engaged
            && k_times_d(c) > 0.05
            && (f.y - k_times_d(c)).abs() < 0.02
            && f.x.abs() < 1e-4
            && f.z.abs() < 1e-4
    };
    let c = stream_until(
        &mut client,
        "F = k·d at the current position",
        |_| plane,
        settled,
    )
    .await;
    assert!(c.output_force.y > 0.0, "pushes out, never pulls: {c:?}");

    // Clock ping and periodic stats on the control channel.
    client
        .control
        .send(&Control::ClockPing(ClockPing { id: 7, t0_ns: 1 }))
        .await
        .unwrap();
    // Stats arrive every 200 ms (older ones may be queued): read until a recent one.
    let mut pong = false;
    let mut stats: Option<protocol::control::Stats> = None;
    let recent = |s: &Option<protocol::control::Stats>| {
        s.is_some_and(|s| s.ticks > 300 && s.packets_in > 300)
    };
    while !(pong && recent(&stats)) {
        match tokio::time::timeout(Duration::from_secs(20), client.control.recv())
            .await
            .unwrap()
            .unwrap()
        {
            Control::ClockPong(p) => {
                assert_eq!((p.id, p.t0_ns), (7, 1));
                assert!(p.t2_ns >= p.t1_ns);
                pong = true;
            }
            Control::Stats(s) => {
                assert!(
                    stats.is_none_or(|old| s.ticks >= old.ticks),
                    "stats go forward"
                );
                stats = Some(s);
            }
            other => panic!("unexpected {other:?}"),
        }
    }
    let s = stats.unwrap();
    assert!(s.packets_out > 300, "{s:?}");
    assert_eq!(s.rejected.total(), 0, "{s:?}");
    client.control.close("test done").await.unwrap();
    eventually("session to end", || server.active_session().is_none()).await;
    eventually("force to fall to zero", || {
        monitor.last_force() == Vec3::ZERO
    })
    .await;
    assert_eq!(monitor.nonfinite_writes(), 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn udp_handshake_stream_and_force() {
    handshake_stream_and_force(TransportKind::Udp).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn quic_handshake_stream_and_force() {
    handshake_stream_and_force(TransportKind::Quic).await;
}

async fn emergency_stop(kind: TransportKind) {
    let (server, monitor) = server(kind, Duration::from_secs(5));
    let mut client = connect(&server, kind).await;
    let f = Vec3::new(0.0, 0.0, 0.4);
    let at_device = |_: &protocol::CursorSample| (monitor.last_force() - f).length() < 1e-5;
    stream_until(
        &mut client,
        "force applied",
        |_| constant(f, (0, 0)),
        at_device,
    )
    .await;
    client
        .control
        .send(&Control::EmergencyStop(EmergencyStop { engage: true }))
        .await
        .unwrap();
    // Keep commanding force: it must stay at zero, and the cursor says so.
    let mut c = stream(&mut client, 1, |_| constant(f, (0, 0))).await;
    for _ in 0..2000 {
        if c.estop {
            break;
        }
        c = stream(&mut client, 1, |_| constant(f, (0, 0))).await;
    }
    assert!(c.estop && !c.engaged);
    stream(&mut client, 50, |_| constant(f, (0, 0))).await;
    assert_eq!(monitor.last_force(), Vec3::ZERO);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn udp_emergency_stop() {
    emergency_stop(TransportKind::Udp).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn quic_emergency_stop() {
    emergency_stop(TransportKind::Quic).await;
}

/// A burst of `Config`s (a UI slider dragged) right before an emergency stop: the stop must
/// still reach the servo, not be dropped on a full event ring.
async fn emergency_stop_after_a_config_burst(kind: TransportKind) {
    let (server, monitor) = server(kind, Duration::from_secs(5));
    let mut client = connect(&server, kind).await;
    let f = Vec3::new(0.0, 0.0, 0.4);
    let at_device = |_: &protocol::CursorSample| (monitor.last_force() - f).length() < 1e-5;
    stream_until(
        &mut client,
        "force applied",
        |_| constant(f, (0, 0)),
        at_device,
    )
    .await;
    let mut burst = Vec::new();
    for _ in 0..1000 {
        burst.extend(Control::Config(protocol::control::Config::DEFAULT).to_frame());
    }
    burst.extend(Control::EmergencyStop(EmergencyStop { engage: true }).to_frame());
    for _ in 0..1000 {
        burst.extend(Control::Config(protocol::control::Config::DEFAULT).to_frame());
    }
    client.control.send_raw(&burst).await.unwrap();
    let mut c = stream(&mut client, 1, |_| constant(f, (0, 0))).await;
    for _ in 0..3000 {
        if c.estop {
            break;
        }
        c = stream(&mut client, 1, |_| constant(f, (0, 0))).await;
    }
    assert!(c.estop && !c.engaged, "the emergency stop was lost");
    stream(&mut client, 50, |_| constant(f, (0, 0))).await;
    assert_eq!(monitor.last_force(), Vec3::ZERO);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn udp_emergency_stop_after_a_config_burst() {
    emergency_stop_after_a_config_burst(TransportKind::Udp).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn quic_emergency_stop_after_a_config_burst() {
    emergency_stop_after_a_config_burst(TransportKind::Quic).await;
}
