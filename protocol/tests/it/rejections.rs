//! Every rejection path, by name: each forged or malformed packet yields its own variant,
//! is counted under its reason, and leaves the accepted stream untouched.

use glam::{Quat, Vec3};
use protocol::error::Reject;
use protocol::packet::{MAC_BYTES, MAX_PACKET_BYTES};
use protocol::{Body, DecodeError, Inbound, ModelKind, Outbound, Packet, SessionKey};

use crate::examples;

fn sealed_with(key: &SessionKey, session: u32, body: Body) -> Vec<u8> {
    let mut out = Outbound::new(session, Some(key.clone()));
    let mut buf = [0u8; MAX_PACKET_BYTES];
    let len = out.encode(5, body, &mut buf);
    buf[..len].to_vec()
}

fn good() -> Vec<u8> {
    sealed_with(
        &examples::key(),
        examples::SESSION,
        Body::Cursor(examples::cursor()),
    )
}

/// Re-seal `bytes` (a sealed packet) after editing its unsealed part.
fn reseal(mut bytes: Vec<u8>, edit: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    bytes.truncate(bytes.len() - MAC_BYTES);
    edit(&mut bytes);
    let tag = examples::key().tag(&bytes);
    bytes.extend_from_slice(&tag);
    bytes
}

fn inbound() -> Inbound {
    Inbound::new(examples::SESSION, Some(examples::key()))
}

fn rejected(bytes: &[u8]) -> DecodeError {
    let mut inb = inbound();
    let err = inb.accept(bytes).expect_err("must be rejected");
    assert_eq!(
        inb.rejects().get(err.reason()),
        1,
        "counted under {:?}",
        err.reason()
    );
    assert_eq!(inb.rejects().total(), 1);
    assert_eq!(
        inb.sequence_stats().received,
        0,
        "a rejected packet must not be recorded"
    );
    err
}

fn cursor_with(edit: impl FnOnce(&mut protocol::CursorSample)) -> Vec<u8> {
    let mut c = examples::cursor();
    edit(&mut c);
    sealed_with(&examples::key(), examples::SESSION, Body::Cursor(c))
}

fn force_with(edit: impl FnOnce(&mut protocol::ForceCommand)) -> Vec<u8> {
    let mut f = examples::force();
    edit(&mut f);
    sealed_with(&examples::key(), examples::SESSION, Body::Force(f))
}

#[test]
fn accepts_the_good_packet() {
    let mut inb = inbound();
    let p = inb.accept(&good()).unwrap();
    assert_eq!(p.body, Body::Cursor(examples::cursor()));
    assert_eq!(inb.rejects().total(), 0);
}

#[test]
fn truncated() {
    let g = good();
    assert!(matches!(rejected(&g[..10]), DecodeError::Truncated { .. }));
    // Header intact, MAC over a shortened body.
    let short = reseal(g, |b| b.truncate(b.len() - 1));
    assert!(matches!(rejected(&short), DecodeError::Truncated { .. }));
    assert!(matches!(rejected(&[]), DecodeError::Truncated { .. }));
}

#[test]
fn trailing_bytes() {
    let long = reseal(good(), |b| b.push(0));
    assert!(matches!(rejected(&long), DecodeError::TrailingBytes { .. }));
    assert!(matches!(
        rejected(&[b'H'; 4096]),
        DecodeError::TrailingBytes { .. }
    ));
}

#[test]
fn bad_magic() {
    let mut g = good();
    g[0] = b'X';
    assert_eq!(rejected(&g), DecodeError::BadMagic { got: [b'X', b'P'] });
    assert_eq!(
        rejected(b"GET / HTTP/1.1"),
        DecodeError::BadMagic { got: *b"GE" }
    );
}

#[test]
fn unsupported_version() {
    let g = reseal(good(), |b| b[2] = 99);
    assert_eq!(rejected(&g), DecodeError::UnsupportedVersion { got: 99 });
}

#[test]
fn unknown_kind() {
    let g = reseal(good(), |b| b[3] = 77);
    assert_eq!(rejected(&g), DecodeError::UnknownKind { got: 77 });
}

#[test]
fn invalid_flags() {
    let g = reseal(good(), |b| b[4] = 0x80);
    assert!(matches!(
        rejected(&g),
        DecodeError::InvalidFlags { flags: 0x80, .. }
    ));
    // Plane and anchor models at once contradict each other.
    let f = force_with(|_| {});
    let both = reseal(f, |b| b[4] = 0b110);
    assert!(matches!(
        rejected(&both),
        DecodeError::InvalidFlags { flags: 0b110, .. }
    ));
}

#[test]
fn bad_mac() {
    let mut g = good();
    let last = g.len() - 1;
    g[last] ^= 1;
    assert_eq!(rejected(&g), DecodeError::BadMac);
    // A body bit flipped after sealing.
    let mut g = good();
    g[30] ^= 0x10;
    assert_eq!(rejected(&g), DecodeError::BadMac);
    // Sealed under another key.
    let other = SessionKey::from_bytes([9; 32]);
    let forged = sealed_with(&other, examples::SESSION, Body::Cursor(examples::cursor()));
    assert_eq!(rejected(&forged), DecodeError::BadMac);
}

