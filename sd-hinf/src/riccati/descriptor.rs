//! Generalized (descriptor) Riccati equations with `E ≠ I`, in scipy's forms:
//!
//! ```text
//! CARE:  AᵀXE + EᵀXA − (EᵀXB + S) R⁻¹ (BᵀXE + Sᵀ) + Q = 0
//! DARE:  AᵀXA − EᵀXE − (AᵀXB + S)(R + BᵀXB)⁻¹(BᵀXA + Sᵀ) + Q = 0
//! ```
//!
//! **Method: reduction to the standard equation** (Arnold & Laub, Proc. IEEE 72(12), 1984,
//! §III: a nonsingular `E` is absorbed into the data). With `Ã = E⁻¹A`, `B̃ = E⁻¹B` and
//! `Y = EᵀXE`, both equations become the standard ones in `(Ã, B̃, Q, R, S)` for `Y`
//! (substitute `X = E⁻ᵀYE⁻¹`: `AᵀXE = ÃᵀY`, `EᵀXB = YB̃`, `AᵀXA = ÃᵀYÃ`, `EᵀXE = Y`), solved
//! by [`super::care`] / [`super::dare`]; the gain `K = R⁻¹(BᵀXE + Sᵀ)` (continuous) or
//! `(R + BᵀXB)⁻¹(BᵀXA + Sᵀ)` (discrete) is the standard one's, and the closed loop's
//! generalized eigenvalues `λ(A − BK, E)` are `λ(Ã − B̃K)`.
//!
//! **Accuracy and refusal.** Forming `E⁻¹A` costs a relative error of about `κ(E)·ε`, and
//! `X = E⁻ᵀYE⁻¹` another `κ(E)²·ε`; `E` with `κ₁(E) > 10⁸` (or singular: a descriptor system
//! with algebraic parts, which needs the deflating-subspace method of the extended pencil)
//! is refused with its condition named. The reported `residual` is the generalized equation's,
//! recomputed with the returned `X` (`‖·‖_F` of the left side over the sum of its terms'
//! norms); `condition` is the reduced equation's estimate times `κ(E)²`.

use super::{care, dare, symmetrize, RiccatiSolution};
use crate::error::{HinfError, Result};
use nalgebra::DMatrix;
use sd_model::ModelError;

/// Largest `κ₁(E)` the reduction accepts (module documentation).
pub const MAX_E_CONDITION: f64 = 1e8;

/// `(E⁻¹, κ₁(E))` of a square finite `e` of the order of `a`, or the error naming the problem.
fn invert_e(e: &DMatrix<f64>, n: usize) -> Result<(DMatrix<f64>, f64)> {
    if e.shape() != (n, n) {
        return Err(ModelError::dim(
            "E",
            format!("{n}x{n}"),
            format!("{}x{}", e.nrows(), e.ncols()),
        )
        .into());
    }
    if e.iter().any(|v| !v.is_finite()) {
        return Err(HinfError::InvalidArgument(
            "E has a non-finite entry".into(),
        ));
    }
    let norm1 = |m: &DMatrix<f64>| {
        (0..m.ncols())
            .map(|j| m.column(j).iter().map(|v| v.abs()).sum::<f64>())
            .fold(0.0, f64::max)
    };
    let inv = e
        .clone()
        .lu()
        .try_inverse()
        .filter(|m| m.iter().all(|v| v.is_finite()));
    let Some(inv) = inv else {
        return Err(HinfError::InvalidArgument(
            "E is singular: a descriptor system with algebraic parts is not supported (only a \
             nonsingular E is reduced to the standard equation)"
                .into(),
        ));
    };
    let kappa = norm1(e) * norm1(&inv);
    if kappa.is_nan() || kappa > MAX_E_CONDITION {
        return Err(HinfError::InvalidArgument(format!(
            "E is ill-conditioned (κ₁(E) = {kappa:.3e} > {MAX_E_CONDITION:.0e}): reducing the \
             equation by E⁻¹ would lose about {:.0} of the 16 digits",
            kappa.log10() * 2.0
        )));
    }
    Ok((inv, kappa))
}

