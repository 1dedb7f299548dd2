//! The CARE: the ordered complex Schur form of the Hamiltonian, then the refinement and checks
//! the DARE shares (the parent module's documentation).

use super::{check, diagnose, empty, finish, sym_solve, symmetrize, Data, Kind, RiccatiSolution};
use crate::error::{HinfError, Result};
use crate::tol;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::linalg::schur::{complex_schur, swap_adjacent, to_complex};
use sd_model::ModelError;

pub(super) fn care_residual(
    d: &Data,
    x: &DMatrix<f64>,
) -> Result<(DMatrix<f64>, f64, DMatrix<f64>)> {
    let t = x * &d.b + &d.s; // XB + S
    let k = sym_solve(&d.r, &t.transpose())
        .ok_or_else(|| HinfError::InvalidArgument("R must be invertible for the CARE".into()))?;
    let ax = d.a.transpose() * x;
    let tk = &t * &k;
    let res = symmetrize(&(&ax + ax.transpose() - &tk + &d.q));
    let scale = d.q.norm() + 2.0 * ax.norm() + tk.norm();
    Ok((res.clone(), res.norm() / scale.max(f64::MIN_POSITIVE), k))
}

/// The relative residual of a given symmetric `x` in the CARE `(a, b, q, r, s)` (the measure
/// [`care`] reports: `‖AᵀX + XA − (XB + S)R⁻¹(BᵀX + Sᵀ) + Q‖_F` over the sum of the terms'
/// norms). For a solution obtained otherwise, e.g. the DARE solution that the exact bilinear
/// map carries over unchanged (loopshaping).
///
/// # Errors
/// As [`care`]: shapes, NaN, asymmetry, R singular; `x` not n×n.
pub fn care_residual_of(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
    x: &DMatrix<f64>,
) -> Result<f64> {
    let d = check(a, b, q, r, s)?;
    if x.shape() != a.shape() {
        return Err(ModelError::dim(
            "X",
            format!("{}x{}", a.nrows(), a.ncols()),
            format!("{}x{}", x.nrows(), x.ncols()),
        )
        .into());
    }
    Ok(care_residual(&d, x)?.1)
}

/// Stabilizing solution of the CARE (module documentation). R must be symmetric and
/// invertible; it may be indefinite (the H∞ Riccati equations), in which case the solution is
/// the one whose graph is the Hamiltonian's stable invariant subspace (X need not be ≥ 0).
///
/// # Errors
/// As [`dare`](super::dare): shapes, NaN, asymmetry, R singular, and
/// [`HinfError::NoStabilizingSolution`] saying why.
pub fn care(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<RiccatiSolution> {
    care_with(a, b, q, r, s, None)
}

/// [`care`] that refuses a Hamiltonian eigenvalue within [`tol::AXIS`]`·‖H‖` of the axis: the
/// H∞ existence tests (γ-iteration, loopshaping's γ_min), where a level at the optimum shows
/// exactly so and a solution computed across it would pass the later tests wrongly.
pub(crate) fn care_separated(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<RiccatiSolution> {
    care_with(a, b, q, r, s, Some(tol::AXIS))
}

fn care_with(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
    axis: Option<f64>,
) -> Result<RiccatiSolution> {
    let d = check(a, b, q, r, s)?;
    let n = d.a.nrows();
    if n == 0 {
        return Ok(empty(d.b.ncols()));
    }
    // the H∞ existence tests first try the Cayley transform and doubling (`cayley.rs`): much
    // faster, and kept only when it vouches for its result
    if axis.is_some() {
        if let Some(sol) = super::cayley::care_by_doubling(&d, axis) {
            return Ok(sol);
        }
    }
    let x0 = match care_initial(&d, axis) {
        Ok(x) => x,
        Err(e) => return Err(diagnose(&d, Kind::Continuous).unwrap_or(e)),
    };
    finish(&d, x0, 0, Kind::Continuous)
}

/// `(A − BR⁻¹Sᵀ, BR⁻¹Bᵀ, Q − SR⁻¹Sᵀ)`: the blocks of the Hamiltonian `[A_s −G; −Q_s −A_sᵀ]`
/// (and of a DARE's doubling iteration); `None` when R is singular.
pub(super) fn separated(d: &Data) -> Option<(DMatrix<f64>, DMatrix<f64>, DMatrix<f64>)> {
    let rinv_st = sym_solve(&d.r, &d.s.transpose())?;
    let rinv_bt = sym_solve(&d.r, &d.b.transpose())?;
    let a_s = &d.a - &d.b * &rinv_st;
    let q_s = symmetrize(&(&d.q - &d.s * &rinv_st));
    let g = symmetrize(&(&d.b * &rinv_bt));
    Some((a_s, g, q_s))
}

fn care_initial(d: &Data, axis: Option<f64>) -> Result<DMatrix<f64>> {
    let n = d.a.nrows();
    let (a_s, g, q_s) = separated(d)
        .ok_or_else(|| HinfError::InvalidArgument("R must be invertible for the CARE".into()))?;
    let mut h = DMatrix::<f64>::zeros(2 * n, 2 * n);
    h.view_mut((0, 0), (n, n)).copy_from(&a_s);
    h.view_mut((0, n), (n, n)).copy_from(&(-&g));
    h.view_mut((n, 0), (n, n)).copy_from(&(-&q_s));
    h.view_mut((n, n), (n, n)).copy_from(&(-a_s.transpose()));
    let (mut u, mut t) = complex_schur(&to_complex(&h))?;
    // Unless `axis` is given, eigenvalues at rounding distance of the axis are not refused by
    // themselves (CAREX 2.8:
    // ±5e-13 off it, a stabilizing solution exists): the split by the sign of the real part
    // must give n stable ones, and `finish` requires the refined X's closed loop to be
    // stable; a pair the rounding put on one side then fails there.
    let stable = |z: C| z.re < 0.0;
    let count = (0..2 * n).filter(|&i| stable(t[(i, i)])).count();
    let hn = h.norm();
    let on_axis = axis.is_some_and(|tol| (0..2 * n).any(|i| t[(i, i)].re.abs() <= tol * hn));
    if on_axis || count != n {
        return Err(HinfError::NoStabilizingSolution {
            equation: "CARE".into(),
            reason: "the Hamiltonian has eigenvalues on (or numerically at) the imaginary axis"
                .into(),
        });
    }
    // bubble the stable eigenvalues to the top
    reorder(&mut t, &mut u, stable);
    let u11 = u.view((0, 0), (n, n)).into_owned();
    let u21 = u.view((n, 0), (n, n)).into_owned();
    // X U11 = U21  ⇔  U11ᵀ Xᵀ = U21ᵀ
    let lu = u11.transpose().lu();
    let xt = lu
        .solve(&u21.transpose())
        .ok_or_else(|| HinfError::NoStabilizingSolution {
            equation: "CARE".into(),
            reason: "the stable invariant subspace is not a graph (U11 singular): (A, B) is not \
                 stabilizable"
                .into(),
        })?;
    let x = xt.transpose().map(|z| z.re);
    Ok(symmetrize(&x))
}

/// Moves the diagonal entries of the triangular `t` satisfying `pred` to the top (stable order
/// otherwise), by adjacent swaps.
fn reorder(t: &mut DMatrix<C>, u: &mut DMatrix<C>, pred: impl Fn(C) -> bool) {
    let n = t.nrows();
    let mut placed = 0;
    for i in 0..n {
        if pred(t[(i, i)]) {
            let mut k = i;
            while k > placed {
                swap_adjacent(t, k - 1, &mut [], &mut [u]);
                k -= 1;
            }
            placed += 1;
        }
    }
}
