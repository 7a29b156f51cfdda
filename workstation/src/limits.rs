//! Caps on the counts a user gives: generator specs, command-line flags and scene or script
//! fields. Each is checked where the value is parsed, so a typo such as
//! `gen:sphere:1:1000000000000` is an error naming the field and the limit instead of an
//! allocation that exhausts memory or a run that never ends.
//!
//! Each cap is a named constant whose doc comment says why that size; [`OverLimit`] carries the
//! constant's name into the message, e.g. `generator "gen:sphere:1:1000000000000": N =
//! 1000000000000 is over the limit of 20000000 points (MAX_GEN_POINTS)`. Caps that lived here
//! before this module stay where they are: [`crate::fit::MAX_SURFACE_SAMPLES`] and the scene
//! file's `MAX_PHASES`, `MAX_STROKE_POINTS`, `MAX_IMAGE_SIDE`.

use std::fmt;

/// Points an analytic generator samples: `fit gen:SHAPE:...:N`, `generate.points` of scene and
/// sculpt files, `bench-sim --points` (times `1 + --static-objects`) and `bench-force
/// --fit-points`. A fitted point holds its position, normal, neighbour list and a
/// 27-coefficient B-spline fit, a few hundred bytes with the spatial index: 2·10⁷ points is
/// several GB and minutes of fitting at the measured 0.34 s per 67k points, 300× the largest
/// scan in `data/`. Beyond that a count is a typo, not a measurement.
pub const MAX_GEN_POINTS: usize = 20_000_000;

/// Simulation steps: `bench-sim --steps` (one timing row kept per step) and `steps` of a script's
/// `rope` and `relax` operations. 10⁶ steps of the measured ~1 ms step is about 17 minutes of
/// simulated sculpting in one operation (1000 s at the default 1 ms `dt`).
pub const MAX_STEPS: usize = 1_000_000;

/// Grid nodes along a side of `bench-sim --grid`: 256³ = 1.7·10⁷ nodes, under the 2·10⁷ nodes a
/// script's region may hold (`region.spacing`), so the benchmark cannot ask for a field the
/// sculpting commands would refuse.
pub const MAX_BENCH_GRID: usize = 256;

/// `bench-sim --static-objects`: each is a full copy of the fitted sphere. 100 copies already
/// dwarf the one simulated object (the default is 10); the points over all copies are also held
/// to [`MAX_GEN_POINTS`].
pub const MAX_STATIC_OBJECTS: usize = 100;

/// Probe contacts of `bench-force --contacts`: the probe renderer preallocates four contact
/// slots per target contact. The bar is 2,000 contacts; 10⁶ is 500× that and about
/// 100 MB of contact slots.
pub const MAX_CONTACTS: usize = 1_000_000;

/// Timed queries per run of `bench-force --queries`: the query points are generated up front
/// (48 B each) and the recorded probe replay keeps a quarter of them per repeat. 10⁶ is 50× the
/// default and stays under 100 MB with [`MAX_REPEATS`] repeats.
pub const MAX_QUERIES: usize = 1_000_000;

/// Runs of `bench-force --repeats`: they estimate the spread of p99 across runs; 100 runs
/// measure it finely, and each run re-times every query.
pub const MAX_REPEATS: usize = 100;

/// Grid cells per radius of `bench-force --cells`: the analytic field's grid spans the sphere
/// with three cells of margin, about `(2·cells + 6)³` nodes. 200 (10× the R/20) is
/// 6.7·10⁷ nodes, about half a GB; finer grids no longer change the measured force error.
pub const MAX_FORCE_CELLS: f64 = 200.0;

/// A user-given count above its cap: names the field or flag, the value, the limit and the
/// constant that holds it.
#[derive(Debug, Clone, PartialEq)]
pub struct OverLimit {
    /// The field or flag, e.g. `--steps`, `op[2].steps`, or `generator "gen:…": N`.
    pub field: String,
    /// The value given.
    pub value: String,
    /// The limit.
    pub limit: String,
    /// What is counted ("points", "steps").
    pub unit: &'static str,
    /// The constant's name, e.g. `MAX_GEN_POINTS`.
    pub constant: &'static str,
}

impl OverLimit {
    /// The message without the field (for errors that carry the field separately).
    pub fn reason(&self) -> String {
        format!(
            "{} is over the limit of {} {} ({})",
            self.value, self.limit, self.unit, self.constant
        )
    }
}

impl fmt::Display for OverLimit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} = {}", self.field, self.reason())
    }
}

impl std::error::Error for OverLimit {}

/// `Ok(())` when `value ≤ limit`, else [`OverLimit`] naming `field` and `constant`. Use
/// [`cap!`](crate::cap) to pass the constant's name without spelling it twice.
pub fn check<T: PartialOrd + fmt::Display>(
    field: impl Into<String>,
    value: T,
    limit: T,
    unit: &'static str,
    constant: &'static str,
) -> Result<(), OverLimit> {
    if value <= limit {
        Ok(())
    } else {
        Err(OverLimit {
            field: field.into(),
            value: value.to_string(),
            limit: limit.to_string(),
            unit,
            constant,
        })
    }
}

/// `cap!(field, value, CONSTANT, unit)`: [`check`] with the constant's name taken from the
/// expression, e.g. `cap!("--steps", args.steps, MAX_STEPS, "steps")?`.
#[macro_export]
macro_rules! cap {
    ($field:expr, $value:expr, $limit:ident, $unit:expr) => {
        $crate::limits::check($field, $value, $limit, $unit, stringify!($limit))
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_message_names_field_value_limit_and_constant() {
        let e = cap!("--steps", 5_000_000, MAX_STEPS, "steps").unwrap_err();
        assert_eq!(
            e.to_string(),
            "--steps = 5000000 is over the limit of 1000000 steps (MAX_STEPS)"
        );
        assert!(cap!("--steps", MAX_STEPS, MAX_STEPS, "steps").is_ok());
        assert!(cap!("--cells", 200.5, MAX_FORCE_CELLS, "cells").is_err());
    }

    #[test]
    fn a_scene_file_gets_the_scripts_caps_under_its_phase_names() {
        // The live scene reuses the sculpt script's checks; an over-long relax in a phase is
        // reported under the phase that holds it.
        let demo = include_str!("../../examples/live/demo.toml");
        let text = format!(
            "{demo}\n[[phase]]\nname = \"long relax\"\nop = {{ kind = \"relax\", steps = 2000000 }}\n"
        );
        let e = crate::live::scene_file::SceneFile::parse(&text)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(".op.steps: 2000000 is over the limit of 1000000 steps (MAX_STEPS)"),
            "{e}"
        );
    }
}
