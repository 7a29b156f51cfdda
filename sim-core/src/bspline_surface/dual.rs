//! The mass-spring ↔ control-net dual map of seed 004 §4.1 (after Dachille & Qin).
//!
//! Mass point `(k, l)` sits at the surface point `S(u_k, u_l)` with uniform parameters, so the
//! mesh `M` and the control net `P` (both `n×n`, one `DVec3` each) are related by
//! `M = A P Aᵀ` and `P = A⁻¹ M A⁻ᵀ` with `A[k][j] = N_j(u_k)`. `A` and `A⁻¹` are computed once;
//! each map costs `2n³` vector multiply-adds into a scratch buffer held here (no allocation).

use glam::DVec3;

use super::SurfaceError;
use super::basis::{collocation_matrix, invert};

/// `A`, `A⁻¹` and the scratch for the two maps.
#[derive(Debug, Clone)]
pub struct DualMap {
    n: usize,
    a: Vec<f64>,
    a_inv: Vec<f64>,
    scratch: Vec<DVec3>,
}

impl DualMap {
    /// The map for an `n×n` mesh and net (`4 ≤ n ≤ 256`).
    pub fn new(n: usize) -> Result<Self, SurfaceError> {
        if !(4..=256).contains(&n) {
            return Err(SurfaceError::BadSize(n));
        }
        let a = collocation_matrix(n);
        let a_inv = invert(&a, n).ok_or(SurfaceError::Singular)?;
        Ok(Self {
            n,
            a,
            a_inv,
            scratch: vec![DVec3::ZERO; n * n],
        })
    }

    /// Points per side.
    pub fn n(&self) -> usize {
        self.n
    }

    /// `A`, row-major.
    pub fn a(&self) -> &[f64] {
        &self.a
    }

    /// Mass points from control points: `mesh = A · control · Aᵀ` (both row-major `n×n`).
    pub fn to_mesh(&mut self, control: &[DVec3], mesh: &mut [DVec3]) {
        sandwich(self.n, &self.a, control, &mut self.scratch, mesh);
    }

    /// Control points from mass points: `control = A⁻¹ · mesh · A⁻ᵀ`.
    pub fn to_control(&mut self, mesh: &[DVec3], control: &mut [DVec3]) {
        sandwich(self.n, &self.a_inv, mesh, &mut self.scratch, control);
    }
}

/// `out = B · x · Bᵀ` for row-major `n×n` `B` (scalars) and `x` (vectors).
fn sandwich(n: usize, b: &[f64], x: &[DVec3], tmp: &mut [DVec3], out: &mut [DVec3]) {
    assert!(
        x.len() == n * n && out.len() == n * n,
        "dual map: buffers must hold n×n points"
    );
    // tmp = B x
    for k in 0..n {
        for j in 0..n {
            let mut s = DVec3::ZERO;
            for i in 0..n {
                s += b[k * n + i] * x[i * n + j];
            }
            tmp[k * n + j] = s;
        }
    }
    // out = tmp Bᵀ
    for k in 0..n {
        for l in 0..n {
            let mut s = DVec3::ZERO;
            for j in 0..n {
                s += tmp[k * n + j] * b[l * n + j];
            }
            out[k * n + l] = s;
        }
    }
}
