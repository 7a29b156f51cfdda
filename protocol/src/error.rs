//! Why a packet was rejected, and counters of rejections by reason.

use serde::{Deserialize, Serialize};

use crate::packet::PacketKind;

/// Why a hot-path packet was not accepted. Every decoder path returns one of these; none panics.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DecodeError {
    /// Fewer bytes than the header, the packet kind or the MAC needs.
    #[error("truncated packet: need {needed} bytes, got {got}")]
    Truncated { needed: usize, got: usize },
    /// More bytes than the packet kind has.
    #[error("packet too long: expected {expected} bytes, got {got}")]
    TrailingBytes { expected: usize, got: usize },
    /// The first two bytes are not `"HP"`: not one of ours.
    #[error("foreign packet: magic {got:02x?}")]
    BadMagic { got: [u8; 2] },
    /// A protocol version this build does not speak.
    #[error("unsupported protocol version {got}")]
    UnsupportedVersion { got: u8 },
    /// A packet kind byte this build does not know.
    #[error("unknown packet kind {got}")]
    UnknownKind { got: u8 },
    /// Flag bits that are undefined for the kind, or a contradictory combination.
    #[error("invalid flags {flags:#06x} for {kind:?} packet")]
    InvalidFlags { kind: PacketKind, flags: u16 },
    /// The MAC does not match: forged, corrupted, or keyed for another session.
    #[error("bad MAC")]
    BadMac,
    /// Authentic framing but another session's id.
    #[error("unknown session {got:#010x}")]
    UnknownSession { got: u32 },
    /// A sequence number already received (replay or network duplicate).
    #[error("replayed sequence {sequence}")]
    Replayed { sequence: u32 },
    /// A sequence number older than the replay window: cannot be told apart from a replay.
    #[error("stale sequence {sequence}, older than the replay window")]
    Stale { sequence: u32 },
    /// A NaN or infinite value.
    #[error("non-finite value in {field}")]
    NonFinite { field: &'static str },
    /// A finite value outside the documented range.
    #[error("{field} out of range: {value}")]
    OutOfRange { field: &'static str, value: f32 },
}

/// A [`DecodeError`] without its data: the key for counting rejections.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(usize)]
pub enum Reject {
    /// [`DecodeError::Truncated`].
    Truncated,
    /// [`DecodeError::TrailingBytes`].
    TrailingBytes,
    /// [`DecodeError::BadMagic`].
    BadMagic,
    /// [`DecodeError::UnsupportedVersion`].
    UnsupportedVersion,
    /// [`DecodeError::UnknownKind`].
    UnknownKind,
    /// [`DecodeError::InvalidFlags`].
    InvalidFlags,
    /// [`DecodeError::BadMac`].
    BadMac,
    /// [`DecodeError::UnknownSession`].
    UnknownSession,
    /// [`DecodeError::Replayed`].
    Replayed,
    /// [`DecodeError::Stale`].
    Stale,
    /// [`DecodeError::NonFinite`].
    NonFinite,
    /// [`DecodeError::OutOfRange`].
    OutOfRange,
}

impl Reject {
    /// Number of reasons.
    pub const COUNT: usize = 12;
    /// Every reason, in counter order.
    pub const ALL: [Reject; Self::COUNT] = [
        Reject::Truncated,
        Reject::TrailingBytes,
        Reject::BadMagic,
        Reject::UnsupportedVersion,
        Reject::UnknownKind,
        Reject::InvalidFlags,
        Reject::BadMac,
        Reject::UnknownSession,
        Reject::Replayed,
        Reject::Stale,
        Reject::NonFinite,
        Reject::OutOfRange,
    ];

    /// Short snake_case name for logs and reports.
    pub const fn as_str(self) -> &'static str {
        match self {
            Reject::Truncated => "truncated",
            Reject::TrailingBytes => "trailing_bytes",
            Reject::BadMagic => "bad_magic",
            Reject::UnsupportedVersion => "unsupported_version",
            Reject::UnknownKind => "unknown_kind",
            Reject::InvalidFlags => "invalid_flags",
            Reject::BadMac => "bad_mac",
            Reject::UnknownSession => "unknown_session",
            Reject::Replayed => "replayed",
            Reject::Stale => "stale",
            Reject::NonFinite => "non_finite",
            Reject::OutOfRange => "out_of_range",
        }
    }
}

impl DecodeError {
    /// The counter this error increments.
    pub const fn reason(&self) -> Reject {
        match self {
            DecodeError::Truncated { .. } => Reject::Truncated,
            DecodeError::TrailingBytes { .. } => Reject::TrailingBytes,
            DecodeError::BadMagic { .. } => Reject::BadMagic,
            DecodeError::UnsupportedVersion { .. } => Reject::UnsupportedVersion,
            DecodeError::UnknownKind { .. } => Reject::UnknownKind,
            DecodeError::InvalidFlags { .. } => Reject::InvalidFlags,
            DecodeError::BadMac => Reject::BadMac,
            DecodeError::UnknownSession { .. } => Reject::UnknownSession,
            DecodeError::Replayed { .. } => Reject::Replayed,
            DecodeError::Stale { .. } => Reject::Stale,
            DecodeError::NonFinite { .. } => Reject::NonFinite,
            DecodeError::OutOfRange { .. } => Reject::OutOfRange,
        }
    }
}

/// Rejected-packet counters, one per [`Reject`] reason. Plain integers: no allocation.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RejectCounts {
    /// Indexed by `Reject as usize`.
    pub counts: [u64; Reject::COUNT],
}

impl RejectCounts {
    /// Count one rejection.
    pub fn record(&mut self, error: &DecodeError) {
        let slot = &mut self.counts[error.reason() as usize];
        *slot = slot.saturating_add(1);
    }

    /// The count for one reason.
    pub fn get(&self, reason: Reject) -> u64 {
        self.counts[reason as usize]
    }

    /// All rejections together.
    pub fn total(&self) -> u64 {
        self.counts.iter().fold(0u64, |a, &c| a.saturating_add(c))
    }

    /// `(name, count)` for every reason with a non-zero count.
    pub fn nonzero(&self) -> impl Iterator<Item = (&'static str, u64)> + '_ {
        Reject::ALL
            .iter()
            .map(|r| (r.as_str(), self.get(*r)))
            .filter(|&(_, c)| c > 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reject_order_matches_discriminants() {
        for (i, r) in Reject::ALL.iter().enumerate() {
            assert_eq!(*r as usize, i, "{r:?}");
        }
    }
}
