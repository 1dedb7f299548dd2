//! The existence test and the central controller at a level γ, on the scaled continuous
//! problem (`D₁₂ = [0; I]`, `D₂₁ = [0 I]`, `D₂₂ = 0`), D₁₁ arbitrary.
//!
//! Glover & Doyle, *Systems & Control Letters* 11 (1988); Zhou, Doyle & Glover, *Robust and
//! Optimal Control* (1996), ch. 17 (the general case). With `D₁• = [D₁₁ D₁₂]`,
//! `D•₁ = [D₁₁; D₂₁]`, `R = D₁•ᵀD₁• − diag(γ²I, 0)`, `R̃ = D•₁D•₁ᵀ − diag(γ²I, 0)`:
//!
//! - X∞ the stabilizing solution of `AᵀX + XA − (XB + C₁ᵀD₁•)R⁻¹(BᵀX + D₁•ᵀC₁) + C₁ᵀC₁ = 0`,
//!   `F = −R⁻¹(D₁•ᵀC₁ + BᵀX)`; Y∞ the dual one with `(Aᵀ, Cᵀ, B₁B₁ᵀ, R̃, B₁D•₁ᵀ)`,
//!   `L = −(B₁D•₁ᵀ + YCᵀ)R̃⁻¹`.
//! - A controller with `‖F_l(P, K)‖∞ < γ` exists iff
//!   `γ > max(σ̄[D₁₁₁₁ D₁₁₁₂], σ̄[D₁₁₁₁ᵀ D₁₁₂₁ᵀ])`, both solutions exist and are ≥ 0, and
//!   `ρ(X∞Y∞) < γ²` (D₁₁ partitioned by the rows of `[0; I]` and the columns of `[0 I]`).
//! - The central one: `D̂₁₁ = −D₁₁₂₁D₁₁₁₁ᵀ(γ²I − D₁₁₁₁D₁₁₁₁ᵀ)⁻¹D₁₁₁₂ − D₁₁₂₂`,
//!   `D̂₁₂D̂₁₂ᵀ = I − D₁₁₂₁(γ²I − D₁₁₁₁ᵀD₁₁₁₁)⁻¹D₁₁₂₁ᵀ`,
//!   `D̂₂₁ᵀD̂₂₁ = I − D₁₁₁₂ᵀ(γ²I − D₁₁₁₁D₁₁₁₁ᵀ)⁻¹D₁₁₁₂` (Cholesky factors),
//!   `Z = (I − γ⁻²Y∞X∞)⁻¹`, `B̂₂ = Z(B₂ + L₁₂)D̂₁₂`, `Ĉ₂ = −D̂₂₁(C₂ + F₁₂)`,
//!   `B̂₁ = −ZL₂ + B̂₂D̂₁₂⁻¹D̂₁₁`, `Ĉ₁ = F₂ + D̂₁₁D̂₂₁⁻¹Ĉ₂`, `Â = A + BF + B̂₁D̂₂₁⁻¹Ĉ₂`,
//!   `K = [Â B̂₁; Ĉ₁ D̂₁₁]` (F split by rows into `F₁₁, F₁₂, F₂`, L by columns into
//!   `L₁₁, L₁₂, L₂`, following D₁₁'s partition).
//!
//! The test at γ is the theorem's four conditions and then, because the formulas are only as
//! good as the Riccati solutions near γ_opt, the closed loop with the central controller must
//! be stable by its eigenvalues.

use super::normalize::Normalized;
use super::GammaOutcome;
use crate::error::Result;
use crate::lft::lft_lower;
use crate::riccati::{care_separated, RiccatiSolution};
use crate::tol;
use nalgebra::DMatrix;
use sd_model::linalg::convert::eigenvalues;
use sd_model::{SampleTime, StateSpace};

/// Everything computed at one feasible γ.
pub(crate) struct Level {
    pub x: RiccatiSolution,
    pub y: RiccatiSolution,
    /// The scaled continuous central controller.
    pub controller: StateSpace,
}

/// D₁₁'s four blocks.
struct D11Parts {
    d1111: DMatrix<f64>,
    d1112: DMatrix<f64>,
    d1121: DMatrix<f64>,
    d1122: DMatrix<f64>,
}

fn parts(nz: &Normalized) -> D11Parts {
    let d = &nz.bl.d11;
    let (p1, m1) = d.shape();
    let m2 = nz.bl.b2.ncols();
    let p2 = nz.bl.c2.nrows();
    let (r, c) = (p1 - m2, m1 - p2);
    D11Parts {
        d1111: d.view((0, 0), (r, c)).into_owned(),
        d1112: d.view((0, c), (r, p2)).into_owned(),
        d1121: d.view((r, 0), (m2, c)).into_owned(),
        d1122: d.view((r, c), (m2, p2)).into_owned(),
    }
}

fn sigma_max(m: &DMatrix<f64>) -> f64 {
    if m.is_empty() {
        return 0.0;
    }
    m.clone()
        .singular_values()
        .iter()
        .fold(0.0f64, |a, v| a.max(*v))
}

