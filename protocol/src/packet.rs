//! Hot-path packets: checked values and their fixed little-endian encoding.
//!
//! Layout (all little-endian, no padding; byte tables in `docs/PROTOCOL.md`):
//! `header (22) | body (cursor 70, force 80) | MAC (16, UDP only)`.
//! Encoding writes into a caller's fixed buffer and never allocates. Decoding checks length,
//! magic, version, kind and flags, then validates every value ([`Packet::validate`]): a decoded
//! [`Packet`] holds only finite numbers inside the documented ranges.

use glam::{Quat, Vec3};
use zerocopy::{FromBytes, IntoBytes};

use crate::error::DecodeError;
use crate::wire::{
    CURSOR_BODY_LEN, FORCE_BODY_LEN, HEADER_LEN, WireCursor, WireForce, WireHeader, WireVec3,
};
use crate::{MAGIC, PROTOCOL_VERSION};

/// Bytes of the common header.
pub const HEADER_BYTES: usize = HEADER_LEN;
/// Bytes of an unsealed `CursorSample` packet (QUIC datagram).
pub const CURSOR_PACKET_BYTES: usize = HEADER_LEN + CURSOR_BODY_LEN;
/// Bytes of an unsealed `ForceCommand` packet (QUIC datagram).
pub const FORCE_PACKET_BYTES: usize = HEADER_LEN + FORCE_BODY_LEN;
/// Bytes of the MAC trailer on UDP packets.
pub const MAC_BYTES: usize = 16;
/// The largest packet on the wire (a sealed `ForceCommand`): size receive buffers with this.
pub const MAX_PACKET_BYTES: usize = FORCE_PACKET_BYTES + MAC_BYTES;

/// Largest |coordinate| of a position, m.
pub const LIMIT_POSITION_M: f32 = 100.0;
/// Largest |component| of a velocity, m/s.
pub const LIMIT_VELOCITY_M_S: f32 = 100.0;
/// Largest |component| of a force, N.
pub const LIMIT_FORCE_N: f32 = 1_000.0;
/// Largest |component| of a torque, N·m.
pub const LIMIT_TORQUE_NM: f32 = 100.0;
/// Largest contact stiffness, N/m (the server clamps further to its device).
pub const LIMIT_STIFFNESS_N_M: f32 = 100_000.0;
/// Largest contact damping, N·s/m.
pub const LIMIT_DAMPING_N_S_M: f32 = 1_000.0;
/// Largest friction coefficient.
pub const LIMIT_FRICTION: f32 = 10.0;
/// Largest validity radius of a local model, m.
pub const LIMIT_VALIDITY_RADIUS_M: f32 = 10.0;
/// Longest lifetime of a local model, µs.
pub const LIMIT_LIFETIME_US: u32 = 10_000_000;
/// Tolerance on the norm of unit quaternions and unit normals.
pub const UNIT_TOLERANCE: f32 = 1e-3;

/// The kind byte of the header.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum PacketKind {
    /// Server → workstation: the device state of one servo tick.
    Cursor = 1,
    /// Workstation → server: a force and the local contact model to render.
    Force = 2,
}

impl PacketKind {
    fn from_byte(b: u8) -> Result<Self, DecodeError> {
        match b {
            1 => Ok(PacketKind::Cursor),
            2 => Ok(PacketKind::Force),
            got => Err(DecodeError::UnknownKind { got }),
        }
    }

    /// Unsealed packet length of this kind.
    pub const fn packet_bytes(self) -> usize {
        match self {
            PacketKind::Cursor => CURSOR_PACKET_BYTES,
            PacketKind::Force => FORCE_PACKET_BYTES,
        }
    }
}

