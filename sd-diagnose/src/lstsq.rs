//! Linear least squares for the modal residues and the initial state.

use nalgebra::{DMatrix, DVector};

/// A least-squares solution.
pub(crate) struct LstSq {
    /// The minimizer of `‖J x − g‖`.
    pub(crate) x: DVector<f64>,
    /// `(JᵀJ)⁺`, the covariance of x for unit-variance residuals.
    pub(crate) cov: DMatrix<f64>,
}

/// The Euclidean norm of each column (1 for a zero or non-finite one).
fn column_scales(j: &DMatrix<f64>) -> Vec<f64> {
    (0..j.ncols())
        .map(|c| {
            let s = j.column(c).norm();
            if s > 0.0 && s.is_finite() {
                s
            } else {
                1.0
            }
        })
        .collect()
}

/// The solution and covariance of the column-scaled problem back in the original columns.
fn unscaled(mut x: DVector<f64>, mut cov: DMatrix<f64>, scale: &[f64]) -> LstSq {
    let n = scale.len();
    for r in 0..n {
        x[r] /= scale[r];
        for c in 0..n {
            cov[(r, c)] /= scale[r] * scale[c];
        }
    }
    LstSq { x, cov }
}

/// `min ‖J x − g‖` by the SVD of J with its columns scaled to unit norm (so the rank cut
/// `1e-10·σ_max` sees the conditioning of the basis, not the units of its columns); `None` when J
/// or g hold a non-finite entry or J has no finite nonzero singular value.
pub(crate) fn scaled_lstsq(j: &DMatrix<f64>, g: &DVector<f64>) -> Option<LstSq> {
    if j.iter().chain(g.iter()).any(|v| !v.is_finite()) {
        return None;
    }
    let n = j.ncols();
    let scale = column_scales(j);
    let mut js = j.clone();
    for (c, s) in scale.iter().enumerate() {
        js.column_mut(c).scale_mut(1.0 / s);
    }
    let svd = js.svd(true, true);
    let (u, vt) = (svd.u.as_ref()?, svd.v_t.as_ref()?);
    let smax = svd.singular_values.max();
    if !(smax.is_finite() && smax > 0.0) {
        return None;
    }
    let mut x = DVector::zeros(n);
    let mut cov = DMatrix::zeros(n, n);
    for (k, &sv) in svd.singular_values.iter().enumerate() {
        if sv > 1e-10 * smax {
            let v = vt.row(k).transpose();
            x += &v * (u.column(k).dot(g) / sv);
            cov += &v * v.transpose() / (sv * sv);
        }
    }
    Some(unscaled(x, cov, &scale))
}

/// `min ‖J x − g‖` by the normal equations of the column-scaled J, `(JₛᵀJₛ) y = Jₛᵀ g`, solved
/// through the symmetric eigendecomposition with eigenvalues below `1e-13·λ_max` cut (singular
/// values below ≈3e-7·σ_max: the normal equations square the condition number, so the cut sits
/// above their rounding level). O(m n²) without forming U, for the tall, narrow modal-residue
/// problems of the hypothesis search; agrees with [`scaled_lstsq`] on well-posed problems
/// (tested to 1e-8).
pub(crate) fn normal_lstsq(j: &DMatrix<f64>, g: &DVector<f64>) -> Option<LstSq> {
    let n = j.ncols();
    let scale = column_scales(j);
    let mut a = j.transpose() * j;
    let mut b = j.transpose() * g;
    for r in 0..n {
        b[r] /= scale[r];
        for c in 0..n {
            a[(r, c)] /= scale[r] * scale[c];
        }
    }
    if !a.iter().all(|v| v.is_finite()) {
        return None;
    }
    let eig = nalgebra::SymmetricEigen::new(a);
    let lmax = eig.eigenvalues.max();
    if !(lmax.is_finite() && lmax > 0.0) {
        return None;
    }
    let mut x = DVector::zeros(n);
    let mut cov = DMatrix::zeros(n, n);
    for (k, &l) in eig.eigenvalues.iter().enumerate() {
        if l > 1e-13 * lmax {
            let v = eig.eigenvectors.column(k);
            x += v * (v.dot(&b) / l);
            cov += v * v.transpose() / l;
        }
    }
    Some(unscaled(x, cov, &scale))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// NaN or infinity anywhere: no solution (instead of a panic inside the SVD's sort).
    #[test]
    fn non_finite_input_has_no_solution() {
        let j = DMatrix::from_row_slice(2, 1, &[1.0, f64::NAN]);
        let g = DVector::from_row_slice(&[1.0, 2.0]);
        assert!(scaled_lstsq(&j, &g).is_none());
        let j = DMatrix::from_row_slice(2, 1, &[1.0, 2.0]);
        let g = DVector::from_row_slice(&[1.0, f64::INFINITY]);
        assert!(scaled_lstsq(&j, &g).is_none());
    }

    /// The normal-equation route agrees with the SVD route on a well-posed tall problem with
    /// columns of very different scales.
    #[test]
    fn normal_equations_agree_with_svd() {
        let (m, n) = (400, 6);
        let j = DMatrix::from_fn(m, n, |r, c| {
            let t = r as f64 / m as f64;
            (t * (c + 1) as f64 * 3.1).sin() * 10f64.powi(c as i32 - 3) + 0.01 * t.powi(c as i32)
        });
        let g = DVector::from_fn(m, |r, _| (r as f64 * 0.37).cos());
        let a = scaled_lstsq(&j, &g).unwrap();
        let b = normal_lstsq(&j, &g).unwrap();
        let ex = (&a.x - &b.x).norm() / a.x.norm();
        let ec = (&a.cov - &b.cov).norm() / a.cov.norm();
        assert!(ex < 1e-8 && ec < 1e-8, "{ex:e} {ec:e}");
    }
}
