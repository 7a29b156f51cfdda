//! End-to-end tests on loopback: the real binaries as processes, and the workstation's threads
//! against in-process servers with the fake device. One test binary.

mod latency;
mod live;
mod server_process;
mod window;
