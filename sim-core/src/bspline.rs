//! Uniform quadratic B-splines on `[0,1]` and the trivariate tensor product used by every local
//! field, plus the precomputed refit operator of the papers' Eq. 4.
//!
//! A spline of `size` coefficients per axis (3..=[`MAX_SIZE`]) has `size − 2` uniform knot spans
//! over `[0,1]`; at any parameter exactly three basis functions are non-zero, so evaluating the
//! trivariate spline touches 27 coefficients whatever the size. Basis functions are C¹, sum to
//! one, and reproduce linear functions: `t = Σ_k g_k B_k(t)` with Greville abscissae `g_k`.
//! Contract: pure functions, no allocation except in [`RefitOperator::new`].

use crate::linalg::cholesky_solve;

/// Largest supported number of coefficients per axis.
pub const MAX_SIZE: usize = 6;

/// The three non-zero basis values (and their `t`-derivatives) at a parameter, starting at `span`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Basis1 {
    /// Index of the first of the three non-zero coefficients.
    pub span: usize,
    /// `B_span(t)`, `B_span+1(t)`, `B_span+2(t)`.
    pub value: [f64; 3],
    /// Their derivatives with respect to `t`.
    pub deriv: [f64; 3],
}

/// Evaluate the uniform quadratic basis of `size` coefficients at `t` (clamped to `[0,1]`).
#[inline]
pub fn basis1(size: usize, t: f64) -> Basis1 {
    let m = (size - 2) as f64;
    let ts = t.clamp(0.0, 1.0) * m;
    // One span (the common size 3): no `floor`, which is a library call on baseline x86-64
    // (the same bits: the span is 0 and τ is t).
    let span = if size == 3 {
        0
    } else {
        (ts.floor() as usize).min(size - 3)
    };
    let tau = ts - span as f64;
    let omt = 1.0 - tau;
    Basis1 {
        span,
        value: [0.5 * omt * omt, 0.5 + tau * omt, 0.5 * tau * tau],
        deriv: [-m * omt, m * (1.0 - 2.0 * tau), m * tau],
    }
}

/// Greville abscissa of coefficient `k` (where a linear function's coefficient sits).
#[inline]
pub fn greville(size: usize, k: usize) -> f64 {
    (k as f64 - 0.5) / (size - 2) as f64
}

/// The 27 non-zero tensor-product basis values at `(u,v,w)` and their flat coefficient indices.
///
/// Flat index of coefficient `(a,b,c)` is `(a·size + b)·size + c` (`c` along the local normal).
#[inline]
pub fn basis3(
    size: usize,
    u: f64,
    v: f64,
    w: f64,
    values: &mut [f64; 27],
    index: &mut [usize; 27],
) {
    let (bu, bv, bw) = (basis1(size, u), basis1(size, v), basis1(size, w));
    let mut n = 0;
    for a in 0..3 {
        for b in 0..3 {
            let ab = bu.value[a] * bv.value[b];
            let row = ((bu.span + a) * size + bv.span + b) * size + bw.span;
            for c in 0..3 {
                values[n] = ab * bw.value[c];
                index[n] = row + c;
                n += 1;
            }
        }
    }
}

/// Value and parametric gradient `(∂/∂u, ∂/∂v, ∂/∂w)` of the trivariate spline with `coeffs`.
#[inline]
pub fn eval3(size: usize, coeffs: &[f64], u: f64, v: f64, w: f64) -> (f64, [f64; 3]) {
    let (bu, bv, bw) = (basis1(size, u), basis1(size, v), basis1(size, w));
    let (mut f, mut gu, mut gv, mut gw) = (0.0, 0.0, 0.0, 0.0);
    for a in 0..3 {
        for b in 0..3 {
            let row = ((bu.span + a) * size + bv.span + b) * size + bw.span;
            let c3 = &coeffs[row..row + 3];
            let s = c3[0] * bw.value[0] + c3[1] * bw.value[1] + c3[2] * bw.value[2];
            let sd = c3[0] * bw.deriv[0] + c3[1] * bw.deriv[1] + c3[2] * bw.deriv[2];
            let (ua, ud, vb, vd) = (bu.value[a], bu.deriv[a], bv.value[b], bv.deriv[b]);
            f += ua * vb * s;
            gu += ud * vb * s;
            gv += ua * vd * s;
            gw += ua * vb * sd;
        }
    }
    (f, [gu, gv, gw])
}

/// The value of [`eval3`] alone (the same arithmetic, so the same bits), for sampling grids.
#[inline]
pub fn eval3_value(size: usize, coeffs: &[f64], u: f64, v: f64, w: f64) -> f64 {
    let (bu, bv, bw) = (basis1(size, u), basis1(size, v), basis1(size, w));
    let mut f = 0.0;
    for a in 0..3 {
        for b in 0..3 {
            let row = ((bu.span + a) * size + bv.span + b) * size + bw.span;
            let c3 = &coeffs[row..row + 3];
            let s = c3[0] * bw.value[0] + c3[1] * bw.value[1] + c3[2] * bw.value[2];
            f += bu.value[a] * bv.value[b] * s;
        }
    }
    f
}

/// The refit operator `[(B⊗C⊗D)ᵀ(B⊗C⊗D)]⁻¹(B⊗C⊗D)ᵀ` (papers' Eq. 4) for a fixed local grid.
///
/// Maps field samples `d` at the `samples³` grid nodes of the unit cube (node `(i,j,l)` at
/// `(i,j,l)/(samples−1)`, flat index `(i·samples + j)·samples + l`) to the `size³` coefficients
/// that fit them in least squares. It is the same for every point, so it is built once and shared.
#[derive(Debug, Clone, PartialEq)]
pub struct RefitOperator {
    size: usize,
    samples: usize,
    /// Row-major `size³ × samples³`.
    matrix: Vec<f64>,
}

