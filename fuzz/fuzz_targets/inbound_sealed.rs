//! The UDP receive path: MAC, session and replay checks in front of decoding. Never panics,
//! and the counters account for every input.
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::{Inbound, SessionKey};

fuzz_target!(|data: &[u8]| {
    let mut inbound = Inbound::new(0x0102_0304, Some(SessionKey::from_bytes([7; 32])));
    // Feed the input as a sequence of datagrams split at 0xFF bytes.
    let mut outcomes = 0u64;
    for datagram in data.split(|&b| b == 0xFF) {
        let _ = inbound.accept(datagram);
        outcomes += 1;
    }
    let accepted = inbound.sequence_stats().received;
    assert_eq!(accepted + inbound.rejects().total(), outcomes);
});
