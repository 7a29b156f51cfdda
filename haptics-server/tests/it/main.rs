//! Integration tests of `haptics-server`: one binary (ripgrep-style), real loopback sockets.
//!
//! Timing is never asserted: every wait is "until the condition holds, or a generous timeout",
//! so a loaded 2-core CI machine makes the tests slower, not flaky.

mod check;
mod cli;
mod common;
mod dhd;
mod loopback;
mod openhaptics;
mod record;
mod security;
mod sessions;
mod virtual_link;
