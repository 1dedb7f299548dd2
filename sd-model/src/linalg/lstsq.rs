//! The toolkit's one linear least-squares solver: column-scaled, rank-revealing, with the
//! covariance of the solution.
//!
//! # Math
//!
//! For `min ‖A x − b‖₂` with `A` m×n, the columns are first scaled to unit Euclidean norm,
//! `Aₛ = A S⁻¹`, `S = diag(‖a_j‖)` (a zero column keeps scale 1), so that the rank decision sees
//! the conditioning of the basis and not the units of its columns. When `m > n` the augmented
//! matrix `[Aₛ b]` is reduced by a Householder QR ([`qr_r`]: faer's blocked kernel at an exact
//! power-of-two column scale): its thin `R` factor
//! is `[[R, c], [0, ρ]]` with `c = Qᵀb` and `ρ` the residual norm, so `Q` is never formed. The
//! n×n `R` (or `Aₛ` itself when `m ≤ n`) is then decomposed by an SVD, `R = U Σ Vᵀ`, and
//!
//! ```text
//! yₛ = Σ_{σ_k > τ} v_k (u_kᵀ c) / σ_k,     Cₛ = Σ_{σ_k > τ} v_k v_kᵀ / σ_k²,     τ = 1e-10·σ_max,
//! x = S⁻¹ yₛ,                               cov = S⁻¹ Cₛ S⁻¹ = (AᵀA)⁺ on the kept subspace.
//! ```
//!
//! `cov` is the covariance of `x` for unit-variance, uncorrelated residuals; multiply by the
//! residual variance for the estimate's covariance. The singular values cut by `τ` are reported
//! through [`LstSq::rank`].
//!
//! # Accuracy
//!
//! QR followed by the SVD of `R` is backward stable (Golub & Van Loan, *Matrix Computations*,
//! 4th ed., §5.3.5 and §5.4.5, "R-SVD"): the computed solution is the exact one of a problem
//! perturbed by `O(m n ε)‖A‖` in the scaled columns, so the relative error is
//! `O(ε κ(Aₛ))` for a small residual — not `ε κ²` as for the normal equations. The cut at
//! `1e-10·σ_max` keeps every direction that is determined to at least six digits.
//!
//! # Cost
//!
//! `O(m n²)` (the QR) plus `O(n³)` (the SVD of `R`); for the tall problems of the fits
//! (`m ≫ n`) the QR dominates.

use faer::MatRef;
use nalgebra::{DMatrix, DVector};

use crate::linalg::convert::{from_faer, svd, to_faer};
use crate::linalg::qr::qr_r;
use crate::{ModelError, Result};

/// Singular values below `RANK_CUT · σ_max` of the column-scaled matrix are treated as zero.
pub const RANK_CUT: f64 = 1e-10;

/// A least-squares solution.
#[derive(Debug, Clone)]
pub struct LstSq {
    /// The minimum-norm minimiser of `‖A x − b‖₂` (in the scaled columns' metric).
    pub x: DVector<f64>,
    /// `(AᵀA)⁺` on the kept subspace: the covariance of `x` for unit-variance residuals.
    pub cov: DMatrix<f64>,
    /// The number of singular values above the cut (`n` for a well-posed problem).
    pub rank: usize,
}

/// The Euclidean norm of each column (1 for a zero one), accumulated relative to the column's
/// largest magnitude so that no square under- or overflows.
fn column_scales(a: MatRef<'_, f64>) -> Vec<f64> {
    (0..a.ncols())
        .map(|c| {
            let amax = a.col(c).iter().fold(0.0f64, |m, v| m.max(v.abs()));
            if amax > 0.0 {
                let inv = 1.0 / amax;
                let ss: f64 = a.col(c).iter().map(|v| (v * inv).powi(2)).sum();
                amax * ss.sqrt()
            } else {
                1.0
            }
        })
        .collect()
}

/// The scaled matrix reduced to at most n rows, `(R, c)` with `‖Aₛ y − b‖² = ‖R y − c‖² + ρ²`.
fn reduce(a: MatRef<'_, f64>, b: &[f64], scale: &[f64]) -> (faer::Mat<f64>, Vec<f64>) {
    let (m, n) = (a.nrows(), a.ncols());
    let width = if m > n { n + 1 } else { n };
    let mut aug = faer::Mat::<f64>::zeros(m, width);
    for (c, &sc) in scale.iter().enumerate() {
        let inv = 1.0 / sc;
        for (v, x) in aug.col_as_slice_mut(c).iter_mut().zip(a.col(c).iter()) {
            *v = x * inv;
        }
    }
    if m <= n {
        return (aug, b.to_vec());
    }
    aug.col_as_slice_mut(n).copy_from_slice(b);
    let rf = qr_r(aug);
    let r = faer::Mat::<f64>::from_fn(n, n, |i, j| rf[(i, j)]);
    let c = (0..n).map(|i| rf[(i, n)]).collect();
    (r, c)
}