/// Which equation.
#[derive(Clone, Copy)]
enum Form {
    Continuous,
    Discrete,
}

/// The generalized equation's relative residual at `x`.
fn generalized_residual(
    form: Form,
    (a, e, b): (&DMatrix<f64>, &DMatrix<f64>, &DMatrix<f64>),
    (q, r, s): (&DMatrix<f64>, &DMatrix<f64>, &DMatrix<f64>),
    x: &DMatrix<f64>,
) -> Option<f64> {
    let (terms, lhs) = match form {
        Form::Continuous => {
            let axe = a.transpose() * x * e;
            let t = e.transpose() * x * b + s;
            let k = r.clone().lu().solve(&t.transpose())?;
            let tk = &t * k;
            let lhs = symmetrize(&(&axe + axe.transpose() - &tk + q));
            (q.norm() + 2.0 * axe.norm() + tk.norm(), lhs)
        }
        Form::Discrete => {
            let axa = a.transpose() * x * a;
            let exe = e.transpose() * x * e;
            let t = a.transpose() * x * b + s;
            let m = r + b.transpose() * x * b;
            let k = m.lu().solve(&t.transpose())?;
            let tk = &t * k;
            let lhs = symmetrize(&(&axa - &exe - &tk + q));
            (q.norm() + axa.norm() + exe.norm() + tk.norm(), lhs)
        }
    };
    Some(lhs.norm() / terms.max(f64::MIN_POSITIVE))
}

fn solve(
    form: Form,
    (a, e, b): (&DMatrix<f64>, &DMatrix<f64>, &DMatrix<f64>),
    (q, r, s): (&DMatrix<f64>, &DMatrix<f64>, Option<&DMatrix<f64>>),
) -> Result<RiccatiSolution> {
    let n = a.nrows();
    let (einv, kappa) = invert_e(e, n)?;
    if b.nrows() != n {
        return Err(ModelError::dim("B", format!("{n} rows"), b.nrows()).into());
    }
    let (at, bt) = (&einv * a, &einv * b);
    let sol = match form {
        Form::Continuous => care(&at, &bt, q, r, s)?,
        Form::Discrete => dare(&at, &bt, q, r, s)?,
    };
    let x = symmetrize(&(einv.transpose() * &sol.x * &einv));
    let zero = DMatrix::zeros(n, b.ncols());
    let s = s.unwrap_or(&zero);
    let residual = generalized_residual(form, (a, e, b), (q, r, s), &x).ok_or_else(|| {
        HinfError::Numerical("the gain's system is singular at the returned solution".into())
    })?;
    Ok(RiccatiSolution {
        x,
        residual,
        condition: sol.condition * kappa * kappa,
        ..sol
    })
}

/// Stabilizing solution of the generalized CARE `AᵀXE + EᵀXA − (EᵀXB + S)R⁻¹(BᵀXE + Sᵀ) + Q = 0`
/// with a nonsingular, well-conditioned `E` (module documentation).
///
/// # Errors
/// As [`care`]; `E` not n×n, non-finite, singular or with `κ₁(E) >` [`MAX_E_CONDITION`].
pub fn gcare(
    a: &DMatrix<f64>,
    e: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<RiccatiSolution> {
    solve(Form::Continuous, (a, e, b), (q, r, s))
}

/// Stabilizing solution of the generalized DARE
/// `AᵀXA − EᵀXE − (AᵀXB + S)(R + BᵀXB)⁻¹(BᵀXA + Sᵀ) + Q = 0` with a nonsingular,
/// well-conditioned `E` (module documentation).
///
/// # Errors
/// As [`dare`]; `E` not n×n, non-finite, singular or with `κ₁(E) >` [`MAX_E_CONDITION`].
pub fn gdare(
    a: &DMatrix<f64>,
    e: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<RiccatiSolution> {
    solve(Form::Discrete, (a, e, b), (q, r, s))
}
