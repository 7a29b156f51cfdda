//! Time integrators for [`DynamicGrid`]: the papers' forward Euler with step halving, semi-implicit
//! (symplectic) Euler, and backward Euler solved by conjugate gradient.
//!
//! Contract: [`Stepper::step`] advances the model by exactly `dt` or leaves it exactly as it was.
//! The state is saved at the step boundary; if any displacement or velocity comes out non-finite,
//! the state is restored and [`StepError::NonFinite`] names the node; values below
//! [`FLUSH_BELOW`] are flushed to zero (no subnormal slow-down). External forces are read,
//! never cleared. After the first step on a model of a given size the stepper allocates nothing.
//!
//! Forward Euler: each step runs `2^level` sub-steps; when `|ü|` exceeds the threshold at any
//! sub-step boundary the whole step is rolled back and retried with `level + 1`. The level sticks
//! (a cheaper level is retried after `relax_after` clean steps); at `max_halvings` the step is
//! accepted with the finest sub-step and reported `saturated`. Stability limits are measured in
//! [`crate::dynamics::stability`] and tabulated in docs/BENCHMARKS.md.

use crate::dynamics::cg::{CgScratch, solve_be};
use crate::dynamics::model::DynamicGrid;

/// Displacements (m) and velocities (m/s) below this are set to zero after each step: far
/// below anything physical, and far enough above the subnormal floats (< 2.2e-308) that
/// their squares (energies) and products with stiffnesses stay normal.
pub const FLUSH_BELOW: f64 = 1e-150;

/// Which scheme advances the model, with its settings.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Integrator {
    /// Explicit Euler (papers): `u += Δt u̇; u̇ += Δt ü` with step halving on `|ü|`.
    ForwardEuler {
        /// Halve the step when any `|ü|` exceeds this (value units / s²).
        accel_threshold: f64,
        /// Most halvings per step (sub-steps ≤ `2^max_halvings`).
        max_halvings: u32,
        /// Clean steps after which one halving is undone (0: never).
        relax_after: u32,
    },
    /// Semi-implicit Euler: `u̇ += Δt ü(u, u̇); u += Δt u̇`.
    SymplecticEuler,
    /// Backward Euler: `(M + Δt C + Δt² K) u̇⁺ = M u̇ + Δt (f − K u)`, `u += Δt u̇⁺`, by Jacobi-PCG.
    BackwardEuler {
        /// Relative residual at which CG stops.
        tolerance: f64,
        /// CG iteration cap.
        max_iterations: u32,
    },
}

impl Integrator {
    /// Forward Euler with the given threshold, 8 halvings at most, relaxing after 1000 steps.
    pub fn forward_euler(accel_threshold: f64) -> Self {
        Self::ForwardEuler {
            accel_threshold,
            max_halvings: 8,
            relax_after: 1000,
        }
    }

    /// Backward Euler to a relative residual of 1e-8 in at most 200 CG iterations.
    pub fn backward_euler() -> Self {
        Self::BackwardEuler {
            tolerance: 1e-8,
            max_iterations: 200,
        }
    }

    /// Short name for tables and logs.
    pub fn name(&self) -> &'static str {
        match self {
            Self::ForwardEuler { .. } => "forward_euler",
            Self::SymplecticEuler => "symplectic_euler",
            Self::BackwardEuler { .. } => "backward_euler",
        }
    }
}

/// What a successful step did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepReport {
    /// Sub-steps taken (forward Euler: `2^level`; others 1).
    pub substeps: u32,
    /// Halvings triggered during this step (forward Euler).
    pub halvings: u32,
    /// Whether forward Euler hit `max_halvings` with `|ü|` still above the threshold.
    pub saturated: bool,
    /// CG iterations (backward Euler).
    pub cg_iterations: u32,
    /// Final CG relative residual (backward Euler).
    pub cg_residual: f64,
    /// Largest `|ü|` seen at a sub-step boundary.
    pub max_accel: f64,
}

/// Why a step was refused; the model is unchanged in every case.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum StepError {
    /// The time step is not a positive finite number.
    #[error("time step {0} is not positive and finite")]
    InvalidDt(f64),
    /// An external force is NaN or infinite; nothing was stepped.
    #[error("external force on node slot {slot} is not finite")]
    NonFiniteForce {
        /// Active slot of the first offending force.
        slot: usize,
    },
    /// A node's value or velocity became non-finite; the step was rolled back.
    #[error("node slot {slot} became non-finite; step rolled back")]
    NonFinite {
        /// Active slot of the first offending node.
        slot: usize,
    },
}

/// Advances a [`DynamicGrid`]; owns only scratch memory.
#[derive(Debug, Clone)]
pub struct Stepper {
    integrator: Integrator,
    level: u32,
    clean_steps: u32,
    u0: Vec<f64>,
    v0: Vec<f64>,
    acc: Vec<f64>,
    rhs: Vec<f64>,
    cg: CgScratch,
}

impl Stepper {
    /// A stepper for `integrator`.
    pub fn new(integrator: Integrator) -> Self {
        Self {
            integrator,
            level: 0,
            clean_steps: 0,
            u0: Vec::new(),
            v0: Vec::new(),
            acc: Vec::new(),
            rhs: Vec::new(),
            cg: CgScratch::default(),
        }
    }

    /// The scheme.
    pub fn integrator(&self) -> &Integrator {
        &self.integrator
    }

    /// Current forward-Euler halving level (sub-steps per step = `2^level`).
    pub fn level(&self) -> u32 {
        self.level
    }

