//! A coarser stand-in for a large splat set, for frames drawn while the view changes: every
//! k-th splat, its axes grown so the k-times-fewer splats cover the same surface.
//!
//! The stride keeps the caller's order, so a set in a spatially coherent order (Morton order,
//! scan lines, the live session's chunks) thins evenly; each kept splat stands for the k
//! around it, covering k times its area, so both semi-axes grow by √k, and by
//! [`THIN_MARGIN`] more against unevenly spaced neighbours (a gap is worse than an overlap,
//! which the blend averages). Curvatures are per metre and stay as they are.

use crate::Splat;

/// Extra growth of a thinned splat's axes beyond √k.
pub const THIN_MARGIN: f32 = 1.2;

/// At most about `budget` of `splats` into `out` (cleared first), every k-th one with its axes
/// grown by √k·[`THIN_MARGIN`]; returns k (1: everything copied unchanged).
pub fn thin_splats(splats: &[Splat], budget: usize, out: &mut Vec<Splat>) -> usize {
    out.clear();
    let k = splats.len().div_ceil(budget.max(1)).max(1);
    if k == 1 {
        out.extend_from_slice(splats);
        return 1;
    }
    let grow = (k as f32).sqrt() * THIN_MARGIN;
    out.extend(splats.iter().step_by(k).map(|s| Splat {
        radius: s.radius * grow,
        minor_radius: s.minor_radius * grow,
        ..*s
    }));
    k
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_set_is_copied_and_a_large_one_thinned_to_the_budget() {
        let s = Splat::disk([0.0; 3], [0.0, 0.0, 1.0], 0.01, [200; 4]);
        let mut out = Vec::new();
        assert_eq!(thin_splats(&[s; 10], 100, &mut out), 1);
        assert_eq!(out, [s; 10]);
        let many = vec![s; 1_000_001];
        let k = thin_splats(&many, 100_000, &mut out);
        assert_eq!(k, 11);
        assert!(out.len() <= 100_000 && out.len() > 90_000, "{}", out.len());
        let grown = 0.01 * (11f32).sqrt() * THIN_MARGIN;
        assert!((out[0].radius - grown).abs() < 1e-7);
    }
}
