//! Tick cost (goal ≤ 1 µs): the servo core alone, with the fake device's read/write, and with
//! the cursor packet's encoding + MAC (everything in a UDP tick but the `send_to` syscall).
//! A fresh command arrives every tick (as at 1 kHz from a workstation). Inputs are fixed (seeded fake device), so runs are comparable.

use criterion::{Criterion, black_box, criterion_group, criterion_main};
use glam::Vec3;
use haptics_server::device::Device;
use haptics_server::device::fake::{FakeDevice, FakeParams, HandPath};
use haptics_server::servo::{ServoCore, ServoParams, SessionEvent};
use protocol::packet::MAX_PACKET_BYTES;
use protocol::{Body, ForceCommand, LocalModel, ModelKind, Outbound, SessionKey};

fn params() -> ServoParams {
    ServoParams {
        smoothing_alpha: 0.5,
        ..ServoParams::omni_at_1khz()
    }
}

fn plane() -> ForceCommand {
    ForceCommand {
        force: Vec3::ZERO,
        torque: None,
        answers_sequence: 0,
        answers_timestamp_ns: 0,
        model: LocalModel {
            kind: ModelKind::Plane,
            point: Vec3::new(0.0, 0.001, 0.0),
            normal: Vec3::Y,
            stiffness: 500.0,
            damping: 1.0,
            friction: 0.3,
            validity_radius: 0.05,
            lifetime_us: u32::MAX / 2,
        },
    }
}

fn bench(c: &mut Criterion) {
    let mut core = ServoCore::new(params());
    core.on_event(0, SessionEvent::Start);
    let cmd = plane();
    core.on_command(0, cmd);
    let mut dev = FakeDevice::new(FakeParams {
        path: HandPath::Circle {
            center: Vec3::ZERO,
            radius: 0.01,
            period_s: 1.0,
        },
        ..FakeParams::default()
    });
    let mut t = 0u64;
    c.bench_function("core_tick_plane_friction_ewma", |b| {
        let s = dev.read(0).unwrap_or_default();
        b.iter(|| {
            t += 1_000_000;
            core.on_command(t, cmd);
            black_box(core.tick(t, black_box(&s)))
        })
    });
    c.bench_function("core_tick_with_fake_device", |b| {
        b.iter(|| {
            t += 1_000_000;
            core.on_command(t, cmd);
            let s = dev.read(t).unwrap_or_default();
            let out = core.tick(t, &s);
            let _ = dev.write_force(out.safety.force);
            black_box(out)
        })
    });
    let mut outbound = Outbound::new(7, Some(SessionKey::from_bytes([3; 32])));
    let mut buf = [0u8; MAX_PACKET_BYTES];
    c.bench_function("core_tick_with_fake_device_and_mac", |b| {
        b.iter(|| {
            t += 1_000_000;
            core.on_command(t, cmd);
            let s = dev.read(t).unwrap_or_default();
            let out = core.tick(t, &s);
            let n = outbound.encode(t, Body::Cursor(out.cursor), &mut buf);
            let _ = dev.write_force(out.safety.force);
            black_box(n)
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
