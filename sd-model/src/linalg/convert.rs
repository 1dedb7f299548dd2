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

/// Singular values (descending) and thin factors `(U, σ, V)` of a real matrix, by faer's SVD.
pub fn svd(a: &DMatrix<f64>) -> Result<(DMatrix<f64>, Vec<f64>, DMatrix<f64>)> {
    let (m, n) = a.shape();
    if m == 0 || n == 0 {
        return Ok((DMatrix::zeros(m, 0), Vec::new(), DMatrix::zeros(n, 0)));
    }
    let fa = to_faer(a);
    let s = fa.thin_svd().map_err(|e| ModelError::NotConverged {
        what: format!("the SVD ({e:?})"),
    })?;
    let u = from_faer(s.U());
    let v = from_faer(s.V());
    let sv = s.S().column_vector().iter().cloned().collect();
    Ok((u, sv, v))
}
