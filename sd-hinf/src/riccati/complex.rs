//! Riccati equations with complex data: the same CARE, DARE and their descriptor forms with
//! `ᵀ` read as the conjugate transpose `ᴴ`,
//!
//! ```text
//! CARE:  AᴴXE + EᴴXA − (EᴴXB + S) R⁻¹ (BᴴXE + Sᴴ) + Q = 0
//! DARE:  AᴴXA − EᴴXE − (AᴴXB + S)(R + BᴴXB)⁻¹(BᴴXA + Sᴴ) + Q = 0
//! ```
//!
//! (`E = I` when absent), with `Q`, `R` Hermitian and the Hermitian stabilizing `X`.
//!
//! **Method: the real representation.** `φ(M) = [Re M  −Im M; Im M  Re M]` is an injective
//! algebra homomorphism from complex `p×q` to real `2p×2q` matrices with `φ(Mᴴ) = φ(M)ᵀ`
//! (Horn & Johnson, *Topics in Matrix Analysis*, §1.3, problem 8 / *Matrix Analysis* 2nd ed.
//! §1.3.P20), so `X` solves the complex equation exactly when `φ(X)` solves the real one in
//! `(φ(A), φ(B), φ(Q), φ(R), φ(S), φ(E))`, and the spectrum of `φ(A − BK)` is that of `A − BK`
//! with its conjugates, so stabilizing is preserved both ways. The real equation's stabilizing
//! solution is unique; `J = φ(iI)` is orthogonal and commutes with all the data, so `JᵀφJ`
//! solves it too and is also stabilizing, hence equal: the real solution has the block
//! structure `[Xr −Xi; Xi Xr]` and gives `X = Xr + iXi` (Hermitian because `φ(X)` is
//! symmetric). The real problem is solved by [`super::care`], [`super::dare`],
//! [`super::descriptor::gcare`] or [`super::descriptor::gdare`] at twice the order (8× the
//! flops), with their refinement, refusals and condition estimate.
//!
//! **Reported.** `X` and `K` from the blocks (the two copies of each part averaged); the
//! relative residual recomputed in complex arithmetic on the complex equation (same
//! normalization as the real solvers); the closed loop and condition of the real problem
//! (the same spectrum; `κ` of `φ`'s equation bounds that of the complex one).

use super::descriptor::{gcare, gdare};
use super::{care, dare, RiccatiSolution};
use crate::error::{HinfError, Result};
use crate::tol;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::ModelError;

/// A complex matrix.
pub type CMatrix = DMatrix<C>;

/// The Hermitian stabilizing solution of a complex Riccati equation with its diagnostics.
#[derive(Debug, Clone)]
pub struct ComplexRiccatiSolution {
    /// The stabilizing solution X (Hermitian).
    pub x: CMatrix,
    /// The gain K (control `u = −K x`).
    pub gain: CMatrix,
    /// Relative residual of the complex equation.
    pub residual: f64,
    /// DARE: spectral radius of `A − BK` (< 1); CARE: spectral abscissa (< 0).
    pub closed_loop: f64,
    /// Relative condition estimate κ of the real representation's equation.
    pub condition: f64,
    /// Doubling (DARE) iterations used.
    pub doubling_steps: usize,
    /// Newton refinement steps kept.
    pub refinement_steps: usize,
}

/// The complex data of one equation; `s` and `e` optional (zero, identity).
#[derive(Debug, Clone, Copy)]
pub struct ComplexRiccatiData<'a> {
    /// State matrix, n×n.
    pub a: &'a CMatrix,
    /// Input matrix, n×m.
    pub b: &'a CMatrix,
    /// State weight, n×n Hermitian.
    pub q: &'a CMatrix,
    /// Input weight, m×m Hermitian.
    pub r: &'a CMatrix,
    /// Cross term, n×m (zero if `None`).
    pub s: Option<&'a CMatrix>,
    /// Descriptor matrix, n×n nonsingular (identity if `None`).
    pub e: Option<&'a CMatrix>,
}

/// `φ(M) = [Re M  −Im M; Im M  Re M]`.
pub fn realify(m: &CMatrix) -> DMatrix<f64> {
    let (p, q) = m.shape();
    DMatrix::from_fn(2 * p, 2 * q, |i, j| {
        let v = m[(i % p, j % q)];
        match (i < p, j < q) {
            (true, true) | (false, false) => v.re,
            (true, false) => -v.im,
            (false, true) => v.im,
        }
    })
}

/// The complex matrix of a real `2p×2q` matrix with `φ`'s block structure (both copies of
/// each part averaged).
fn complexify(m: &DMatrix<f64>) -> CMatrix {
    let (p, q) = (m.nrows() / 2, m.ncols() / 2);
    DMatrix::from_fn(p, q, |i, j| {
        C::new(
            0.5 * (m[(i, j)] + m[(i + p, j + q)]),
            0.5 * (m[(i + p, j)] - m[(i, j + q)]),
        )
    })
}