/// Cursor flag: the server is sending force to the device (a session is up and ramped in).
pub const CURSOR_FLAG_ENGAGED: u16 = 1 << 0;
/// Cursor flag: emergency stop is latched; output is zero until released.
pub const CURSOR_FLAG_ESTOP: u16 = 1 << 1;
/// Cursor flag: the `ack` fields name the newest force command the server applied.
pub const CURSOR_FLAG_ACK: u16 = 1 << 2;
/// Force flag: the torque field is meaningful.
pub const FORCE_FLAG_TORQUE: u16 = 1 << 0;
/// Force flag: the local model is a unilateral contact plane.
pub const FORCE_FLAG_MODEL_PLANE: u16 = 1 << 1;
/// Force flag: the local model is a bilateral spring toward an anchor point.
pub const FORCE_FLAG_MODEL_ANCHOR: u16 = 1 << 2;

/// One decoded hot-path packet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Packet {
    /// Session id from `Welcome`.
    pub session: u32,
    /// Per-direction sequence number, +1 per packet, wrapping.
    pub sequence: u32,
    /// Sender's monotonic clock at send, ns.
    pub timestamp_ns: u64,
    /// The kind-specific content.
    pub body: Body,
}

/// The kind-specific part of a packet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Body {
    /// Server → workstation.
    Cursor(CursorSample),
    /// Workstation → server.
    Force(ForceCommand),
}

/// The device state at one servo tick, in the device frame (m, m/s, N).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CursorSample {
    /// Stylus tip position, m.
    pub position: Vec3,
    /// Stylus orientation, unit quaternion.
    pub orientation: Quat,
    /// Tip velocity, m/s.
    pub velocity: Vec3,
    /// Button bit mask (bit 0 = primary).
    pub buttons: u16,
    /// The force the device is outputting this tick, N (after smoothing and safety).
    pub output_force: Vec3,
    /// Servo tick counter, wrapping.
    pub servo_tick: u32,
    /// Force output is live.
    pub engaged: bool,
    /// Emergency stop is latched.
    pub estop: bool,
    /// The newest force command the server has applied, when it has one this session.
    pub ack: Option<ForceAck>,
}

/// Which force command a cursor sample follows, and when it reached the server: with the
/// command's own send time (client clock) and the cursor's header timestamp (server clock),
/// every cursor carries the four timestamps of an NTP exchange, so the client measures the
/// network round trip exactly and one-way delays within the clock estimator's bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ForceAck {
    /// The command's header `sequence`.
    pub sequence: u32,
    /// When it arrived at the server, server clock, ns.
    pub arrival_ns: u64,
}

/// What the server renders until the next command: a force plus a local contact model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceCommand {
    /// Force computed at the answered cursor position, N (device frame).
    pub force: Vec3,
    /// Torque, N·m, when the device can render it.
    pub torque: Option<Vec3>,
    /// Sequence number of the cursor sample this answers (round-trip measurement).
    pub answers_sequence: u32,
    /// Sender timestamp of that cursor sample, echoed, ns of the server's clock.
    pub answers_timestamp_ns: u64,
    /// The contact model valid near the cursor.
    pub model: LocalModel,
}

/// What kind of local model a [`ForceCommand`] carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum ModelKind {
    /// No model: the server holds `force` until the next command (`lifetime_us` unused); its
    /// watchdog fades the force out when commands stop.
    #[default]
    None,
    /// Unilateral plane through `point` with outward unit `normal`: push-out force
    /// `k·depth − b·v_n` when the cursor is below it, friction `friction` along the plane.
    Plane,
    /// Bilateral spring toward `point` (`normal` unused): the reaction of material being dragged.
    Anchor,
}

/// A local model of the scene near the contact, rendered by the server at its own rate.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LocalModel {
    /// Which model; see [`ModelKind`].
    pub kind: ModelKind,
    /// Contact point on the surface (plane) or anchor point, m.
    pub point: Vec3,
    /// Outward unit normal of the contact plane (zero unless `Plane`).
    pub normal: Vec3,
    /// Stiffness, N/m.
    pub stiffness: f32,
    /// Damping, N·s/m.
    pub damping: f32,
    /// Coulomb friction coefficient along the plane.
    pub friction: f32,
    /// The model is valid within this distance of `point`, m.
    pub validity_radius: f32,
    /// The model is valid this long after the command is received, µs.
    pub lifetime_us: u32,
}

