//! One session's hot-path endpoints: [`Outbound`] numbers and seals, [`Inbound`] checks.
//!
//! Order of checks in [`Inbound::accept`]: length and magic (cheap, drops foreign traffic),
//! then the MAC (nothing unauthenticated is parsed further), then version, kind, flags and
//! values, then the session id, then the replay window. Only a packet that passes all of them
//! updates the sequence statistics. Each rejection increments one counter of
//! [`Inbound::rejects`].

use crate::error::{DecodeError, RejectCounts};
use crate::mac::SessionKey;
use crate::packet::{Body, MAC_BYTES, MAX_PACKET_BYTES, Packet, decode_header};
use crate::seq::{Arrival, SequenceStats, SequenceTracker};

/// Numbers and encodes one direction's packets; seals them with a MAC when keyed (UDP).
#[derive(Debug, Clone)]
pub struct Outbound {
    session: u32,
    key: Option<SessionKey>,
    next_sequence: u32,
}

impl Outbound {
    /// An endpoint for `session`; `key` is `Some` on UDP (MAC appended), `None` on QUIC.
    pub fn new(session: u32, key: Option<SessionKey>) -> Self {
        Self {
            session,
            key,
            next_sequence: 0,
        }
    }

    /// Encode `body` as the next packet, stamped `timestamp_ns`; returns the wire length.
    /// No allocation.
    pub fn encode(
        &mut self,
        timestamp_ns: u64,
        body: Body,
        out: &mut [u8; MAX_PACKET_BYTES],
    ) -> usize {
        let packet = Packet {
            session: self.session,
            sequence: self.next_sequence,
            timestamp_ns,
            body,
        };
        self.next_sequence = self.next_sequence.wrapping_add(1);
        let len = packet.encode(out);
        match &self.key {
            Some(key) => {
                let tag = key.tag(&out[..len]);
                out[len..len + MAC_BYTES].copy_from_slice(&tag);
                len + MAC_BYTES
            }
            None => len,
        }
    }

    /// The sequence number the next packet will carry.
    pub fn next_sequence(&self) -> u32 {
        self.next_sequence
    }
}

/// Authenticates, decodes and de-duplicates one direction's packets; counts rejections.
#[derive(Debug, Clone)]
pub struct Inbound {
    session: u32,
    key: Option<SessionKey>,
    tracker: SequenceTracker,
    rejects: RejectCounts,
}

impl Inbound {
    /// An endpoint expecting `session`; with `key`, every packet must carry a valid MAC.
    pub fn new(session: u32, key: Option<SessionKey>) -> Self {
        Self {
            session,
            key,
            tracker: SequenceTracker::new(),
            rejects: RejectCounts::default(),
        }
    }

    /// Check one datagram; on success it is a new, authentic, valid packet of this session.
    pub fn accept(&mut self, datagram: &[u8]) -> Result<Packet, DecodeError> {
        let result = self.check(datagram);
        if let Err(error) = &result {
            self.rejects.record(error);
        }
        result
    }

    fn check(&mut self, datagram: &[u8]) -> Result<Packet, DecodeError> {
        if datagram.len() > MAX_PACKET_BYTES {
            return Err(DecodeError::TrailingBytes {
                expected: MAX_PACKET_BYTES,
                got: datagram.len(),
            });
        }
        // Magic and version first: foreign traffic is named as such, not as a bad MAC.
        decode_header(datagram)?;
        let body = match &self.key {
            Some(key) => {
                let Some(split) = datagram.len().checked_sub(MAC_BYTES) else {
                    return Err(DecodeError::Truncated {
                        needed: MAC_BYTES,
                        got: datagram.len(),
                    });
                };
                let (body, tag) = datagram.split_at(split);
                if !key.verify(body, tag) {
                    return Err(DecodeError::BadMac);
                }
                body
            }
            None => datagram,
        };
        let packet = Packet::decode(body)?;
        if packet.session != self.session {
            return Err(DecodeError::UnknownSession {
                got: packet.session,
            });
        }
        match self.tracker.classify(packet.sequence) {
            Arrival::Duplicate => {
                return Err(DecodeError::Replayed {
                    sequence: packet.sequence,
                });
            }
            Arrival::Stale => {
                return Err(DecodeError::Stale {
                    sequence: packet.sequence,
                });
            }
            _ => {}
        }
        self.tracker.record(packet.sequence);
        Ok(packet)
    }

    /// Rejections so far, by reason.
    pub fn rejects(&self) -> &RejectCounts {
        &self.rejects
    }

    /// Loss, reordering and duplicate counters of accepted traffic. Duplicates and stale
    /// packets appear in [`Inbound::rejects`] as `replayed` and `stale` instead.
    pub fn sequence_stats(&self) -> SequenceStats {
        self.tracker.stats()
    }

    /// The newest sequence accepted so far (a packet accepted with an older one arrived late,
    /// after a newer one).
    pub fn newest_sequence(&self) -> Option<u32> {
        self.tracker.newest()
    }

    /// The session this endpoint accepts.
    pub fn session(&self) -> u32 {
        self.session
    }
}
