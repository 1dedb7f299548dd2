//! The CARE through the DARE its Cayley transform gives: the doubling algorithm ([`crate::sda`])
//! instead of an ordered Schur form of the Hamiltonian.
//!
//! **Math.** The CARE `AᵀX + XA − (XB + S)R⁻¹(BᵀX + Sᵀ) + Q = 0` is the Kalman–Yakubovich–Popov
//! equation of the Popov function `Φ(s) = [(sI − A)⁻¹B; I]^* [Q S; Sᵀ R] [(sI − A)⁻¹B; I]`. With
//! `N = (I − A)⁻¹`, `z = (1 + s)/(1 − s)`, `A_d = N(I + A)`, `B_d = √2·NB`:
//! `(zI − A_d)⁻¹B_d = ((1 − s)/√2)(sI − A)⁻¹B`, hence `(sI − A)⁻¹B = √2·N(zI − A_d)⁻¹B_d + NB`
//! exactly: `[x; u] = M[x_d; u]` with `M = [√2N NB; 0 I]`, and the discrete Popov matrix is
//! `MᵀΠM`:
//!
//! ```text
//! Q_d = 2NᵀQN,   S_d = √2·Nᵀ(QNB + S),   R_d = R + BᵀNᵀS + SᵀNB + BᵀNᵀQNB,
//! ```
//!
//! and the DARE `A_dᵀXA_d − X − (A_dᵀXB_d + S_d)(R_d + B_dᵀXB_d)⁻¹(B_dᵀXA_d + S_dᵀ) + Q_d = 0`
//! has the same stabilizing solution X (the stable deflating subspace of its symplectic pencil
//! is the Cayley image of the Hamiltonian's stable invariant subspace; for `Q = CᵀC`,
//! `S = CᵀD`, `R = DᵀD − J` these are the data of the bilinear image of `(A, B, C, D)`, the
//! fact loopshaping uses). The DARE is solved by doubling on `(A_d − B_dR_d⁻¹S_dᵀ,
//! B_dR_d⁻¹B_dᵀ, Q_d − S_dR_d⁻¹S_dᵀ)` — R_d may be indefinite (the H∞ equations), the
//! iteration only needs `I + G_kH_k` invertible — and the result is refined and checked on the
//! continuous equation itself (Newton, closed-loop abscissa, condition: the parent's `finish`).
//!
//! **When it is used, and why it is safe.** Only where the caller can fall back: `None` sends
//! it to the Schur method, which then decides. The result is kept only when the refined X's
//! relative CARE residual is at most [`tol::BILINEAR_RESIDUAL`] and its closed loop is stable;
//! with an axis tolerance (the H∞ existence tests) the closed loop's abscissa must also be
//! below `−axis·‖H‖_F` — the Schur method's own refusal criterion, since the stable Hamiltonian
//! eigenvalues are the closed loop's. A doubling step costs about 15n³ flops of matrix
//! products and one LU (faer), against the O((2n)³) complex QR sweeps and swaps of the ordered
//! Schur form (nalgebra); `cargo xtask bench --only hinfsyn` times the whole synthesis on the
//! 64-state mixed-sensitivity plant that these equations dominated.

use super::{finish, symmetrize, Data, Kind, RiccatiSolution};
use crate::tol;
use nalgebra::DMatrix;

/// The stabilizing solution by the Cayley transform and doubling, or `None` when that route
/// does not deliver one it can vouch for (module documentation).
pub(super) fn care_by_doubling(d: &Data, axis: Option<f64>) -> Option<RiccatiSolution> {
    let n = d.a.nrows();
    let ident = DMatrix::<f64>::identity(n, n);
    let nm = (&ident - &d.a).try_inverse()?;
    if nm.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let r2 = std::f64::consts::SQRT_2;
    let nb = &nm * &d.b;
    let qn = &d.q * &nm;
    let a_d = &nm * (&ident + &d.a);
    let q_d = symmetrize(&(nm.transpose() * &qn * 2.0));
    let qnb_s = &qn * &d.b + &d.s;
    let s_d = nm.transpose() * &qnb_s * r2;
    let r_d = symmetrize(
        &(&d.r + nb.transpose() * &d.s + d.s.transpose() * &nb + nb.transpose() * &qn * &d.b),
    );
    let discrete = Data {
        a: a_d,
        b: &nb * r2,
        q: q_d,
        r: r_d,
        s: s_d,
    };
    let (a_s, g, q_s) = super::care::separated(&discrete)?;
    let (x0, steps) = crate::sda::doubling(&a_s, &g, &q_s).ok()?;
    if x0.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let sol = finish(d, symmetrize(&x0), steps, Kind::Continuous).ok()?;
    if !(sol.residual <= tol::BILINEAR_RESIDUAL && sol.closed_loop < 0.0) {
        return None;
    }
    if let Some(tol_axis) = axis {
        if sol.closed_loop > -tol_axis * hamiltonian_norm(d)? {
            return None;
        }
    }
    Some(sol)
}

/// `‖[A_s −G; −Q_s −A_sᵀ]‖_F` of the continuous equation (the scale of the Schur method's axis
/// test).
fn hamiltonian_norm(d: &Data) -> Option<f64> {
    let (a_s, g, q_s) = super::care::separated(d)?;
    let sq = 2.0 * a_s.norm_squared() + g.norm_squared() + q_s.norm_squared();
    Some(sq.sqrt())
}
