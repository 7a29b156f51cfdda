//! `haptics-server loop-bench`: the servo driver loop alone (fake device, no network) for N
//! seconds, then a bare sleep-then-spin loop with the same period, spin and real-time settings,
//! in the same process; both report start lateness after the deadline (p50/p99/p99.9/max).
//! The bare loop is the floor the OS gives; the difference is what the driver adds.

use std::time::{Duration, Instant};

use hdrhistogram::Histogram;
use protocol::control::Percentiles;

use crate::clock::MonoClock;
use crate::device::fake::{FakeDevice, FakeParams};
use crate::servo::driver::{self, CursorSink, DriverConfig};
use crate::servo::rt::{self, RtReport};
use crate::telemetry::{ServoStats, percentiles};

/// Results of one run.
#[derive(Debug, Clone)]
pub struct LoopBench {
    /// The driver loop's telemetry (lateness, tick cost, period, overruns).
    pub driver: ServoStats,
    /// Lateness of the bare loop.
    pub bare_lateness: Percentiles,
    /// Iterations of the bare loop.
    pub bare_ticks: u64,
    /// What the OS granted the bare loop's thread.
    pub rt: RtReport,
}

/// Run both loops for `seconds` each.
pub fn run(seconds: f64, cfg: &DriverConfig) -> std::io::Result<LoopBench> {
    let duration = Duration::from_secs_f64(seconds.max(0.1));
    let mut cfg = cfg.clone();
    cfg.log_every = Duration::ZERO;
    cfg.record = None;
    let (link, mut threads) = driver::spawn(
        FakeDevice::new(FakeParams::default()),
        CursorSink::None,
        cfg.clone(),
        MonoClock::new(),
    )?;
    std::thread::sleep(duration);
    threads.stop();
    let driver = link.stats.lock().map(|s| *s).unwrap_or_default();

    let period = Duration::from_nanos(cfg.params.period_ns());
    let (spin, req) = (cfg.spin, cfg.rt);
    let bare = std::thread::Builder::new()
        .name("bare-loop".into())
        .spawn(move || {
            let report = rt::setup_current_thread(req);
            let mut h = Histogram::<u64>::new_with_bounds(1, 10_000_000_000, 3)
                .expect("constant, valid bounds");
            let start = Instant::now();
            let mut deadline = start + period;
            while deadline.duration_since(start) < duration {
                let reached = rt::wait_until(deadline, spin);
                let late =
                    u64::try_from(reached.duration_since(deadline).as_nanos()).unwrap_or(u64::MAX);
                let _ = h.record(late.clamp(1, 10_000_000_000));
                deadline += period;
            }
            (percentiles(&h), h.len(), report)
        })?;
    let (bare_lateness, bare_ticks, rt) = bare
        .join()
        .map_err(|_| std::io::Error::other("bare loop panicked"))?;
    Ok(LoopBench {
        driver,
        bare_lateness,
        bare_ticks,
        rt,
    })
}

/// A plain-text table of the results.
pub fn report(b: &LoopBench, rate_hz: u32, spin: Duration) -> String {
    let us = |ns: u64| format!("{:>9.2}", ns as f64 / 1e3);
    let row = |name: &str, p: &Percentiles| {
        format!(
            "{name:<22}{}{}{}{}\n",
            us(p.p50),
            us(p.p99),
            us(p.p999),
            us(p.max)
        )
    };
    let d = &b.driver;
    let mut s = format!(
        "loop-bench: {rate_hz} Hz, spin {} µs, {} driver ticks, {} bare ticks\n",
        spin.as_micros(),
        d.ticks,
        b.bare_ticks
    );
    s.push_str(&format!(
        "real-time: pinned {:?}, SCHED_FIFO {:?}, mlockall {}\n",
        b.rt.pinned, b.rt.fifo, b.rt.locked
    ));
    for w in &b.rt.warnings {
        s.push_str(&format!("warning: {w}\n"));
    }
    s.push_str(&format!(
        "{:<22}{:>9}{:>9}{:>9}{:>9}   (µs)\n",
        "", "p50", "p99", "p99.9", "max"
    ));
    s.push_str(&row("driver lateness", &d.lateness_ns));
    s.push_str(&row("bare loop lateness", &b.bare_lateness));
    s.push_str(&row("driver tick cost", &d.tick_cost_ns));
    s.push_str(&row("driver period", &d.period_ns));
    s.push_str(&format!(
        "driver overruns (> 1 period late): {}, telemetry records dropped: {}\n",
        d.overruns, d.dropped_records
    ));
    s
}