/// `min ‖A x − b‖₂` for a faer matrix (see the [module](self) docs for the method).
///
/// # Errors
/// [`ModelError::DimensionMismatch`] when `b` does not have `A`'s rows;
/// [`ModelError::NonFinite`] for a NaN or infinite entry; [`ModelError::Singular`] when `A` has
/// no nonzero singular value; [`ModelError::NotConverged`] when the SVD fails.
pub fn lstsq_faer(a: MatRef<'_, f64>, b: &[f64]) -> Result<LstSq> {
    let (m, n) = (a.nrows(), a.ncols());
    if b.len() != m {
        return Err(ModelError::DimensionMismatch {
            what: "least-squares right-hand side".into(),
            expected: format!("{m} rows"),
            found: format!("{}", b.len()),
        });
    }
    let finite = (0..n).all(|c| a.col(c).iter().all(|v| v.is_finite()));
    if !finite || b.iter().any(|v| !v.is_finite()) {
        return Err(ModelError::NonFinite {
            what: "the least-squares problem".into(),
        });
    }
    let scale = column_scales(a);
    let (r, c) = reduce(a, b, &scale);
    let (u, s, v) = svd(&from_faer(r.as_ref()))?;
    let smax = s.iter().cloned().fold(0.0, f64::max);
    if !(smax.is_finite() && smax > 0.0) {
        return Err(ModelError::Singular {
            what: "the least-squares matrix (all columns zero)".into(),
        });
    }
    let mut x = DVector::zeros(n);
    let mut cov = DMatrix::zeros(n, n);
    let mut rank = 0;
    for (k, &sv) in s.iter().enumerate() {
        if sv > RANK_CUT * smax {
            rank += 1;
            let uc: f64 = (0..c.len()).map(|i| u[(i, k)] * c[i]).sum();
            let vk = v.column(k);
            x.axpy(uc / sv, &vk, 1.0);
            cov.ger(1.0 / (sv * sv), &vk, &vk, 1.0);
        }
    }
    for i in 0..n {
        x[i] /= scale[i];
        for j in 0..n {
            cov[(i, j)] /= scale[i] * scale[j];
        }
    }
    Ok(LstSq { x, cov, rank })
}

/// `min ‖A x − b‖₂` for nalgebra arguments; see [`lstsq_faer`].
///
/// # Errors
/// As [`lstsq_faer`].
pub fn lstsq(a: &DMatrix<f64>, b: &DVector<f64>) -> Result<LstSq> {
    lstsq_faer(to_faer(a).as_ref(), b.as_slice())
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A tall problem with columns twelve decades apart: the solution of a consistent system is
    /// recovered to `n·ε·κ(Aₛ)`, and the covariance is the inverse of the normal matrix.
    #[test]
    fn recovers_a_badly_scaled_consistent_system() {
        let (m, n) = (300, 7);
        let a = DMatrix::from_fn(m, n, |r, c| {
            let t = r as f64 / m as f64;
            ((c + 1) as f64 * 2.3 * t).sin() * 10f64.powi(2 * c as i32 - 6)
        });
        let x0 = DVector::from_fn(n, |i, _| (i as f64 + 1.0) * 10f64.powi(6 - 2 * i as i32));
        let b = &a * &x0;
        let ls = lstsq(&a, &b).unwrap();
        assert_eq!(ls.rank, n);
        let err = ((&ls.x - &x0).component_div(&x0)).amax();
        assert!(err < 1e-8, "relative error {err:e}");
        // checked in the scaled columns, where both factors are O(1)
        let s = DMatrix::from_diagonal(&DVector::from_fn(n, |c, _| a.column(c).norm()));
        let si = s.clone().try_inverse().unwrap();
        let normal = &si * a.transpose() * &a * &si;
        let ident = &normal * (&s * &ls.cov * &s);
        let off = (ident - DMatrix::identity(n, n)).amax();
        assert!(off < 1e-9, "(AₛᵀAₛ)·covₛ − I = {off:e}");
    }

    /// A rank-deficient problem (two equal columns) gives the minimum-norm solution and rank n−1.
    #[test]
    fn rank_deficient_gives_minimum_norm() {
        let a = DMatrix::from_row_slice(4, 2, &[1.0, 1.0, 2.0, 2.0, 3.0, 3.0, 4.0, 4.0]);
        let b = DVector::from_row_slice(&[2.0, 4.0, 6.0, 8.0]);
        let ls = lstsq(&a, &b).unwrap();
        assert_eq!(ls.rank, 1);
        assert!((ls.x[0] - 1.0).abs() < 1e-12 && (ls.x[1] - 1.0).abs() < 1e-12);
    }

    /// A wide problem (m < n) takes the SVD path directly and still fits exactly.
    #[test]
    fn wide_problem_is_solved_exactly() {
        let a = DMatrix::from_row_slice(2, 3, &[1.0, 0.0, 1.0, 0.0, 2.0, 0.0]);
        let b = DVector::from_row_slice(&[2.0, 4.0]);
        let ls = lstsq(&a, &b).unwrap();
        assert!((&a * &ls.x - &b).amax() < 1e-12);
        assert!((ls.x[0] - 1.0).abs() < 1e-12 && (ls.x[2] - 1.0).abs() < 1e-12);
    }

    /// NaN or infinity anywhere, a wrong shape or an all-zero matrix: a named error, no panic.
    #[test]
    fn bad_input_is_an_error() {
        let g = DVector::from_row_slice(&[1.0, 2.0]);
        let j = DMatrix::from_row_slice(2, 1, &[1.0, f64::NAN]);
        assert!(matches!(lstsq(&j, &g), Err(ModelError::NonFinite { .. })));
        let j = DMatrix::from_row_slice(2, 1, &[1.0, 2.0]);
        let gi = DVector::from_row_slice(&[1.0, f64::INFINITY]);
        assert!(matches!(lstsq(&j, &gi), Err(ModelError::NonFinite { .. })));
        let g3 = DVector::from_row_slice(&[1.0, 2.0, 3.0]);
        assert!(matches!(
            lstsq(&j, &g3),
            Err(ModelError::DimensionMismatch { .. })
        ));
        let z = DMatrix::zeros(2, 2);
        assert!(matches!(lstsq(&z, &g), Err(ModelError::Singular { .. })));
    }
}
