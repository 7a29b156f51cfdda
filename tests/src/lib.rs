//! Shared helpers for the end-to-end tests in `tests/it/`: locating the project's binaries and
//! running them as child processes on loopback.
//!
//! The tests run the real `haptics-server` executable (not an in-process server), so they
//! exercise argument parsing, certificate files, logging and signal handling as a lab would.
//! `cargo test --workspace` builds every workspace binary before running tests, so the
//! executables sit next to the test binary's `deps/` folder.

use std::net::{SocketAddr, TcpListener, UdpSocket};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

/// Path of a workspace binary built in the same profile as the running test.
pub fn binary(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test binary path");
    // target/<profile>/deps/it-<hash>  →  target/<profile>/<name>
    let dir = exe
        .parent()
        .and_then(|d| d.parent())
        .expect("target/<profile>");
    let path = dir.join(name);
    assert!(
        path.exists(),
        "{} not built: run the tests with `cargo test --workspace` (or `cargo build -p {name}` first)",
        path.display()
    );
    path
}

/// A loopback port free for both TCP and UDP right now.
pub fn free_port() -> u16 {
    for _ in 0..50 {
        let tcp = TcpListener::bind("127.0.0.1:0").expect("bind tcp");
        let port = tcp.local_addr().expect("addr").port();
        if UdpSocket::bind(("127.0.0.1", port)).is_ok() {
            return port;
        }
    }
    panic!("no port free for both TCP and UDP on loopback");
}

/// A child process that is killed when dropped, so a failing test leaves nothing running.
#[derive(Debug)]
pub struct ChildGuard(pub Option<Child>);

impl ChildGuard {
    /// Spawn `command` with stdout and stderr captured.
    pub fn spawn(mut command: Command) -> Self {
        let child = command
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spawn child process");
        Self(Some(child))
    }

    /// Send SIGINT (what Ctrl-C sends) and wait for the process; returns its exit status and
    /// everything it wrote to stderr.
    pub fn interrupt(mut self) -> (std::process::ExitStatus, String) {
        let child = self.0.take().expect("running");
        let status = Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .expect("run kill");
        assert!(status.success(), "kill -INT failed");
        let out = child.wait_with_output().expect("wait for child");
        (
            out.status,
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        if let Some(mut child) = self.0.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// `127.0.0.1:port`.
pub fn loopback(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

/// Who may run beside whom on a 2-core test machine.
///
/// Tests whose assertions need a 1 kHz loop to keep time (forces felt, rates kept, round trips
/// through a delaying relay) take [`wall_clock_slot`]: they run alone among the tests that take
/// a slot. Tests that only load the processors (software rendering, the window under Xvfb) take
/// [`busy_slot`]: they run beside each other but never beside a wall-clock test. A loaded CI
/// machine otherwise starves a servo loop and a correct program fails a timing assertion.
static SLOTS: std::sync::RwLock<()> = std::sync::RwLock::new(());

/// Exclusive: held for the whole of a test whose assertions depend on wall-clock timing.
pub fn wall_clock_slot() -> std::sync::RwLockWriteGuard<'static, ()> {
    // A failed test poisons the lock; the next one still runs (the failure is already reported).
    SLOTS.write().unwrap_or_else(|e| e.into_inner())
}

/// Shared: held by a test that keeps the processors busy but asserts nothing about timing.
pub fn busy_slot() -> std::sync::RwLockReadGuard<'static, ()> {
    SLOTS.read().unwrap_or_else(|e| e.into_inner())
}