impl Packet {
    /// Length of this packet unsealed.
    pub fn encoded_len(&self) -> usize {
        self.kind().packet_bytes()
    }

    /// The header kind of this packet.
    pub fn kind(&self) -> PacketKind {
        match self.body {
            Body::Cursor(_) => PacketKind::Cursor,
            Body::Force(_) => PacketKind::Force,
        }
    }

    /// Write the unsealed packet to the front of `out`, returning its length.
    ///
    /// `out` must hold [`MAX_PACKET_BYTES`]; encoding does not validate (call
    /// [`Packet::validate`] on values you did not construct yourself).
    pub fn encode(&self, out: &mut [u8; MAX_PACKET_BYTES]) -> usize {
        let (kind, flags) = match &self.body {
            Body::Cursor(c) => (PacketKind::Cursor, cursor_flags(c)),
            Body::Force(f) => (PacketKind::Force, force_flags(f)),
        };
        let header = WireHeader {
            magic: MAGIC,
            version: PROTOCOL_VERSION,
            kind: kind as u8,
            flags: flags.into(),
            session: self.session.into(),
            sequence: self.sequence.into(),
            timestamp_ns: self.timestamp_ns.into(),
        };
        out[..HEADER_LEN].copy_from_slice(header.as_bytes());
        let body = &mut out[HEADER_LEN..];
        match &self.body {
            Body::Cursor(c) => body[..CURSOR_BODY_LEN].copy_from_slice(wire_cursor(c).as_bytes()),
            Body::Force(f) => body[..FORCE_BODY_LEN].copy_from_slice(wire_force(f).as_bytes()),
        }
        kind.packet_bytes()
    }

    /// Decode and validate an unsealed packet that must span all of `bytes`.
    pub fn decode(bytes: &[u8]) -> Result<Packet, DecodeError> {
        let header = decode_header(bytes)?;
        let kind = PacketKind::from_byte(header.kind)?;
        let expected = kind.packet_bytes();
        if bytes.len() < expected {
            return Err(DecodeError::Truncated {
                needed: expected,
                got: bytes.len(),
            });
        }
        if bytes.len() > expected {
            return Err(DecodeError::TrailingBytes {
                expected,
                got: bytes.len(),
            });
        }
        let flags = header.flags.get();
        let body_bytes = &bytes[HEADER_LEN..];
        let body = match kind {
            PacketKind::Cursor => {
                if flags & !(CURSOR_FLAG_ENGAGED | CURSOR_FLAG_ESTOP | CURSOR_FLAG_ACK) != 0 {
                    return Err(DecodeError::InvalidFlags { kind, flags });
                }
                let w = WireCursor::read_from_bytes(body_bytes)
                    .map_err(|_| truncated(expected, bytes))?;
                Body::Cursor(cursor_from_wire(&w, flags))
            }
            PacketKind::Force => {
                let known = FORCE_FLAG_TORQUE | FORCE_FLAG_MODEL_PLANE | FORCE_FLAG_MODEL_ANCHOR;
                let both = FORCE_FLAG_MODEL_PLANE | FORCE_FLAG_MODEL_ANCHOR;
                if flags & !known != 0 || flags & both == both {
                    return Err(DecodeError::InvalidFlags { kind, flags });
                }
                let w = WireForce::read_from_bytes(body_bytes)
                    .map_err(|_| truncated(expected, bytes))?;
                Body::Force(force_from_wire(&w, flags))
            }
        };
        let packet = Packet {
            session: header.session.get(),
            sequence: header.sequence.get(),
            timestamp_ns: header.timestamp_ns.get(),
            body,
        };
        packet.validate()?;
        Ok(packet)
    }

    /// Check every value is finite and inside its documented range.
    pub fn validate(&self) -> Result<(), DecodeError> {
        match &self.body {
            Body::Cursor(c) => c.validate(),
            Body::Force(f) => f.validate(),
        }
    }
}

