//! A bicubic B-spline patch on a clamped uniform `n×n` control net.

use glam::DVec3;

use super::SurfaceError;
use super::basis::cubic_basis;

/// `S(u, v) = Σ_ij N_i(u) N_j(v) P_ij`, `(u, v) ∈ [0,1]²`; `P_ij` at index `i·n + j`.
#[derive(Debug, Clone, PartialEq)]
pub struct BicubicPatch {
    n: usize,
    control: Vec<DVec3>,
}

impl BicubicPatch {
    /// A patch from `n×n` control points (row-major, `4 ≤ n ≤ 256`, all finite).
    pub fn new(n: usize, control: Vec<DVec3>) -> Result<Self, SurfaceError> {
        if !(4..=256).contains(&n) {
            return Err(SurfaceError::BadSize(n));
        }
        if control.len() != n * n {
            return Err(SurfaceError::WrongLength {
                expected: n * n,
                got: control.len(),
            });
        }
        if !control.iter().all(|p| p.is_finite()) {
            return Err(SurfaceError::NonFinite);
        }
        Ok(Self { n, control })
    }

    /// A flat square patch: `z = 0`, `[−half, half]²`, control points evenly spaced.
    pub fn flat(n: usize, half: f64) -> Result<Self, SurfaceError> {
        let mut control = Vec::with_capacity(n * n);
        let step = 2.0 * half / (n.max(2) - 1) as f64;
        for i in 0..n {
            for j in 0..n {
                control.push(DVec3::new(
                    -half + i as f64 * step,
                    -half + j as f64 * step,
                    0.0,
                ));
            }
        }
        Self::new(n, control)
    }

    /// Control points per side.
    pub fn n(&self) -> usize {
        self.n
    }

    /// The control net, row-major.
    pub fn control(&self) -> &[DVec3] {
        &self.control
    }

    /// The control net for in-place updates (e.g. from [`super::DualMap::to_control`]).
    pub fn control_mut(&mut self) -> &mut [DVec3] {
        &mut self.control
    }

    /// The surface point at `(u, v)` (clamped to `[0,1]²`).
    pub fn point(&self, u: f64, v: f64) -> DVec3 {
        self.point_and_tangents(u, v).0
    }

    /// Point and partial derivatives `S_u`, `S_v` at `(u, v)`.
    pub fn point_and_tangents(&self, u: f64, v: f64) -> (DVec3, DVec3, DVec3) {
        let (bu, bv) = (cubic_basis(self.n, u), cubic_basis(self.n, v));
        let (mut s, mut su, mut sv) = (DVec3::ZERO, DVec3::ZERO, DVec3::ZERO);
        for a in 0..4 {
            for b in 0..4 {
                let p = self.control[(bu.first + a) * self.n + bv.first + b];
                s += bu.value[a] * bv.value[b] * p;
                su += bu.deriv[a] * bv.value[b] * p;
                sv += bu.value[a] * bv.deriv[b] * p;
            }
        }
        (s, su, sv)
    }

    /// Unit normal `S_u × S_v / ‖…‖` at `(u, v)`, zero where the patch is degenerate.
    pub fn normal(&self, u: f64, v: f64) -> DVec3 {
        let (_, su, sv) = self.point_and_tangents(u, v);
        su.cross(sv).normalize_or_zero()
    }
}