    /// Advance `model` by `dt`, or leave it untouched and say why.
    pub fn step(&mut self, model: &mut DynamicGrid, dt: f64) -> Result<StepReport, StepError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(StepError::InvalidDt(dt));
        }
        let n = model.active_len();
        if let Some(slot) = model.force.iter().position(|f| !f.is_finite()) {
            return Err(StepError::NonFiniteForce { slot });
        }
        for buf in [&mut self.u0, &mut self.v0, &mut self.acc, &mut self.rhs] {
            buf.resize(n, 0.0);
        }
        self.u0.copy_from_slice(&model.u);
        self.v0.copy_from_slice(&model.v);
        let report = match self.integrator {
            Integrator::ForwardEuler {
                accel_threshold,
                max_halvings,
                relax_after,
            } => self.forward_euler(model, dt, accel_threshold, max_halvings, relax_after),
            Integrator::SymplecticEuler => {
                model.acceleration(&model.u, &model.v, &mut self.acc);
                for s in 0..n {
                    model.v[s] += dt * self.acc[s];
                    model.u[s] += dt * model.v[s];
                }
                StepReport {
                    substeps: 1,
                    max_accel: max_abs(&self.acc),
                    ..StepReport::default()
                }
            }
            Integrator::BackwardEuler {
                tolerance,
                max_iterations,
            } => self.backward_euler(model, dt, tolerance, max_iterations),
        };
        if let Some(slot) = (0..n).find(|&s| !(model.u[s].is_finite() && model.v[s].is_finite())) {
            model.u.copy_from_slice(&self.u0);
            model.v.copy_from_slice(&self.v0);
            return Err(StepError::NonFinite { slot });
        }
        // What has decayed to physically nothing becomes exactly nothing: a settled region's
        // displacements otherwise sink into subnormal floats, on which every later step runs
        // tens of times slower (measured: a decayed 216-node model stepped at ~40 µs per
        // forward-Euler sub-step instead of ~1 µs).
        for x in model.u.iter_mut().chain(model.v.iter_mut()) {
            if x.abs() < FLUSH_BELOW {
                *x = 0.0;
            }
        }
        model.advance_time(dt);
        Ok(report)
    }

    fn forward_euler(
        &mut self,
        model: &mut DynamicGrid,
        dt: f64,
        threshold: f64,
        max_halvings: u32,
        relax_after: u32,
    ) -> StepReport {
        if relax_after > 0 && self.clean_steps >= relax_after && self.level > 0 {
            self.level -= 1;
            self.clean_steps = 0;
        }
        let mut halvings = 0;
        loop {
            let subs = 1u32 << self.level.min(30);
            let h = dt / subs as f64;
            let mut max_accel: f64 = 0.0;
            let mut exceeded = false;
            for sub in 0..=subs {
                model.acceleration(&model.u, &model.v, &mut self.acc);
                let a = max_abs(&self.acc);
                max_accel = max_accel.max(a);
                // A NaN acceleration also counts as exceeding (so it triggers halving first).
                if a.is_nan() || a > threshold {
                    exceeded = true;
                    break;
                }
                if sub == subs {
                    break;
                }
                for s in 0..self.acc.len() {
                    model.u[s] += h * model.v[s];
                    model.v[s] += h * self.acc[s];
                }
            }
            if !exceeded {
                self.clean_steps = self.clean_steps.saturating_add(1);
                return StepReport {
                    substeps: subs,
                    halvings,
                    max_accel,
                    ..StepReport::default()
                };
            }
            self.clean_steps = 0;
            if self.level >= max_halvings {
                // Finest step and still above the threshold: finish the step at this level.
                model.u.copy_from_slice(&self.u0);
                model.v.copy_from_slice(&self.v0);
                for _ in 0..subs {
                    model.acceleration(&model.u, &model.v, &mut self.acc);
                    max_accel = max_accel.max(max_abs(&self.acc));
                    for s in 0..self.acc.len() {
                        model.u[s] += h * model.v[s];
                        model.v[s] += h * self.acc[s];
                    }
                }
                return StepReport {
                    substeps: subs,
                    halvings,
                    saturated: true,
                    max_accel,
                    ..StepReport::default()
                };
            }
            model.u.copy_from_slice(&self.u0);
            model.v.copy_from_slice(&self.v0);
            self.level += 1;
            halvings += 1;
        }
    }

    fn backward_euler(
        &mut self,
        model: &mut DynamicGrid,
        dt: f64,
        tolerance: f64,
        max_iterations: u32,
    ) -> StepReport {
        let n = model.active_len();
        for s in 0..n {
            let ku = model.stiffness_apply(&model.u, s);
            self.rhs[s] = model.params.mass[s] * model.v[s] + dt * (model.force[s] - ku);
        }
        // Warm start from the current velocity; solve into `acc`, then swap roles.
        self.acc.copy_from_slice(&model.v);
        let out = solve_be(
            model,
            dt,
            &self.rhs,
            &mut self.acc,
            &mut self.cg,
            tolerance,
            max_iterations,
        );
        let mut max_accel: f64 = 0.0;
        for s in 0..n {
            let v1 = self.acc[s];
            max_accel = max_accel.max(((v1 - model.v[s]) / dt).abs());
            model.v[s] = v1;
            model.u[s] += dt * v1;
        }
        StepReport {
            substeps: 1,
            cg_iterations: out.iterations,
            cg_residual: out.relative_residual,
            max_accel,
            ..StepReport::default()
        }
    }
}

fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0, |m, v| {
        if v.abs() > m || v.is_nan() {
            v.abs()
        } else {
            m
        }
    })
}
