//! Clamped uniform cubic B-spline basis on `[0, 1]` and the dual map's matrix `A`.
//!
//! `n ≥ 4` control points per direction; knots `0,0,0,0, 1/(n−3), …, (n−4)/(n−3), 1,1,1,1`, so
//! the patch interpolates its corner control points and is C² inside.

/// Knot `i` (0-based) of the clamped uniform cubic knot vector with `n` control points.
#[inline]
fn knot(n: usize, i: usize) -> f64 {
    let spans = (n - 3) as f64;
    (i.saturating_sub(3).min(n - 3)) as f64 / spans
}

/// The four non-zero cubic basis values (and first derivatives in the parameter) at `t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CubicBasis {
    /// Index of the first of the four non-zero basis functions.
    pub first: usize,
    /// `N_first(t) … N_first+3(t)`; they sum to one.
    pub value: [f64; 4],
    /// Their derivatives `dN/dt`.
    pub deriv: [f64; 4],
}

/// Evaluate the clamped uniform cubic basis of `n` (≥ 4) functions at `t` (clamped to `[0,1]`).
///
/// Cox–de Boor in the triangular form of Piegl & Tiller (A2.2), derivatives from the quadratic
/// level (A2.3, first order). No allocation.
pub fn cubic_basis(n: usize, t: f64) -> CubicBasis {
    debug_assert!(n >= 4);
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let spans = n - 3;
    // Knot span index s with knot(s) ≤ t < knot(s+1), s in 3..=n−1.
    let s = 3 + ((t * spans as f64).floor() as usize).min(spans - 1);
    let mut left = [0.0; 4];
    let mut right = [0.0; 4];
    // ndu[j][r]: basis of degree j (upper triangle) and knot differences (lower).
    let mut ndu = [[0.0f64; 4]; 4];
    ndu[0][0] = 1.0;
    for j in 1..=3 {
        left[j] = t - knot(n, s + 1 - j);
        right[j] = knot(n, s + j) - t;
        let mut saved = 0.0;
        for r in 0..j {
            ndu[j][r] = right[r + 1] + left[j - r];
            let temp = ndu[r][j - 1] / ndu[j][r];
            ndu[r][j] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        ndu[j][j] = saved;
    }
    let mut value = [0.0; 4];
    let mut deriv = [0.0; 4];
    for r in 0..4 {
        value[r] = ndu[r][3];
        // dN_{s−3+r,3} = 3 (N_{s−3+r,2}/(t_{s+r} − t_{s−3+r}) − N_{s−2+r,2}/(t_{s+r+1} − t_{s−2+r}))
        let a = if r >= 1 {
            ndu[r - 1][2] / ndu[3][r - 1]
        } else {
            0.0
        };
        let b = if r <= 2 { ndu[r][2] / ndu[3][r] } else { 0.0 };
        deriv[r] = 3.0 * (a - b);
    }
    CubicBasis {
        first: s - 3,
        value,
        deriv,
    }
}

/// The parameter of mass point `k` of `n`: uniform, `k / (n − 1)`.
#[inline]
pub fn mass_parameter(n: usize, k: usize) -> f64 {
    k as f64 / (n - 1) as f64
}

/// `A[k][j] = N_j(u_k)` at the uniform mass parameters, row-major `n×n`.
///
/// Invertible for every `n ≥ 4`: `u_k` lies inside the support of `N_k` (Schoenberg–Whitney),
/// since `(k−3)/(n−3) < k/(n−1) < (k+1)/(n−3)` for interior `k` and the ends interpolate.
pub fn collocation_matrix(n: usize) -> Vec<f64> {
    let mut a = vec![0.0; n * n];
    for k in 0..n {
        let b = cubic_basis(n, mass_parameter(n, k));
        for r in 0..4 {
            a[k * n + b.first + r] = b.value[r];
        }
    }
    a
}

/// Invert the row-major `n×n` matrix `a` by Gauss–Jordan with partial pivoting.
///
/// `None` if a pivot falls below `1e-12` of the largest entry (numerically singular).
pub fn invert(a: &[f64], n: usize) -> Option<Vec<f64>> {
    let mut m = a.to_vec();
    let mut inv = vec![0.0; n * n];
    for i in 0..n {
        inv[i * n + i] = 1.0;
    }
    let scale = a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    for col in 0..n {
        let pivot =
            (col..n).max_by(|&x, &y| m[x * n + col].abs().total_cmp(&m[y * n + col].abs()))?;
        if m[pivot * n + col].abs() < 1e-12 * scale {
            return None;
        }
        for c in 0..n {
            m.swap(col * n + c, pivot * n + c);
            inv.swap(col * n + c, pivot * n + c);
        }
        let d = 1.0 / m[col * n + col];
        for c in 0..n {
            m[col * n + c] *= d;
            inv[col * n + c] *= d;
        }
        for r in 0..n {
            let f = m[r * n + col];
            if r != col && f != 0.0 {
                for c in 0..n {
                    m[r * n + c] -= f * m[col * n + c];
                    inv[r * n + c] -= f * inv[col * n + c];
                }
            }
        }
    }
    Some(inv)
}
