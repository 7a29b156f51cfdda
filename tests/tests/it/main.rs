//! End-to-end tests on loopback: the real binaries as processes, and the workstation's threads
//! against in-process servers with the fake device; and `deploy/` (configs, units, udev rules,
//! the netem script). One test binary.

mod applied_age;
mod deploy;
mod latency;
mod live;
mod server_process;
mod share;
mod software;
mod window;
