//! The one place where nalgebra and faer matrices are converted.

use crate::error::{ModelError, Result};
use nalgebra::DMatrix;
use num_complex::Complex64 as C;

/// nalgebra → faer.
pub fn to_faer(a: &DMatrix<f64>) -> faer::Mat<f64> {
    faer::Mat::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)])
}

/// faer → nalgebra.
pub fn from_faer(a: faer::MatRef<'_, f64>) -> DMatrix<f64> {
    DMatrix::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)])
}

/// Eigenvalues of a real square matrix: exact power-of-two diagonal balancing (as LAPACK
/// xGEEV does by default), then faer's multishift QR. Balancing leaves the eigenvalues
/// unchanged and makes badly scaled (physical-coordinate) matrices both faster and more
/// accurate to decompose.
pub fn eigenvalues(a: &DMatrix<f64>) -> Result<Vec<C>> {
    if a.nrows() == 0 {
        return Ok(Vec::new());
    }
    let (bal, _) = super::expm::balance_diag(a);
    let m = to_faer(&bal);
    let ev = m.eigenvalues().map_err(|e| ModelError::NotConverged {
        what: format!("the eigenvalue iteration ({e:?})"),
    })?;
    Ok(ev.into_iter().map(|z| C::new(z.re, z.im)).collect())
}

/// Generalized eigenvalues `(α, β)` of the pencil `A − λ E` (λ = α/β; complex ones in exact
/// conjugate pairs), by faer's QZ without eigenvectors (faer 0.24's eigenvector back-substitution under-sizes its workspace for some
/// small pencils and panics; the eigenvalues need none of it).
pub fn generalized_eigenvalues(a: &DMatrix<f64>, e: &DMatrix<f64>) -> Result<Vec<(C, C)>> {
    let n = a.nrows();
    if n == 0 {
        return Ok(Vec::new());
    }
    let (mut fa, mut fe) = (to_faer(a), to_faer(e));
    let mut s_re = faer::diag::Diag::<f64>::zeros(n);
    let mut s_im = faer::diag::Diag::<f64>::zeros(n);
    let mut s_b = faer::diag::Diag::<f64>::zeros(n);
    let par = faer::get_global_parallelism();
    let no = faer::linalg::evd::ComputeEigenvectors::No;
    let mut mem = faer::dyn_stack::MemBuffer::new(faer::linalg::gevd::gevd_scratch::<f64>(
        n,
        no,
        no,
        par,
        Default::default(),
    ));
    faer::linalg::gevd::gevd_real(
        fa.as_mut(),
        fe.as_mut(),
        s_re.as_mut(),
        s_im.as_mut(),
        s_b.as_mut(),
        None,
        None,
        par,
        faer::dyn_stack::MemStack::new(&mut mem),
        Default::default(),
    )
    .map_err(|e| ModelError::NotConverged {
        what: format!("the QZ iteration ({e:?})"),
    })?;
    // a complex pair is (αᵣ + iαᵢ)/β for its first member (αᵢ > 0); faer scales the second
    // member's (α, β) differently from the first (its quotient is not the conjugate), so the
    // second is the first's conjugate, exactly, as the real pencil requires
    let mut out: Vec<(C, C)> = Vec::with_capacity(n);
    let mut i = 0;
    while i < n {
        let first = (C::new(s_re[i], s_im[i]), C::new(s_b[i], 0.0));
        out.push(first);
        if s_im[i] > 0.0 && i + 1 < n && s_im[i + 1] < 0.0 {
            out.push((first.0.conj(), first.1));
            i += 2;
        } else {
            i += 1;
        }
    }
    Ok(out)
}

/// Singular values (descending) and thin factors `(U, σ, V)` of a real matrix, by faer's SVD;
/// where it reports no convergence (it does on some well-conditioned matrices with paired
/// singular values, e.g. a 16 × 16 triangle of a local modal fit: the test
/// `svd_falls_back_where_faer_does_not_converge`), by nalgebra's one-sided Golub–Kahan SVD.
///
/// # Errors
/// [`ModelError::NotConverged`] when neither converges.
pub fn svd(a: &DMatrix<f64>) -> Result<(DMatrix<f64>, Vec<f64>, DMatrix<f64>)> {
    let (m, n) = a.shape();
    if m == 0 || n == 0 {
        return Ok((DMatrix::zeros(m, 0), Vec::new(), DMatrix::zeros(n, 0)));
    }
    let fa = to_faer(a);
    match fa.thin_svd() {
        Ok(s) => {
            let u = from_faer(s.U());
            let v = from_faer(s.V());
            let sv = s.S().column_vector().iter().cloned().collect();
            Ok((u, sv, v))
        }
        Err(e) => svd_nalgebra(a).ok_or_else(|| ModelError::NotConverged {
            what: format!("the SVD (faer: {e:?}; nalgebra: no convergence either)"),
        }),
    }
}

/// nalgebra's SVD, sorted descending, as `(U, σ, V)`; `None` without convergence.
fn svd_nalgebra(a: &DMatrix<f64>) -> Option<(DMatrix<f64>, Vec<f64>, DMatrix<f64>)> {
    let iterations = 200 * a.nrows().max(a.ncols());
    let s = nalgebra::linalg::SVD::try_new(a.clone(), true, true, f64::EPSILON, iterations)?;
    let (u, vt) = (s.u?, s.v_t?);
    let mut order: Vec<usize> = (0..s.singular_values.len()).collect();
    order.sort_by(|&i, &j| s.singular_values[j].total_cmp(&s.singular_values[i]));
    let uo = DMatrix::from_fn(u.nrows(), order.len(), |r, c| u[(r, order[c])]);
    let vo = DMatrix::from_fn(vt.ncols(), order.len(), |r, c| vt[(order[c], r)]);
    Some((
        uo,
        order.iter().map(|&i| s.singular_values[i]).collect(),
        vo,
    ))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A matrix faer's SVD does not converge on: the fallback's factors reproduce it to
    /// `n·ε·σ_max`, are orthonormal, and the values descend.
    #[test]
    fn svd_falls_back_where_faer_does_not_converge() {
        let text = include_str!("testdata/faer_svd_no_convergence.txt");
        let rows: Vec<Vec<f64>> = text
            .lines()
            .filter(|l| !l.starts_with('#'))
            .map(|l| l.split_whitespace().map(|x| x.parse().unwrap()).collect())
            .collect();
        let n = rows.len();
        let a = DMatrix::from_fn(n, n, |i, j| rows[i][j]);
        assert!(to_faer(&a).thin_svd().is_err(), "faer converges here now");
        let (u, s, v) = svd(&a).unwrap();
        let back =
            &u * DMatrix::from_diagonal(&nalgebra::DVector::from_vec(s.clone())) * v.transpose();
        let tol = 10.0 * n as f64 * f64::EPSILON * s[0];
        assert!((back - &a).amax() <= tol);
        assert!(
            (u.transpose() * &u - DMatrix::identity(n, n)).amax() <= 10.0 * n as f64 * f64::EPSILON
        );
        assert!(
            (v.transpose() * &v - DMatrix::identity(n, n)).amax() <= 10.0 * n as f64 * f64::EPSILON
        );
        assert!(s.windows(2).all(|w| w[0] >= w[1]));
    }
}
