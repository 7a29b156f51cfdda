//! The clock estimator recovers a known offset within its stated bound.

use protocol::{ClockEstimator, ClockSample};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Simulate pings with exponential queueing delays, asymmetric outliers and clock drift.
fn run(seed: u64, offset_ns: i64, drift_ppm: f64, outlier_rate: f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut est = ClockEstimator::new(100.0);
    let mut client_ns: u64 = 10_000_000_000;
    let server_at = |client: u64| -> u64 {
        let drifted = client as f64 * (1.0 + drift_ppm * 1e-6);
        (drifted as i64 + offset_ns) as u64
    };
    for _ in 0..2000 {
        let base = 50_000.0; // 50 µs propagation each way
        let mut fwd = base + -rng.random::<f64>().max(1e-12).ln() * 20_000.0;
        let mut back = base + -rng.random::<f64>().max(1e-12).ln() * 20_000.0;
        if rng.random_bool(outlier_rate) {
            // Asymmetric outliers: one direction stalls for up to 20 ms.
            if rng.random_bool(0.5) {
                fwd += rng.random_range(1e6..2e7)
            } else {
                back += rng.random_range(1e6..2e7)
            }
        }
        let hold = rng.random_range(1_000..50_000) as f64;
        let t0 = client_ns;
        let t1 = server_at(t0 + fwd as u64);
        let t2 = server_at(t0 + (fwd + hold) as u64);
        let t3 = t0 + (fwd + hold + back) as u64;
        est.add(ClockSample {
            t0_ns: t0,
            t1_ns: t1,
            t2_ns: t2,
            t3_ns: t3,
        })
        .unwrap();
        client_ns = t3 + rng.random_range(1_000_000..5_000_000);

        let e = est.estimate().unwrap();
        // The true offset now, at the client's latest receive time.
        let truth = server_at(t3) as i128 - t3 as i128;
        let error = (i128::from(e.offset_ns) - truth).unsigned_abs();
        assert!(
            error <= u128::from(e.uncertainty_ns),
            "seed {seed}: error {error} ns exceeds bound {} ns ({e:?})",
            e.uncertainty_ns
        );
    }
    let e = est.estimate().unwrap();
    // Min-RTT filtering: the bound stays near the floor (2 × 50 µs propagation), not the outliers.
    assert!(
        e.uncertainty_ns < 150_000,
        "bound {} ns not tight",
        e.uncertainty_ns
    );
}

#[test]
fn recovers_positive_and_negative_offsets() {
    run(1, 5_000_000_000, 0.0, 0.0);
    run(2, -3_000_000_000, 0.0, 0.0);
}

#[test]
fn outliers_do_not_move_the_estimate_outside_its_bound() {
    for seed in 10..20 {
        run(seed, 123_456_789, 0.0, 0.3);
    }
}

#[test]
fn drift_within_the_assumed_rate_stays_inside_the_bound() {
    run(30, -42_000_000, 50.0, 0.1);
    run(31, 42_000_000, -50.0, 0.1);
}
