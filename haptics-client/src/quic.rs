//! QUIC transport settings shared by the server and the client.

use std::time::Duration;

/// Datagram buffer, bytes: a handful of packets, so stale data is dropped, not queued.
pub const DATAGRAM_BUFFER_BYTES: usize = 8 * 128;

/// Transport settings shared by server and client.
pub fn transport_config(idle: Duration) -> quinn::TransportConfig {
    let mut t = quinn::TransportConfig::default();
    t.max_idle_timeout(idle.try_into().ok());
    t.keep_alive_interval(Some(idle / 4));
    t.datagram_receive_buffer_size(Some(DATAGRAM_BUFFER_BYTES));
    t.datagram_send_buffer_size(DATAGRAM_BUFFER_BYTES);
    t.max_concurrent_uni_streams(0u8.into());
    t.max_concurrent_bidi_streams(1u8.into());
    t
}
