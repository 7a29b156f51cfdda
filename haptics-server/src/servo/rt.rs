//! Real-time setup of the calling thread and the deadline wait.
//!
//! [`setup_current_thread`] tries, in order, CPU pinning (`core_affinity`), `SCHED_FIFO`
//! (`sched_setscheduler`) and `mlockall`, and reports what worked; anything refused (no
//! `CAP_SYS_NICE`, a container, a non-Linux OS) is a warning, never an error.
//! [`wait_until`] sleeps until `spin` before the deadline, then spins on the clock.

use std::time::{Duration, Instant};

/// What to ask of the OS.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RtRequest {
    /// `SCHED_FIFO` priority (1–99); `None` = stay `SCHED_OTHER`.
    pub fifo_priority: Option<i32>,
    /// CPU to pin to; `None` = no pinning.
    pub cpu: Option<usize>,
    /// Lock all pages in memory.
    pub mlockall: bool,
}

/// What the OS granted; `warnings` says what was refused and why.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RtReport {
    /// Pinned to this CPU.
    pub pinned: Option<usize>,
    /// Running `SCHED_FIFO` at this priority.
    pub fifo: Option<i32>,
    /// Pages locked.
    pub locked: bool,
    /// One line per refused request.
    pub warnings: Vec<String>,
}

/// Apply `req` to the calling thread (call it from the servo thread before the loop).
pub fn setup_current_thread(req: RtRequest) -> RtReport {
    let mut report = RtReport::default();
    if let Some(cpu) = req.cpu {
        let ids = core_affinity::get_core_ids().unwrap_or_default();
        match ids.into_iter().find(|c| c.id == cpu) {
            Some(id) if core_affinity::set_for_current(id) => report.pinned = Some(cpu),
            Some(_) => report
                .warnings
                .push(format!("could not pin the servo thread to CPU {cpu}")),
            None => report
                .warnings
                .push(format!("CPU {cpu} does not exist; not pinned")),
        }
    }
    if let Some(prio) = req.fifo_priority {
        match set_fifo(prio) {
            Ok(()) => report.fifo = Some(prio),
            Err(e) => report.warnings.push(format!(
                "SCHED_FIFO priority {prio} refused ({e}); running SCHED_OTHER, expect more \
                 jitter (grant CAP_SYS_NICE or an rtprio limit, see deploy/README.md)"
            )),
        }
    }
    if req.mlockall {
        match lock_memory() {
            Ok(()) => report.locked = true,
            Err(e) => report.warnings.push(format!(
                "mlockall refused ({e}); pages may fault (raise RLIMIT_MEMLOCK)"
            )),
        }
    }
    report
}

/// Run the calling thread `SCHED_FIFO` at `priority`.
#[cfg(target_os = "linux")]
pub fn set_fifo(priority: i32) -> std::io::Result<()> {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: `param` is a valid, initialised sched_param; pid 0 is the calling thread.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

#[cfg(target_os = "linux")]
fn lock_memory() -> std::io::Result<()> {
    // SAFETY: mlockall takes only flags and touches no Rust-visible memory.
    let rc = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Run the calling thread `SCHED_FIFO` at `priority` (Linux only).
#[cfg(not(target_os = "linux"))]
pub fn set_fifo(_priority: i32) -> std::io::Result<()> {
    Err(std::io::Error::other("SCHED_FIFO is Linux-only here"))
}

#[cfg(not(target_os = "linux"))]
fn lock_memory() -> std::io::Result<()> {
    Err(std::io::Error::other("mlockall is Linux-only here"))
}

/// Sleep until `spin` before `deadline`, then spin until it; returns the instant reached
/// (never before `deadline`).
pub fn wait_until(deadline: Instant, spin: Duration) -> Instant {
    let now = Instant::now();
    if let Some(left) = deadline.checked_duration_since(now)
        && left > spin
    {
        std::thread::sleep(left - spin);
    }
    loop {
        let now = Instant::now();
        if now >= deadline {
            return now;
        }
        std::hint::spin_loop();
    }
}