/// Why a refit operator could not be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RefitError {
    /// The spline size is outside `3..=MAX_SIZE`.
    #[error("spline size {0} is outside 3..={MAX_SIZE}")]
    Size(usize),
    /// Fewer grid samples per axis than coefficients: the system would be underdetermined.
    #[error("{samples} samples per axis cannot determine {size} coefficients per axis")]
    TooFewSamples {
        /// Coefficients per axis.
        size: usize,
        /// Samples per axis.
        samples: usize,
    },
}

impl RefitOperator {
    /// Build the operator for `size` coefficients and `samples ≥ size` grid nodes per axis.
    pub fn new(size: usize, samples: usize) -> Result<Self, RefitError> {
        if !(3..=MAX_SIZE).contains(&size) {
            return Err(RefitError::Size(size));
        }
        if samples < size {
            return Err(RefitError::TooFewSamples { size, samples });
        }
        // 1-D collocation matrix (samples × size); the 3-D one is its Kronecker cube, so the
        // operator is the Kronecker cube of the 1-D pseudo-inverse.
        let mut b1 = vec![0.0; samples * size];
        for i in 0..samples {
            let t = i as f64 / (samples - 1) as f64;
            let bs = basis1(size, t);
            for k in 0..3 {
                b1[i * size + bs.span + k] = bs.value[k];
            }
        }
        // pinv = (BᵀB)⁻¹ Bᵀ, column by column.
        let mut pinv = vec![0.0; size * samples];
        for i in 0..samples {
            let mut btb = vec![0.0; size * size];
            for r in 0..samples {
                for a in 0..size {
                    for c in 0..size {
                        btb[a * size + c] += b1[r * size + a] * b1[r * size + c];
                    }
                }
            }
            let mut rhs: Vec<f64> = (0..size).map(|a| b1[i * size + a]).collect();
            let ok = cholesky_solve(&mut btb, &mut rhs, size);
            debug_assert!(ok, "uniform B-spline collocation is full rank");
            for a in 0..size {
                pinv[a * samples + i] = rhs[a];
            }
        }
        let (c3, s3) = (size * size * size, samples * samples * samples);
        let mut matrix = vec![0.0; c3 * s3];
        for a in 0..size {
            for b in 0..size {
                for c in 0..size {
                    let row = ((a * size + b) * size + c) * s3;
                    for i in 0..samples {
                        for j in 0..samples {
                            let ab = pinv[a * samples + i] * pinv[b * samples + j];
                            for l in 0..samples {
                                matrix[row + (i * samples + j) * samples + l] =
                                    ab * pinv[c * samples + l];
                            }
                        }
                    }
                }
            }
        }
        Ok(Self {
            size,
            samples,
            matrix,
        })
    }

    /// Coefficients per axis.
    pub fn size(&self) -> usize {
        self.size
    }

    /// Grid samples per axis.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Unit-cube coordinates of sample node `(i, j, l)`.
    pub fn node(&self, i: usize, j: usize, l: usize) -> [f64; 3] {
        let s = (self.samples - 1) as f64;
        [i as f64 / s, j as f64 / s, l as f64 / s]
    }

    /// `coeffs = M · samples` (lengths `size³` and `samples³`). Allocation-free.
    pub fn apply(&self, samples: &[f64], coeffs: &mut [f64]) {
        let s3 = self.samples.pow(3);
        assert_eq!(samples.len(), s3, "refit expects samples³ values");
        assert_eq!(
            coeffs.len(),
            self.size.pow(3),
            "refit writes size³ coefficients"
        );
        for (row, out) in self.matrix.chunks_exact(s3).zip(coeffs.iter_mut()) {
            *out = row.iter().zip(samples).map(|(m, d)| m * d).sum();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partition_of_unity_and_linear_precision() {
        for size in 3..=MAX_SIZE {
            for i in 0..=50 {
                let t = i as f64 / 50.0;
                let b = basis1(size, t);
                let sum: f64 = b.value.iter().sum();
                let lin: f64 = (0..3)
                    .map(|k| b.value[k] * greville(size, b.span + k))
                    .sum();
                let dsum: f64 = b.deriv.iter().sum();
                assert!((sum - 1.0).abs() < 1e-14 && (lin - t).abs() < 1e-14 && dsum.abs() < 1e-12);
            }
        }
    }

    #[test]
    fn refit_reproduces_a_spline_from_its_samples() {
        for (size, samples) in [(3, 3), (3, 5), (4, 6)] {
            let op = RefitOperator::new(size, samples).unwrap();
            let coeffs: Vec<f64> = (0..size.pow(3))
                .map(|i| ((i * 37) % 11) as f64 - 5.0)
                .collect();
            let mut d = vec![0.0; samples.pow(3)];
            for i in 0..samples {
                for j in 0..samples {
                    for l in 0..samples {
                        let [u, v, w] = op.node(i, j, l);
                        d[(i * samples + j) * samples + l] = eval3(size, &coeffs, u, v, w).0;
                    }
                }
            }
            let mut back = vec![0.0; size.pow(3)];
            op.apply(&d, &mut back);
            for (a, b) in coeffs.iter().zip(&back) {
                assert!(
                    (a - b).abs() < 1e-9,
                    "size {size} samples {samples}: {a} vs {b}"
                );
            }
        }
        assert!(RefitOperator::new(4, 3).is_err() && RefitOperator::new(2, 3).is_err());
    }
}
