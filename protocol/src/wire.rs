//! The raw little-endian layouts of the hot-path packets, as `zerocopy` structs.
//!
//! These types are the byte tables of `docs/PROTOCOL.md` written in Rust: every field is an
//! unaligned little-endian primitive, so `repr(C)` adds no padding and the sizes below are exact.
//! Nothing outside this crate sees them; [`crate::packet`] converts to and from checked values.

use zerocopy::byteorder::little_endian::{F32, U16, U32, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

/// Common header, 22 bytes.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct WireHeader {
    pub magic: [u8; 2],
    pub version: u8,
    pub kind: u8,
    pub flags: U16,
    pub session: U32,
    pub sequence: U32,
    pub timestamp_ns: U64,
}

/// Three little-endian `f32`, 12 bytes.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct WireVec3 {
    pub x: F32,
    pub y: F32,
    pub z: F32,
}

/// `CursorSample` body, 70 bytes.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct WireCursor {
    pub position: WireVec3,
    /// Unit quaternion in `x, y, z, w` order.
    pub orientation: [F32; 4],
    pub velocity: WireVec3,
    pub output_force: WireVec3,
    pub servo_tick: U32,
    pub buttons: U16,
    pub ack_sequence: U32,
    pub ack_arrival_ns: U64,
}

/// `ForceCommand` body, 80 bytes.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct WireForce {
    pub force: WireVec3,
    pub torque: WireVec3,
    pub answers_sequence: U32,
    pub answers_timestamp_ns: U64,
    pub point: WireVec3,
    pub normal: WireVec3,
    pub stiffness: F32,
    pub damping: F32,
    pub friction: F32,
    pub validity_radius: F32,
    pub lifetime_us: U32,
}

pub(crate) const HEADER_LEN: usize = size_of::<WireHeader>();
pub(crate) const CURSOR_BODY_LEN: usize = size_of::<WireCursor>();
pub(crate) const FORCE_BODY_LEN: usize = size_of::<WireForce>();

const _: () = assert!(HEADER_LEN == 22);
const _: () = assert!(CURSOR_BODY_LEN == 70);
const _: () = assert!(FORCE_BODY_LEN == 80);

impl From<glam::Vec3> for WireVec3 {
    fn from(v: glam::Vec3) -> Self {
        Self {
            x: v.x.into(),
            y: v.y.into(),
            z: v.z.into(),
        }
    }
}

impl From<WireVec3> for glam::Vec3 {
    fn from(v: WireVec3) -> Self {
        glam::Vec3::new(v.x.get(), v.y.get(), v.z.get())
    }
}