/// Check the fixed header fields (magic, version) and return the raw header.
pub(crate) fn decode_header(bytes: &[u8]) -> Result<WireHeader, DecodeError> {
    let Ok((header, _)) = WireHeader::read_from_prefix(bytes) else {
        if bytes.len() >= 2 && bytes[..2] != MAGIC {
            return Err(DecodeError::BadMagic {
                got: [bytes[0], bytes[1]],
            });
        }
        return Err(DecodeError::Truncated {
            needed: HEADER_LEN,
            got: bytes.len(),
        });
    };
    if header.magic != MAGIC {
        return Err(DecodeError::BadMagic { got: header.magic });
    }
    if header.version != PROTOCOL_VERSION {
        return Err(DecodeError::UnsupportedVersion {
            got: header.version,
        });
    }
    Ok(header)
}

fn truncated(expected: usize, bytes: &[u8]) -> DecodeError {
    DecodeError::Truncated {
        needed: expected,
        got: bytes.len(),
    }
}

impl CursorSample {
    /// Check every value is finite and inside its documented range.
    pub fn validate(&self) -> Result<(), DecodeError> {
        check_vec("cursor.position", self.position, LIMIT_POSITION_M)?;
        let q = self.orientation;
        check_vec(
            "cursor.orientation",
            Vec3::new(q.x, q.y, q.z),
            1.0 + UNIT_TOLERANCE,
        )?;
        check_scalar(
            "cursor.orientation",
            q.w,
            -1.0 - UNIT_TOLERANCE,
            1.0 + UNIT_TOLERANCE,
        )?;
        check_unit("cursor.orientation", q.length())?;
        check_vec("cursor.velocity", self.velocity, LIMIT_VELOCITY_M_S)?;
        check_vec("cursor.output_force", self.output_force, LIMIT_FORCE_N)
    }
}

impl ForceCommand {
    /// Check every value is finite and inside its documented range.
    pub fn validate(&self) -> Result<(), DecodeError> {
        check_vec("force.force", self.force, LIMIT_FORCE_N)?;
        if let Some(t) = self.torque {
            check_vec("force.torque", t, LIMIT_TORQUE_NM)?;
        }
        self.model.validate()
    }
}

impl LocalModel {
    /// Check every value is finite and inside its documented range.
    pub fn validate(&self) -> Result<(), DecodeError> {
        check_vec("model.point", self.point, LIMIT_POSITION_M)?;
        check_vec("model.normal", self.normal, 1.0 + UNIT_TOLERANCE)?;
        if self.kind == ModelKind::Plane {
            check_unit("model.normal", self.normal.length())?;
        }
        check_scalar("model.stiffness", self.stiffness, 0.0, LIMIT_STIFFNESS_N_M)?;
        check_scalar("model.damping", self.damping, 0.0, LIMIT_DAMPING_N_S_M)?;
        check_scalar("model.friction", self.friction, 0.0, LIMIT_FRICTION)?;
        check_scalar(
            "model.validity_radius",
            self.validity_radius,
            0.0,
            LIMIT_VALIDITY_RADIUS_M,
        )?;
        if self.lifetime_us > LIMIT_LIFETIME_US {
            let value = self.lifetime_us as f32;
            return Err(DecodeError::OutOfRange {
                field: "model.lifetime_us",
                value,
            });
        }
        Ok(())
    }
}

fn check_scalar(field: &'static str, value: f32, min: f32, max: f32) -> Result<(), DecodeError> {
    if !value.is_finite() {
        return Err(DecodeError::NonFinite { field });
    }
    if value < min || value > max {
        return Err(DecodeError::OutOfRange { field, value });
    }
    Ok(())
}

fn check_vec(field: &'static str, v: Vec3, limit: f32) -> Result<(), DecodeError> {
    for value in v.to_array() {
        check_scalar(field, value, -limit, limit)?;
    }
    Ok(())
}

