//! End-to-end tests: the real binaries as processes on loopback. One test binary.

mod server_process;
