//! Unsealed hot-path decoding: never panics; whatever decodes is valid and re-encodes exactly.
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::Packet;
use protocol::packet::MAX_PACKET_BYTES;

fuzz_target!(|data: &[u8]| {
    if let Ok(packet) = Packet::decode(data) {
        assert_eq!(packet.validate(), Ok(()));
        let mut out = [0u8; MAX_PACKET_BYTES];
        let len = packet.encode(&mut out);
        // Flags and every field round-trip; ignored torque bytes may differ, so compare values.
        assert_eq!(Packet::decode(&out[..len]), Ok(packet));
    }
});