fn hcat(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let mut m = DMatrix::zeros(a.nrows(), a.ncols() + b.ncols());
    m.view_mut((0, 0), a.shape()).copy_from(a);
    m.view_mut((0, a.ncols()), b.shape()).copy_from(b);
    m
}

fn vcat(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let mut m = DMatrix::zeros(a.nrows() + b.nrows(), a.ncols());
    m.view_mut((0, 0), a.shape()).copy_from(a);
    m.view_mut((a.nrows(), 0), b.shape()).copy_from(b);
    m
}

/// The Parrott bound: no γ at or below it is achievable by any controller.
pub(crate) fn parrott(nz: &Normalized) -> f64 {
    let p = parts(nz);
    sigma_max(&hcat(&p.d1111, &p.d1112)).max(sigma_max(&vcat(&p.d1111, &p.d1121)))
}

/// Smallest eigenvalue of the solution X of `AᵀX + XA − … + Q = 0` relative to the scale it is
/// computed to: `‖X‖₂ + ‖Q‖/‖A_c‖` (`A_c = A − B·gain`, the closed loop; a solution that is zero
/// in exact arithmetic comes out at roundoff level, and its sign there means nothing).
fn relative_min_eig(
    sol: &RiccatiSolution,
    q: &DMatrix<f64>,
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
) -> f64 {
    let x = &sol.x;
    if x.is_empty() {
        return 0.0;
    }
    let ev = x.clone().symmetric_eigen().eigenvalues;
    let big = ev.iter().fold(0.0f64, |acc, v| acc.max(v.abs()));
    let small = ev.iter().fold(f64::INFINITY, |acc, v| acc.min(*v));
    let ac = (a - b * &sol.gain).norm();
    let scale = big + q.norm() / ac.max(f64::MIN_POSITIVE);
    if scale == 0.0 {
        0.0
    } else {
        small / scale
    }
}

/// The two Riccati equations at γ (one on each core), with w and z scaled by 1/γ so that R
/// stays well conditioned for any γ: with `S = diag(I/γ, I)`, the X equation on
/// `(A, BS, C₁ᵀC₁, SRS, C₁ᵀD₁•S)` has the same solution and the gain `S⁻¹·gain`
/// (`SRS = (D₁•S)ᵀ(D₁•S) − diag(I, 0)`); dually for Y with `T = diag(I/γ, I)` on the outputs.
/// The returned gains are the unscaled ones (`F = −gain_X`, `L = −gain_Yᵀ`).
fn riccati_pair(nz: &Normalized, gamma: f64) -> (Result<RiccatiSolution>, Result<RiccatiSolution>) {
    let bl = &nz.bl;
    let (m1, p1) = (bl.b1.ncols(), bl.c1.nrows());
    let b = hcat(&(&bl.b1 / gamma), &bl.b2);
    let c = vcat(&(&bl.c1 / gamma), &bl.c2);
    let d1 = hcat(&(&bl.d11 / gamma), &bl.d12);
    let dd1 = vcat(&(&bl.d11 / gamma), &bl.d21);
    let mut r = d1.transpose() * &d1;
    for i in 0..m1 {
        r[(i, i)] -= 1.0;
    }
    let mut rt = &dd1 * dd1.transpose();
    for i in 0..p1 {
        rt[(i, i)] -= 1.0;
    }
    let qx = bl.c1.transpose() * &bl.c1;
    let sx = bl.c1.transpose() * &d1;
    let qy = &bl.b1 * bl.b1.transpose();
    let sy = &bl.b1 * dd1.transpose();
    let at = bl.a.transpose();
    let ct = c.transpose();
    let unscale = |sol: Result<RiccatiSolution>, k: usize| {
        sol.map(|mut s| {
            for i in 0..k {
                s.gain.row_mut(i).scale_mut(1.0 / gamma);
            }
            s
        })
    };
    let (x, y) = rayon::join(
        || care_separated(&bl.a, &b, &qx, &r, Some(&sx)),
        || care_separated(&at, &ct, &qy, &rt, Some(&sy)),
    );
    (unscale(x, m1), unscale(y, p1))
}

