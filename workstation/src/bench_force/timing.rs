//! Per-query timing with its spread: percentiles of individually timed calls over several runs.

use std::time::Instant;

use serde::Serialize;

/// Percentiles of one timed query, µs, and the spread of the p99 across runs.
#[derive(Debug, Clone, Copy, Serialize, Default)]
pub struct Timing {
    /// Median over all runs.
    pub p50: f64,
    /// Median of the runs' p99.
    pub p99: f64,
    /// Smallest run p99.
    pub p99_min: f64,
    /// Largest run p99.
    pub p99_max: f64,
    /// 99.9th percentile over all runs.
    pub p999: f64,
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i]
}

/// Time `query(i)` for `i in 0..n` per run, `repeats` runs, after one untimed warm-up run.
pub fn time_runs(repeats: usize, n: usize, mut query: impl FnMut(usize)) -> Timing {
    (0..n.min(1000)).for_each(&mut query);
    let mut all = Vec::with_capacity(repeats * n);
    let mut p99s = Vec::with_capacity(repeats);
    let mut run = Vec::with_capacity(n);
    for _ in 0..repeats.max(1) {
        run.clear();
        for i in 0..n {
            let t0 = Instant::now();
            query(i);
            run.push(t0.elapsed().as_secs_f64() * 1e6);
        }
        run.sort_by(f64::total_cmp);
        p99s.push(percentile(&run, 0.99));
        all.extend_from_slice(&run);
    }
    all.sort_by(f64::total_cmp);
    p99s.sort_by(f64::total_cmp);
    Timing {
        p50: percentile(&all, 0.5),
        p99: percentile(&p99s, 0.5),
        p99_min: p99s[0],
        p99_max: p99s[p99s.len() - 1],
        p999: percentile(&all, 0.999),
    }
}
