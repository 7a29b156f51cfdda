//! Measured and predicted stability limits of the integrators on a given model.
//!
//! Contract: [`measure_limit`] bisects the time step (in log space) between a stable and an
//! unstable guess. A run is *unstable* when, from a seeded random displacement with no external
//! force, the energy exceeds `growth ×` its initial value within `steps` steps, or a step fails.
//! Forward Euler is measured with halving disabled (that is what halving protects). Deterministic.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::dynamics::{DynamicGrid, Integrator, Stepper};

/// Settings of a measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LimitSearch {
    /// Steps per trial run.
    pub steps: u32,
    /// Energy growth factor that counts as unstable.
    pub growth: f64,
    /// Bisection rounds (each halves the log-interval).
    pub rounds: u32,
    /// Seed of the initial displacement.
    pub seed: u64,
}

impl Default for LimitSearch {
    fn default() -> Self {
        Self {
            steps: 2000,
            growth: 100.0,
            rounds: 16,
            seed: 7,
        }
    }
}

/// Whether `integrator` keeps `model` (forces cleared, seeded displacement) bounded at `dt`.
pub fn is_stable(
    model: &DynamicGrid,
    integrator: Integrator,
    dt: f64,
    search: &LimitSearch,
) -> bool {
    let mut m = model.clone();
    m.clear_forces();
    let mut rng = ChaCha8Rng::seed_from_u64(search.seed);
    for s in 0..m.active_len() {
        m.u[s] = 1e-3 * (rng.random::<f64>() - 0.5);
        m.v[s] = 0.0;
    }
    let e0 = m.energy();
    let integrator = match integrator {
        Integrator::ForwardEuler { .. } => Integrator::ForwardEuler {
            accel_threshold: f64::INFINITY,
            max_halvings: 0,
            relax_after: 0,
        },
        other => other,
    };
    let mut stepper = Stepper::new(integrator);
    for _ in 0..search.steps {
        if stepper.step(&mut m, dt).is_err() {
            return false;
        }
        let e = m.energy();
        if e.is_nan() || e > search.growth * e0 {
            return false;
        }
    }
    true
}

/// The largest stable step in `[lo, hi]` to within the bisection's resolution; `lo` if even `lo`
/// is unstable and `hi` if `hi` is stable.
pub fn measure_limit(
    model: &DynamicGrid,
    integrator: Integrator,
    lo: f64,
    hi: f64,
    search: &LimitSearch,
) -> f64 {
    if !is_stable(model, integrator, lo, search) {
        return lo;
    }
    if is_stable(model, integrator, hi, search) {
        return hi;
    }
    let (mut a, mut b) = (lo.ln(), hi.ln());
    for _ in 0..search.rounds {
        let mid = 0.5 * (a + b);
        if is_stable(model, integrator, mid.exp(), search) {
            a = mid;
        } else {
            b = mid;
        }
    }
    a.exp()
}

/// Predicted limits for uniform node parameters from the Gershgorin bound on `ω_max` and the
/// top mode's damping ratio `ζ = c/(2 m ω_max)` (the top mode is the binding one in every
/// regime). Forward Euler: `Δt < 2ζ/ω = c/(m ω²)` when underdamped (so it needs damping:
/// undamped it is unconditionally unstable), `Δt < 2/(ω(ζ + √(ζ²−1)))` when overdamped (the fast
/// real eigenvalue). Symplectic Euler: `Δt < min((2/ω)(√(1+ζ²) − ζ), 1/(ζ ω))`. Backward Euler
/// has no limit. Returns `(forward, symplectic)` in seconds.
pub fn predicted_limits(model: &DynamicGrid) -> (f64, f64) {
    let w = model.omega_max_bound();
    let p = model.node_params(0);
    let zeta = p.damping / (2.0 * p.mass * w);
    let fe = if zeta < 1.0 {
        2.0 * zeta / w
    } else {
        2.0 / (w * (zeta + (zeta * zeta - 1.0).sqrt()))
    };
    let se = ((2.0 / w) * ((1.0 + zeta * zeta).sqrt() - zeta)).min(if zeta > 0.0 {
        1.0 / (zeta * w)
    } else {
        f64::INFINITY
    });
    (fe, se)
}