/// The theorem's conditions at γ and, when they hold, the central controller whose loop must
/// be stable; `Ok(Err(outcome))` says which condition failed.
pub(crate) fn at_gamma(
    nz: &Normalized,
    gamma: f64,
) -> Result<std::result::Result<Level, GammaOutcome>> {
    let bound = parrott(nz);
    if gamma <= bound {
        return Ok(Err(GammaOutcome::BelowParrott { bound }));
    }
    let g2 = gamma * gamma;
    let (x, y) = riccati_pair(nz, gamma);
    let x = match x {
        Ok(x) => x,
        Err(e) => {
            return Ok(Err(GammaOutcome::XRiccati {
                reason: e.to_string(),
            }))
        }
    };
    let y = match y {
        Ok(y) => y,
        Err(e) => {
            return Ok(Err(GammaOutcome::YRiccati {
                reason: e.to_string(),
            }))
        }
    };
    let bl = &nz.bl;
    let ex = relative_min_eig(
        &x,
        &(bl.c1.transpose() * &bl.c1),
        &bl.a,
        &hcat(&bl.b1, &bl.b2),
    );
    let ey = relative_min_eig(
        &y,
        &(&bl.b1 * bl.b1.transpose()),
        &bl.a.transpose(),
        &vcat(&bl.c1, &bl.c2).transpose(),
    );
    // semidefinite up to the solution's own accuracy (κ·ε relative, κ its condition estimate)
    let psd = |sol: &RiccatiSolution| tol::PSD.max(100.0 * sol.condition * f64::EPSILON);
    if ex < -psd(&x) {
        return Ok(Err(GammaOutcome::XIndefinite { min_eigenvalue: ex }));
    }
    if ey < -psd(&y) {
        return Ok(Err(GammaOutcome::YIndefinite { min_eigenvalue: ey }));
    }
    let rho = eigenvalues(&(&x.x * &y.x))?
        .iter()
        .fold(0.0f64, |a, z| a.max(z.norm()));
    if rho >= g2 {
        return Ok(Err(GammaOutcome::Coupling {
            spectral_radius: rho,
            gamma_squared: g2,
        }));
    }
    let Some(controller) = central(nz, gamma, &x, &y)? else {
        return Ok(Err(GammaOutcome::ControllerSingular));
    };
    let cl = lft_lower(&nz.plant, &controller, nz.partition())?;
    let abscissa = eigenvalues(cl.a())?
        .iter()
        .fold(f64::NEG_INFINITY, |a, z| a.max(z.re));
    if abscissa.is_nan() || abscissa >= 0.0 {
        return Ok(Err(GammaOutcome::LoopUnstable { abscissa }));
    }
    Ok(Ok(Level { x, y, controller }))
}

/// Lower Cholesky factor of a symmetric positive definite matrix (`None` if it is not).
fn chol_lower(m: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    if m.is_empty() {
        return Some(m.clone());
    }
    m.clone().cholesky().map(|c| c.l())
}

/// `(γ²I − M)⁻¹`.
fn gamma_inv(g2: f64, m: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = m.nrows();
    (DMatrix::<f64>::identity(n, n) * g2 - m).try_inverse()
}

/// The central controller's formulas (module documentation); `None` when a factor that must be
/// positive definite or invertible is not (γ numerically at the optimum).
fn central(
    nz: &Normalized,
    gamma: f64,
    x: &RiccatiSolution,
    y: &RiccatiSolution,
) -> Result<Option<StateSpace>> {
    let bl = &nz.bl;
    let g2 = gamma * gamma;
    let p = parts(nz);
    let (m1, m2) = (bl.b1.ncols(), bl.b2.ncols());
    let (p1, p2) = (bl.c1.nrows(), bl.c2.nrows());
    let n = bl.a.nrows();
    let (Some(ga), Some(gb)) = (
        gamma_inv(g2, &(&p.d1111 * p.d1111.transpose())),
        gamma_inv(g2, &(p.d1111.transpose() * &p.d1111)),
    ) else {
        return Ok(None);
    };
    let dh11 = -(&p.d1121 * p.d1111.transpose() * &ga * &p.d1112) - &p.d1122;
    let i_m2 = DMatrix::<f64>::identity(m2, m2);
    let i_p2 = DMatrix::<f64>::identity(p2, p2);
    let (Some(dh12), Some(dh21t)) = (
        chol_lower(&(&i_m2 - &p.d1121 * &gb * p.d1121.transpose())),
        chol_lower(&(&i_p2 - p.d1112.transpose() * &ga * &p.d1112)),
    ) else {
        return Ok(None);
    };
    let dh21 = dh21t.transpose();
    let f = -&x.gain;
    let l = -y.gain.transpose();
    let f12 = f.rows(m1 - p2, p2).into_owned();
    let f2 = f.rows(m1, m2).into_owned();
    let l12 = l.columns(p1 - m2, m2).into_owned();
    let l2 = l.columns(p1, p2).into_owned();
    let Some(z) = (DMatrix::<f64>::identity(n, n) - &y.x * &x.x / g2).try_inverse() else {
        return Ok(None);
    };
    let (Some(dh12_inv), Some(dh21_inv)) = (dh12.clone().try_inverse(), dh21.clone().try_inverse())
    else {
        return Ok(None);
    };
    let bh2 = &z * (&bl.b2 + &l12) * &dh12;
    let ch2 = -(&dh21 * (&bl.c2 + &f12));
    let bh1 = -(&z * &l2) + &bh2 * &dh12_inv * &dh11;
    let ch1 = &f2 + &dh11 * &dh21_inv * &ch2;
    let b = hcat(&bl.b1, &bl.b2);
    let ah = &bl.a + &b * &f + &bh1 * &dh21_inv * &ch2;
    if [&ah, &bh1, &ch1, &dh11]
        .iter()
        .any(|m| m.iter().any(|v| !v.is_finite()))
    {
        return Ok(None);
    }
    Ok(Some(StateSpace::new(
        ah,
        bh1,
        ch1,
        dh11,
        SampleTime::Continuous,
    )?))
}
