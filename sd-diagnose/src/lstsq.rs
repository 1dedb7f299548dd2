//! Linear least squares for the modal residues and the initial state.

use nalgebra::{DMatrix, DVector};

/// A least-squares solution.
pub(crate) struct LstSq {
    /// The minimizer of `‖J x − g‖`.
    pub(crate) x: DVector<f64>,
    /// `(JᵀJ)⁺`, the covariance of x for unit-variance residuals.
    pub(crate) cov: DMatrix<f64>,
    /// `‖J x − g‖²`.
    pub(crate) residual: f64,
}

/// `min ‖J x − g‖` by the SVD of J with its columns scaled to unit norm (so the rank cut
/// `1e-10·σ_max` sees the conditioning of the basis, not the units of its columns); `None` when J
/// has no finite nonzero singular value.
pub(crate) fn scaled_lstsq(j: &DMatrix<f64>, g: &DVector<f64>) -> Option<LstSq> {
    let n = j.ncols();
    let scale: Vec<f64> = (0..n)
        .map(|c| {
            let s = j.column(c).norm();
            if s > 0.0 && s.is_finite() {
                s
            } else {
                1.0
            }
        })
        .collect();
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
    for a in 0..n {
        x[a] /= scale[a];
        for b in 0..n {
            cov[(a, b)] /= scale[a] * scale[b];
        }
    }
    let residual = (g - j * &x).norm_squared();
    Some(LstSq { x, cov, residual })
}
