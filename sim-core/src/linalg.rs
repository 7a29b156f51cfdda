//! Small dense linear algebra for the fits: symmetric 3×3 eigen-decomposition (PCA normals) and
//! an in-place Cholesky solve for the local B-spline normal equations.
//!
//! Contract: no allocation; inputs are row-major slices owned by the caller; failures are
//! reported by return value (never a panic, never a NaN written as a result).

use glam::{DMat3, DVec3};

/// Eigenvalues (ascending) and unit eigenvectors of a symmetric 3×3 matrix by cyclic Jacobi.
///
/// The result is exact to a few ulps for any finite symmetric input; returns `None` if the input
/// holds a non-finite entry.
pub fn sym3_eigen(m: DMat3) -> Option<([f64; 3], [DVec3; 3])> {
    let mut a = [
        [m.x_axis.x, m.y_axis.x, m.z_axis.x],
        [m.x_axis.y, m.y_axis.y, m.z_axis.y],
        [m.x_axis.z, m.y_axis.z, m.z_axis.z],
    ];
    if a.iter().flatten().any(|v| !v.is_finite()) {
        return None;
    }
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _sweep in 0..32 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        let diag = a[0][0].abs() + a[1][1].abs() + a[2][2].abs();
        if off <= f64::EPSILON * diag * 1e-3 || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for row in a.iter_mut() {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (row_p, row_q) = (a[p], a[q]);
            for k in 0..3 {
                a[p][k] = c * row_p[k] - s * row_q[k];
                a[q][k] = s * row_p[k] + c * row_q[k];
            }
            for row in v.iter_mut() {
                let (vkp, vkq) = (row[p], row[q]);
                row[p] = c * vkp - s * vkq;
                row[q] = s * vkp + c * vkq;
            }
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| a[i][i].total_cmp(&a[j][j]));
    let vals = order.map(|i| a[i][i]);
    let vecs = order.map(|i| DVec3::new(v[0][i], v[1][i], v[2][i]).normalize_or_zero());
    Some((vals, vecs))
}

/// Solve `A x = b` in place for a symmetric positive definite `n×n` matrix (row-major, only the
/// upper triangle is read). On success `b` holds `x` and `a` is overwritten by its factor.
///
/// Returns `false` (leaving `b` unspecified but finite inputs untouched elsewhere) when a pivot is
/// not positive or not finite, i.e. the matrix is not numerically positive definite.
pub fn cholesky_solve(a: &mut [f64], b: &mut [f64], n: usize) -> bool {
    debug_assert!(a.len() >= n * n && b.len() >= n);
    // Factor A = Uᵀ U, U upper triangular, stored in the upper triangle of `a`. Right-looking:
    // after row i is final, subtract its outer product from the trailing block, row by row, so
    // every inner loop runs over contiguous memory.
    for i in 0..n {
        let d = a[i * n + i];
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        let inv = 1.0 / d;
        a[i * n + i] = d;
        for v in &mut a[i * n + i + 1..(i + 1) * n] {
            *v *= inv;
        }
        let (head, tail) = a.split_at_mut((i + 1) * n);
        let urow = &head[i * n..(i + 1) * n];
        for k in i + 1..n {
            let f = urow[k];
            if f != 0.0 {
                let row = &mut tail[(k - i - 1) * n..(k - i) * n];
                for (x, u) in row[k..].iter_mut().zip(&urow[k..]) {
                    *x -= f * u;
                }
            }
        }
    }
    // Forward: Uᵀ y = b.
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= a[k * n + i] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
    // Backward: U x = y.
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= a[i * n + k] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
    b[..n].iter().all(|v| v.is_finite())
}

/// [`cholesky_solve`] for a compile-time size: the same algorithm on fixed-size rows, which the
/// compiler unrolls and vectorises (the 27×27 local fit is the hot case).
pub fn cholesky_solve_fixed<const N: usize>(a: &mut [[f64; N]; N], b: &mut [f64; N]) -> bool {
    for i in 0..N {
        let d = a[i][i];
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        let inv = 1.0 / d;
        a[i][i] = d;
        for v in &mut a[i][i + 1..] {
            *v *= inv;
        }
        let (head, tail) = a.split_at_mut(i + 1);
        let urow = &head[i];
        for (k, row) in (i + 1..N).zip(tail.iter_mut()) {
            let f = urow[k];
            for j in k..N {
                row[j] -= f * urow[j];
            }
        }
    }
    for i in 0..N {
        let mut s = b[i];
        for k in 0..i {
            s -= a[k][i] * b[k];
        }
        b[i] = s / a[i][i];
    }
    for i in (0..N).rev() {
        let mut s = b[i];
        for k in i + 1..N {
            s -= a[i][k] * b[k];
        }
        b[i] = s / a[i][i];
    }
    b.iter().all(|v| v.is_finite())
}

/// An orthonormal pair of tangents completing the unit vector `n` to a right-handed frame.
pub fn tangent_frame(n: DVec3) -> (DVec3, DVec3) {
    let t1 = n.any_orthonormal_vector();
    (t1, n.cross(t1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigen_of_diagonal_and_rotated() {
        let (vals, vecs) = sym3_eigen(DMat3::from_diagonal(DVec3::new(3.0, 1.0, 2.0))).unwrap();
        assert_eq!(vals, [1.0, 2.0, 3.0]);
        assert!((vecs[0].y.abs() - 1.0).abs() < 1e-12);
        let r = DMat3::from_euler(glam::EulerRot::XYZ, 0.3, -1.1, 0.7);
        let m = r * DMat3::from_diagonal(DVec3::new(5.0, 0.0, 1e-3)) * r.transpose();
        let (vals, vecs) = sym3_eigen(m).unwrap();
        assert!(vals[0].abs() < 1e-12 && (vals[2] - 5.0).abs() < 1e-12);
        assert!((m * vecs[0]).length() < 1e-12);
        assert!(sym3_eigen(DMat3::from_diagonal(DVec3::new(f64::NAN, 0.0, 0.0))).is_none());
    }

    #[test]
    fn cholesky_solves_and_rejects_indefinite() {
        let mut a = [4.0, 2.0, 0.0, 2.0, 5.0, 1.0, 0.0, 1.0, 3.0];
        let orig = a;
        let mut b = [1.0, 2.0, 3.0];
        assert!(cholesky_solve(&mut a, &mut b, 3));
        for i in 0..3 {
            let r: f64 = (0..3).map(|j| orig[i * 3 + j] * b[j]).sum();
            assert!((r - [1.0, 2.0, 3.0][i]).abs() < 1e-12);
        }
        let mut a = [1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky_solve(&mut a, &mut [1.0, 1.0], 2));
    }
}
