//! Lyapunov equations by the Bartels–Stewart method on the complex Schur form.
//!
//! Continuous: `A P + P Aᵀ + Q = 0`. Discrete (Stein): `A P Aᵀ − P + Q = 0`.
//! With `A = U T Uᴴ` (T upper triangular) and `P̃ = Uᴴ P U`, the columns of P̃ follow by
//! back-substitution from the last (Bartels & Stewart, CACM 15(9), 1972; Kitagawa 1977 for the
//! discrete case):
//! - CT: `(T + t̄_jj I) p_j = −q_j − Σ_{k>j} t̄_jk p_k`
//! - DT: `(t̄_jj T − I) p_j = −q_j − T Σ_{k>j} t̄_jk p_k`
//!
//! Cost O(n³); backward stable; the result is symmetrised and returned real (the imaginary part
//! is rounding for real data). A unique solution needs `λ_i + λ̄_j ≠ 0` (CT) or `λ_i λ̄_j ≠ 1`
//! (DT); near-violations are reported as singular.

use super::schur::{complex_schur, to_complex};
use crate::error::{ModelError, Result};
use nalgebra::DMatrix;
use num_complex::Complex64 as C;

/// Which Lyapunov equation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LyapKind {
    /// `A P + P Aᵀ + Q = 0`.
    Continuous,
    /// `A P Aᵀ − P + Q = 0`.
    Discrete,
}

/// Solves the Lyapunov equation of `kind` for symmetric `Q`.
pub fn lyap(a: &DMatrix<f64>, q: &DMatrix<f64>, kind: LyapKind) -> Result<DMatrix<f64>> {
    let n = a.nrows();
    if !a.is_square() || q.shape() != (n, n) {
        return Err(ModelError::dim(
            "Lyapunov equation (A, Q)",
            format!("{n}x{n}"),
            format!("{}x{}", q.nrows(), q.ncols()),
        ));
    }
    if n == 0 {
        return Ok(DMatrix::zeros(0, 0));
    }
    let (u, t) = complex_schur(&to_complex(a))?;
    let qt = u.adjoint() * to_complex(q) * &u;
    let mut p = DMatrix::<C>::zeros(n, n);
    let scale = t.iter().map(|v| v.norm()).fold(0.0, f64::max).max(1.0);
    let tiny = 1e3 * f64::EPSILON * scale;
    let mut rhs = nalgebra::DVector::<C>::zeros(n);
    for j in (0..n).rev() {
        // acc = Σ_{k>j} conj(t_jk) p_k
        let mut acc = nalgebra::DVector::<C>::zeros(n);
        for k in (j + 1)..n {
            let w = t[(j, k)].conj();
            if w != C::new(0.0, 0.0) {
                acc.axpy(w, &p.column(k), C::new(1.0, 0.0));
            }
        }
        let tjj = t[(j, j)].conj();
        match kind {
            LyapKind::Continuous => {
                for i in 0..n {
                    rhs[i] = -qt[(i, j)] - acc[i];
                }
                // (T + tjj I) x = rhs
                for i in (0..n).rev() {
                    let mut s = rhs[i];
                    for l in (i + 1)..n {
                        s -= t[(i, l)] * p[(l, j)];
                    }
                    let d = t[(i, i)] + tjj;
                    if d.norm() <= tiny {
                        return Err(ModelError::Singular {
                            what: "the continuous Lyapunov operator (A has eigenvalues λ, μ with λ + μ̄ = 0: \
                                   poles on or symmetric about the imaginary axis)"
                                .into(),
                        });
                    }
                    p[(i, j)] = s / d;
                }
            }
            LyapKind::Discrete => {
                let tacc = &t * &acc;
                for i in 0..n {
                    rhs[i] = -qt[(i, j)] - tacc[i];
                }
                // (tjj T − I) x = rhs
                for i in (0..n).rev() {
                    let mut s = rhs[i];
                    for l in (i + 1)..n {
                        s -= tjj * t[(i, l)] * p[(l, j)];
                    }
                    let d = tjj * t[(i, i)] - C::new(1.0, 0.0);
                    if d.norm() <= tiny {
                        return Err(ModelError::Singular {
                            what: "the discrete Lyapunov operator (A has eigenvalues λ, μ with λ·μ̄ = 1: \
                                   poles on or mirrored about the unit circle)"
                                .into(),
                        });
                    }
                    p[(i, j)] = s / d;
                }
            }
        }
    }
    let full = &u * p * u.adjoint();
    let re = full.map(|v| v.re);
    Ok((&re + re.transpose()) * 0.5)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn residuals_small() {
        let a = DMatrix::from_row_slice(3, 3, &[-1.0, 2.0, 0.0, -3.0, -0.5, 1.0, 0.2, 0.0, -2.0]);
        let q = DMatrix::from_row_slice(3, 3, &[2.0, 0.5, 0.0, 0.5, 1.0, 0.1, 0.0, 0.1, 3.0]);
        let p = lyap(&a, &q, LyapKind::Continuous).unwrap();
        let r = &a * &p + &p * a.transpose() + &q;
        assert!(r.abs().max() < 1e-13);
        let ad = &a * 0.3;
        let p = lyap(&ad, &q, LyapKind::Discrete).unwrap();
        let r = &ad * &p * ad.transpose() - &p + &q;
        assert!(r.abs().max() < 1e-13);
    }
}
