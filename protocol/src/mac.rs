//! The 16-byte MAC that authenticates every UDP hot-path packet.
//!
//! MAC = the first 16 bytes of BLAKE3 in keyed mode (`blake3::keyed_hash`) over the whole
//! unsealed packet, header included, keyed by the 32-byte per-session [`SessionKey`] that the
//! server sends in `Welcome` over the authenticated control channel. BLAKE3's keyed mode is a
//! PRF, so a truncated tag is a sound MAC; the comparison is constant-time.

/// The 32-byte key of one session's MACs. Its `Debug` output never shows the key.
#[derive(Clone, PartialEq, Eq)]
pub struct SessionKey([u8; 32]);

impl SessionKey {
    /// Wrap 32 bytes (from the OS's random source on the server; from `Welcome` on the client).
    pub const fn from_bytes(bytes: [u8; 32]) -> Self {
        Self(bytes)
    }

    /// The raw key, for `Welcome`.
    pub const fn as_bytes(&self) -> &[u8; 32] {
        &self.0
    }

    /// The MAC of `message` under this key.
    pub fn tag(&self, message: &[u8]) -> [u8; 16] {
        let hash = blake3::keyed_hash(&self.0, message);
        let mut tag = [0u8; 16];
        tag.copy_from_slice(&hash.as_bytes()[..16]);
        tag
    }

    /// Whether `tag` is the MAC of `message`, compared in constant time.
    pub fn verify(&self, message: &[u8], tag: &[u8]) -> bool {
        tag.len() == 16 && constant_time_eq::constant_time_eq(&self.tag(message), tag)
    }
}

impl std::fmt::Debug for SessionKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("SessionKey(<redacted>)")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tag_depends_on_key_and_message() {
        let a = SessionKey::from_bytes([1; 32]);
        let b = SessionKey::from_bytes([2; 32]);
        assert_ne!(a.tag(b"x"), b.tag(b"x"));
        assert_ne!(a.tag(b"x"), a.tag(b"y"));
        assert!(a.verify(b"x", &a.tag(b"x")));
        assert!(!a.verify(b"x", &b.tag(b"x")));
        assert!(!a.verify(b"x", &a.tag(b"x")[..15]));
    }

    #[test]
    fn debug_redacts_key() {
        let text = format!("{:?}", SessionKey::from_bytes([0xAB; 32]));
        assert!(
            !text.contains("171") && !text.to_lowercase().contains("ab"),
            "{text}"
        );
    }
}