fn check_unit(field: &'static str, norm: f32) -> Result<(), DecodeError> {
    if (norm - 1.0).abs() > UNIT_TOLERANCE {
        return Err(DecodeError::OutOfRange { field, value: norm });
    }
    Ok(())
}

fn cursor_flags(c: &CursorSample) -> u16 {
    let mut flags = 0;
    if c.engaged {
        flags |= CURSOR_FLAG_ENGAGED;
    }
    if c.estop {
        flags |= CURSOR_FLAG_ESTOP;
    }
    if c.ack.is_some() {
        flags |= CURSOR_FLAG_ACK;
    }
    flags
}

fn force_flags(f: &ForceCommand) -> u16 {
    let mut flags = 0;
    if f.torque.is_some() {
        flags |= FORCE_FLAG_TORQUE;
    }
    flags |= match f.model.kind {
        ModelKind::None => 0,
        ModelKind::Plane => FORCE_FLAG_MODEL_PLANE,
        ModelKind::Anchor => FORCE_FLAG_MODEL_ANCHOR,
    };
    flags
}

fn wire_cursor(c: &CursorSample) -> WireCursor {
    let q = c.orientation;
    WireCursor {
        position: c.position.into(),
        orientation: [q.x.into(), q.y.into(), q.z.into(), q.w.into()],
        velocity: c.velocity.into(),
        output_force: c.output_force.into(),
        servo_tick: c.servo_tick.into(),
        buttons: c.buttons.into(),
        ack_sequence: c.ack.map_or(0, |a| a.sequence).into(),
        ack_arrival_ns: c.ack.map_or(0, |a| a.arrival_ns).into(),
    }
}

fn cursor_from_wire(w: &WireCursor, flags: u16) -> CursorSample {
    let [x, y, z, qw] = w.orientation.map(|c| c.get());
    CursorSample {
        position: w.position.into(),
        orientation: Quat::from_xyzw(x, y, z, qw),
        velocity: w.velocity.into(),
        buttons: w.buttons.get(),
        output_force: w.output_force.into(),
        servo_tick: w.servo_tick.get(),
        engaged: flags & CURSOR_FLAG_ENGAGED != 0,
        estop: flags & CURSOR_FLAG_ESTOP != 0,
        ack: (flags & CURSOR_FLAG_ACK != 0).then(|| ForceAck {
            sequence: w.ack_sequence.get(),
            arrival_ns: w.ack_arrival_ns.get(),
        }),
    }
}

fn wire_force(f: &ForceCommand) -> WireForce {
    let m = &f.model;
    WireForce {
        force: f.force.into(),
        torque: f.torque.unwrap_or(Vec3::ZERO).into(),
        answers_sequence: f.answers_sequence.into(),
        answers_timestamp_ns: f.answers_timestamp_ns.into(),
        point: m.point.into(),
        normal: m.normal.into(),
        stiffness: m.stiffness.into(),
        damping: m.damping.into(),
        friction: m.friction.into(),
        validity_radius: m.validity_radius.into(),
        lifetime_us: m.lifetime_us.into(),
    }
}

fn force_from_wire(w: &WireForce, flags: u16) -> ForceCommand {
    let kind = if flags & FORCE_FLAG_MODEL_PLANE != 0 {
        ModelKind::Plane
    } else if flags & FORCE_FLAG_MODEL_ANCHOR != 0 {
        ModelKind::Anchor
    } else {
        ModelKind::None
    };
    ForceCommand {
        force: w.force.into(),
        torque: (flags & FORCE_FLAG_TORQUE != 0).then(|| WireVec3::into(w.torque)),
        answers_sequence: w.answers_sequence.get(),
        answers_timestamp_ns: w.answers_timestamp_ns.get(),
        model: LocalModel {
            kind,
            point: w.point.into(),
            normal: w.normal.into(),
            stiffness: w.stiffness.get(),
            damping: w.damping.get(),
            friction: w.friction.get(),
            validity_radius: w.validity_radius.get(),
            lifetime_us: w.lifetime_us.get(),
        },
    }
}
