//! The stiffness operator `K` of a [`DynamicGrid`] (anchors plus neighbour springs) in a
//! branch-free table, and the quantities derived from it: `K x`, its diagonal, accelerations,
//! energy and the Gershgorin bound on the highest natural frequency.
//!
//! Contract: the table is rebuilt row by row whenever node parameters change, so `K` always
//! matches the parameters; `K x` at a slot reads six neighbours and allocates nothing. A
//! neighbour that is fixed (inactive) or absent is stored as the slot itself with stiffness 0
//! (a fixed neighbour's spring lives in the diagonal), so the inner loop has no branches.

use crate::dynamics::model::{ABSENT, DynamicGrid, FIXED, ParamArrays};

/// `K = diag − offdiag`, row per active slot.
#[derive(Debug, Clone, Default)]
pub(crate) struct SpringTable {
    /// `a_s + Σ_j k_sj` over every spring of the slot (fixed neighbours included).
    diag: Vec<f64>,
    /// Neighbour slot per spring (the slot itself where there is no active neighbour).
    idx: Vec<[u32; 6]>,
    /// Spring constant per neighbour (0 where there is no active neighbour).
    k: Vec<[f64; 6]>,
}

impl SpringTable {
    /// The table for neighbour lists `nbr` and parameters `p`.
    pub(crate) fn build(nbr: &[[u32; 6]], p: &ParamArrays) -> Self {
        let n = nbr.len();
        let mut t = Self {
            diag: vec![0.0; n],
            idx: vec![[0; 6]; n],
            k: vec![[0.0; 6]; n],
        };
        for s in 0..n {
            t.update_row(s, nbr, p);
        }
        t
    }

    /// Recompute row `s` from the current parameters.
    pub(crate) fn update_row(&mut self, s: usize, nbr: &[[u32; 6]], p: &ParamArrays) {
        let ks = p.stiffness[s];
        let mut diag = p.anchor[s];
        for (q, &j) in nbr[s].iter().enumerate() {
            let (idx, k) = match j {
                ABSENT => (s as u32, 0.0),
                FIXED => {
                    diag += ks;
                    (s as u32, 0.0)
                }
                j => {
                    let k = 0.5 * (ks + p.stiffness[j as usize]);
                    diag += k;
                    (j, k)
                }
            };
            self.idx[s][q] = idx;
            self.k[s][q] = k;
        }
        self.diag[s] = diag;
    }
}

impl DynamicGrid {
    /// `(K x)_s`.
    #[inline]
    pub(crate) fn stiffness_apply(&self, x: &[f64], s: usize) -> f64 {
        let t = &self.springs;
        let (idx, k) = (&t.idx[s], &t.k[s]);
        let mut off = 0.0;
        for q in 0..6 {
            off += k[q] * x[idx[q] as usize];
        }
        t.diag[s] * x[s] - off
    }

    /// `K_ss`.
    #[inline]
    pub(crate) fn stiffness_diag(&self, s: usize) -> f64 {
        self.springs.diag[s]
    }

    /// Acceleration `(f − c u̇ − K u)/m` of every slot for the state `(x, xd)`, into `out`.
    pub(crate) fn acceleration(&self, x: &[f64], xd: &[f64], out: &mut [f64]) {
        let p = &self.params;
        for s in 0..out.len() {
            let f = self.force[s] - p.damping[s] * xd[s] - self.stiffness_apply(x, s);
            out[s] = f / p.mass[s];
        }
    }

    /// `(K x)_s`: the elastic force of displacement vector `x` at slot `s` (for checks).
    pub fn stiffness_times(&self, x: &[f64], s: usize) -> f64 {
        self.stiffness_apply(x, s)
    }

    /// Current acceleration of every slot, into `out` (one entry per slot).
    pub fn acceleration_into(&self, out: &mut [f64]) {
        self.acceleration(&self.u, &self.v, out);
    }

    /// Mechanical energy `½ u̇ᵀMu̇ + ½ uᵀKu` (J).
    pub fn energy(&self) -> f64 {
        let p = &self.params;
        (0..self.u.len())
            .map(|s| {
                0.5 * (p.mass[s] * self.v[s] * self.v[s]
                    + self.u[s] * self.stiffness_apply(&self.u, s))
            })
            .sum()
    }

    /// Upper bound (Gershgorin) on the highest natural angular frequency `ω_max = √λ_max(M⁻¹K)`.
    pub fn omega_max_bound(&self) -> f64 {
        let t = &self.springs;
        (0..self.u.len())
            .map(|s| ((t.diag[s] + t.k[s].iter().sum::<f64>()) / self.params.mass[s]).sqrt())
            .fold(0.0, f64::max)
    }
}