#[test]
fn unknown_session() {
    let g = sealed_with(
        &examples::key(),
        0xdead_beef,
        Body::Cursor(examples::cursor()),
    );
    assert_eq!(
        rejected(&g),
        DecodeError::UnknownSession { got: 0xdead_beef }
    );
}

#[test]
fn replayed_and_stale() {
    let mut out = Outbound::new(examples::SESSION, Some(examples::key()));
    let mut inb = inbound();
    let mut packets = Vec::new();
    for _ in 0..100 {
        let mut buf = [0u8; MAX_PACKET_BYTES];
        let len = out.encode(1, Body::Cursor(examples::cursor()), &mut buf);
        packets.push(buf[..len].to_vec());
    }
    for p in &packets[..] {
        inb.accept(p).unwrap();
    }
    assert_eq!(
        inb.accept(&packets[99]),
        Err(DecodeError::Replayed { sequence: 99 })
    );
    assert_eq!(
        inb.accept(&packets[50]),
        Err(DecodeError::Replayed { sequence: 50 })
    );
    assert_eq!(
        inb.accept(&packets[3]),
        Err(DecodeError::Stale { sequence: 3 })
    );
    assert_eq!(inb.rejects().get(Reject::Replayed), 2);
    assert_eq!(inb.rejects().get(Reject::Stale), 1);
    assert_eq!(inb.sequence_stats().received, 100);
}

#[test]
fn non_finite_values() {
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (cursor_with(|c| c.position.x = f32::NAN), "cursor.position"),
        (
            cursor_with(|c| c.velocity.z = f32::INFINITY),
            "cursor.velocity",
        ),
        (
            cursor_with(|c| c.orientation = Quat::from_xyzw(f32::NAN, 0., 0., 1.)),
            "cursor.orientation",
        ),
        (
            cursor_with(|c| c.output_force.y = f32::NEG_INFINITY),
            "cursor.output_force",
        ),
        (force_with(|f| f.force.y = f32::NAN), "force.force"),
        (
            force_with(|f| f.torque = Some(Vec3::new(0., f32::NAN, 0.))),
            "force.torque",
        ),
        (
            force_with(|f| f.model.stiffness = f32::NAN),
            "model.stiffness",
        ),
        (
            force_with(|f| f.model.normal = Vec3::new(f32::NAN, 0., 0.)),
            "model.normal",
        ),
        (
            force_with(|f| f.model.point.z = f32::INFINITY),
            "model.point",
        ),
    ];
    for (bytes, field) in cases {
        assert_eq!(
            rejected(&bytes),
            DecodeError::NonFinite { field },
            "{field}"
        );
    }
}

#[test]
fn out_of_range_values() {
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (cursor_with(|c| c.position.x = 1e4), "cursor.position"),
        (
            cursor_with(|c| c.orientation = Quat::from_xyzw(0., 0., 0., 0.5)),
            "cursor.orientation",
        ),
        (force_with(|f| f.force.x = 5e3), "force.force"),
        (force_with(|f| f.model.stiffness = -1.0), "model.stiffness"),
        (force_with(|f| f.model.stiffness = 1e9), "model.stiffness"),
        (force_with(|f| f.model.damping = -0.1), "model.damping"),
        (force_with(|f| f.model.friction = 11.0), "model.friction"),
        (
            force_with(|f| f.model.validity_radius = -1.0),
            "model.validity_radius",
        ),
        (
            force_with(|f| f.model.lifetime_us = 60_000_000),
            "model.lifetime_us",
        ),
        (
            force_with(|f| f.model.normal = Vec3::new(0., 0.5, 0.)),
            "model.normal",
        ),
    ];
    for (bytes, field) in cases {
        let err = rejected(&bytes);
        assert!(
            matches!(err, DecodeError::OutOfRange { field: f, .. } if f == field),
            "{field}: got {err:?}"
        );
    }
}

#[test]
fn normal_need_not_be_unit_without_a_plane() {
    let mut f = examples::force();
    f.model.kind = ModelKind::Anchor;
    f.model.normal = Vec3::ZERO;
    let p = Packet {
        session: 1,
        sequence: 0,
        timestamp_ns: 0,
        body: Body::Force(f),
    };
    assert_eq!(p.validate(), Ok(()));
}

#[test]
fn rejections_do_not_disturb_the_stream() {
    let mut out = Outbound::new(examples::SESSION, Some(examples::key()));
    let mut inb = inbound();
    let mut buf = [0u8; MAX_PACKET_BYTES];
    let mut accepted = 0;
    for i in 0..50u32 {
        let len = out.encode(u64::from(i), Body::Force(examples::force()), &mut buf);
        let mut forged = buf[..len].to_vec();
        forged[len - 1] ^= 0xff;
        assert_eq!(inb.accept(&forged), Err(DecodeError::BadMac));
        assert!(inb.accept(&buf[..len]).is_ok());
        accepted += 1;
    }
    assert_eq!(inb.sequence_stats().received, accepted);
    assert_eq!(inb.sequence_stats().lost, 0);
    assert_eq!(inb.rejects().get(Reject::BadMac), 50);
}