/// Shapes, finiteness and Hermitian `Q`, `R`, with the error naming what to fix.
fn check(d: &ComplexRiccatiData<'_>) -> Result<()> {
    let (n, m) = (d.a.nrows(), d.b.ncols());
    let mut shapes = vec![
        ("A", d.a, n, n),
        ("B", d.b, n, m),
        ("Q", d.q, n, n),
        ("R", d.r, m, m),
    ];
    if let Some(s) = d.s {
        shapes.push(("S", s, n, m));
    }
    if let Some(e) = d.e {
        shapes.push(("E", e, n, n));
    }
    for (what, mat, rows, cols) in shapes {
        if mat.shape() != (rows, cols) {
            return Err(ModelError::dim(
                what,
                format!("{rows}x{cols}"),
                format!("{}x{}", mat.nrows(), mat.ncols()),
            )
            .into());
        }
        if mat.iter().any(|v| !v.re.is_finite() || !v.im.is_finite()) {
            return Err(ModelError::NonFinite { what: what.into() }.into());
        }
    }
    for (what, mat) in [("Q", d.q), ("R", d.r)] {
        let nm = mat.norm();
        let skew = (mat - mat.adjoint()).norm();
        if skew > tol::SYMMETRY * nm.max(f64::MIN_POSITIVE) {
            return Err(HinfError::InvalidArgument(format!(
                "{what} must be Hermitian (relative ‖{what} − {what}ᴴ‖ = {:.1e})",
                skew / nm
            )));
        }
    }
    Ok(())
}

/// Which equation.
#[derive(Clone, Copy, PartialEq)]
enum Form {
    Continuous,
    Discrete,
}

/// The complex equation's relative residual at `x` (the real solvers' normalization).
fn residual(form: Form, d: &ComplexRiccatiData<'_>, x: &CMatrix) -> Option<f64> {
    let n = d.a.nrows();
    let eye = CMatrix::identity(n, n);
    let e = d.e.unwrap_or(&eye);
    let zero = CMatrix::zeros(n, d.b.ncols());
    let s = d.s.unwrap_or(&zero);
    let herm = |m: CMatrix| (&m + m.adjoint()) * C::new(0.5, 0.0);
    let (terms, lhs) = match form {
        Form::Continuous => {
            let axe = d.a.adjoint() * x * e;
            let t = e.adjoint() * x * d.b + s;
            let k = d.r.clone().lu().solve(&t.adjoint())?;
            let tk = &t * k;
            let lhs = herm(&axe + axe.adjoint() - &tk + d.q);
            (d.q.norm() + 2.0 * axe.norm() + tk.norm(), lhs)
        }
        Form::Discrete => {
            let axa = d.a.adjoint() * x * d.a;
            let exe = e.adjoint() * x * e;
            let t = d.a.adjoint() * x * d.b + s;
            let k = (d.r + d.b.adjoint() * x * d.b).lu().solve(&t.adjoint())?;
            let tk = &t * k;
            let lhs = herm(&axa - &exe - &tk + d.q);
            (d.q.norm() + axa.norm() + exe.norm() + tk.norm(), lhs)
        }
    };
    Some(lhs.norm() / terms.max(f64::MIN_POSITIVE))
}

fn solve(form: Form, d: &ComplexRiccatiData<'_>) -> Result<ComplexRiccatiSolution> {
    check(d)?;
    let (a, b, q, r) = (realify(d.a), realify(d.b), realify(d.q), realify(d.r));
    let s = d.s.map(realify);
    let e = d.e.map(realify);
    let real: RiccatiSolution = match (form, &e) {
        (Form::Continuous, None) => care(&a, &b, &q, &r, s.as_ref())?,
        (Form::Discrete, None) => dare(&a, &b, &q, &r, s.as_ref())?,
        (Form::Continuous, Some(e)) => gcare(&a, e, &b, &q, &r, s.as_ref())?,
        (Form::Discrete, Some(e)) => gdare(&a, e, &b, &q, &r, s.as_ref())?,
    };
    let x = complexify(&real.x);
    let x = (&x + x.adjoint()) * C::new(0.5, 0.0);
    let gain = complexify(&real.gain);
    let residual = residual(form, d, &x).ok_or_else(|| {
        HinfError::Numerical("the gain's system is singular at the returned solution".into())
    })?;
    Ok(ComplexRiccatiSolution {
        x,
        gain,
        residual,
        closed_loop: real.closed_loop,
        condition: real.condition,
        doubling_steps: real.doubling_steps,
        refinement_steps: real.refinement_steps,
    })
}

/// Hermitian stabilizing solution of the complex CARE (with `E` when given; module
/// documentation).
///
/// # Errors
/// Shapes, non-finite entries, `Q` or `R` not Hermitian; then as [`care`] / [`gcare`] on the
/// real representation (no stabilizing solution with the reason, `E` singular or
/// ill-conditioned).
pub fn care_complex(d: &ComplexRiccatiData<'_>) -> Result<ComplexRiccatiSolution> {
    solve(Form::Continuous, d)
}

/// Hermitian stabilizing solution of the complex DARE (with `E` when given; module
/// documentation).
///
/// # Errors
/// As [`care_complex`], with [`dare`] / [`gdare`].
pub fn dare_complex(d: &ComplexRiccatiData<'_>) -> Result<ComplexRiccatiSolution> {
    solve(Form::Discrete, d)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn realify_is_a_homomorphism_with_the_adjoint() {
        let m = CMatrix::from_fn(2, 3, |i, j| C::new(i as f64 + 0.5, j as f64 - 1.0));
        let k = CMatrix::from_fn(3, 2, |i, j| C::new(1.0 - j as f64, 2.0 * i as f64));
        let lhs = realify(&(&m * &k));
        let rhs = realify(&m) * realify(&k);
        assert!((lhs - rhs).norm() < 1e-13);
        assert!((realify(&m.adjoint()) - realify(&m).transpose()).norm() == 0.0);
        assert!((complexify(&realify(&m)) - m).norm() == 0.0);
    }
}
