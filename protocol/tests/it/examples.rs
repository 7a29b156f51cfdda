//! Canonical example packets: the golden vectors and `docs/PROTOCOL.md` are made from these.

use glam::{Quat, Vec3};
use protocol::control::{ClockPing, Config, ErrorCode, ErrorMessage, Hello, Welcome};
use protocol::{
    Body, Control, CursorSample, ForceAck, ForceCommand, LocalModel, ModelKind, SessionKey,
};

pub const SESSION: u32 = 0x0102_0304;

/// The example session key: bytes 0, 1, …, 31.
pub fn key() -> SessionKey {
    let mut bytes = [0u8; 32];
    for (i, b) in bytes.iter_mut().enumerate() {
        *b = i as u8;
    }
    SessionKey::from_bytes(bytes)
}

pub fn cursor() -> CursorSample {
    CursorSample {
        position: Vec3::new(0.01, -0.02, 0.05),
        orientation: Quat::IDENTITY,
        velocity: Vec3::new(0.1, 0.0, 0.0),
        buttons: 1,
        output_force: Vec3::new(0.0, 0.5, 0.0),
        servo_tick: 42,
        engaged: true,
        estop: false,
        ack: Some(ForceAck {
            sequence: 6,
            arrival_ns: 999_650_000,
        }),
    }
}

pub fn force() -> ForceCommand {
    ForceCommand {
        force: Vec3::new(0.0, 1.5, 0.0),
        torque: None,
        answers_sequence: 7,
        answers_timestamp_ns: 1_000_000_000,
        model: LocalModel {
            kind: ModelKind::Plane,
            point: Vec3::new(0.01, 0.0, 0.05),
            normal: Vec3::Y,
            stiffness: 500.0,
            damping: 2.0,
            friction: 0.25,
            validity_radius: 0.005,
            lifetime_us: 20_000,
        },
    }
}

/// (name, sequence, timestamp, body) of every golden packet.
pub fn packets() -> Vec<(&'static str, u32, u64, Body)> {
    vec![
        ("cursor", 7, 1_000_000_000, Body::Cursor(cursor())),
        ("force", 9, 1_000_350_000, Body::Force(force())),
    ]
}

pub fn controls() -> Vec<(&'static str, Control)> {
    vec![
        (
            "hello",
            Control::Hello(Hello {
                protocol_version: protocol::PROTOCOL_VERSION,
                client_name: "ws".into(),
                requested_rate_hz: 1000,
            }),
        ),
        (
            "welcome",
            Control::Welcome(Welcome {
                protocol_version: protocol::PROTOCOL_VERSION,
                device_name: "fake".into(),
                dof_input: 6,
                dof_output: 3,
                workspace_min: [-0.08, -0.06, -0.04],
                workspace_max: [0.08, 0.06, 0.04],
                max_force_n: 3.3,
                max_stiffness_n_per_m: 700.0,
                servo_rate_hz: 1000,
                session_id: SESSION,
                session_key: *key().as_bytes(),
            }),
        ),
        (
            "clock_ping",
            Control::ClockPing(ClockPing {
                id: 3,
                t0_ns: 123_456_789,
            }),
        ),
        ("config", Control::Config(Config::DEFAULT)),
        (
            "error",
            Control::Error(ErrorMessage {
                code: ErrorCode::Busy,
                message: "busy".into(),
            }),
        ),
    ]
}
