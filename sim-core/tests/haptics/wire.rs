//! The one conversion to the wire: whatever a query produced, the packet validates.

use glam::DVec3;
use protocol::packet::{Body, LIMIT_STIFFNESS_N_M, MAX_PACKET_BYTES, ModelKind, Packet};
use sim_core::haptic::{ContactModel, HapticOutput};

fn round_trip(out: &HapticOutput) -> protocol::ForceCommand {
    let packet = Packet {
        session: 7,
        sequence: 1,
        timestamp_ns: 2,
        body: Body::Force(out.to_command(3, 4)),
    };
    let mut buf = [0u8; MAX_PACKET_BYTES];
    let len = packet.encode(&mut buf);
    match Packet::decode(&buf[..len])
        .expect("the receiver accepts it")
        .body
    {
        Body::Force(cmd) => cmd,
        Body::Cursor(_) => unreachable!("a force packet decodes as a force"),
    }
}

fn plane() -> ContactModel {
    ContactModel {
        kind: ModelKind::Plane,
        point: DVec3::new(0.01, 0.02, 0.03),
        normal: DVec3::Z,
        stiffness: 800.0,
        damping: 2.0,
        friction: 0.4,
        validity_radius: 0.004,
        lifetime_s: 0.05,
    }
}

#[test]
fn a_plane_model_survives_the_wire() {
    let out = HapticOutput {
        force: DVec3::new(0.0, 0.0, 1.5),
        model: plane(),
    };
    let cmd = round_trip(&out);
    assert_eq!(cmd.model.kind, ModelKind::Plane);
    assert_eq!(cmd.model.lifetime_us, 50_000);
    assert!((cmd.model.stiffness - 800.0).abs() < 1e-3 && (cmd.force.z - 1.5).abs() < 1e-6);
}

#[test]
fn out_of_range_and_non_finite_models_are_clamped_or_made_inert() {
    let huge = HapticOutput {
        force: DVec3::new(1e9, -1e9, 0.0),
        model: ContactModel {
            stiffness: 1e12,
            damping: 1e9,
            friction: 1e3,
            validity_radius: 1e6,
            lifetime_s: 1e9,
            ..plane()
        },
    };
    let cmd = round_trip(&huge);
    assert_eq!(cmd.model.stiffness, LIMIT_STIFFNESS_N_M);
    let nan = HapticOutput {
        force: DVec3::splat(f64::NAN),
        model: ContactModel {
            point: DVec3::new(f64::NAN, 0.0, 0.0),
            ..plane()
        },
    };
    let cmd = round_trip(&nan);
    assert_eq!(
        cmd.model.kind,
        ModelKind::None,
        "a non-finite model becomes inert"
    );
    assert_eq!(cmd.force, glam::Vec3::ZERO);
    let skewed = HapticOutput {
        force: DVec3::ZERO,
        model: ContactModel {
            normal: DVec3::new(0.0, 3.0, 4.0),
            lifetime_s: f64::INFINITY,
            ..plane()
        },
    };
    let cmd = round_trip(&skewed);
    assert!(
        (cmd.model.normal.length() - 1.0).abs() < 1e-6,
        "normal renormalised"
    );
    assert_eq!(
        cmd.model.lifetime_us, 0,
        "a non-finite lifetime is no lifetime"
    );
}
