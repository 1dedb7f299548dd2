//! Algebraic Riccati equations: the stabilizing solution, its residual, the closed loop and a
//! condition estimate — or an error that says why there is none.
//!
//! **DARE** `AᵀXA − X − (AᵀXB + S)(R + BᵀXB)⁻¹(BᵀXA + Sᵀ) + Q = 0`, gain
//! `K = (R + BᵀXB)⁻¹(BᵀXA + Sᵀ)`, closed loop `A − BK` with spectral radius < 1.
//! **CARE** `AᵀX + XA − (XB + S)R⁻¹(BᵀX + Sᵀ) + Q = 0`, `K = R⁻¹(BᵀX + Sᵀ)`, `A − BK` Hurwitz.
//!
//! **Method, and why.**
//! - DARE: the structure-preserving doubling algorithm (SDA; Chu, Fan, Lin & Wang, *Linear
//!   Algebra Appl.* 396, 2005) on `(A_s, G, Q_s)` = `(A − BR⁻¹Sᵀ, BR⁻¹Bᵀ, Q − SR⁻¹Sᵀ)`:
//!   `W = I + G_kH_k`, `A_{k+1} = A_kW⁻¹A_k`, `G_{k+1} = G_k + A_kW⁻¹G_kA_kᵀ`,
//!   `H_{k+1} = H_k + A_kᵀH_kW⁻¹A_k`, `H_k → X` quadratically (error ~ ρ(A − BK)^{2^{k+1}});
//!   each step's two independent halves run on two cores (`sda.rs`, bit-identical to one). It
//!   needs no inverse of A (a delay or a weight state makes A singular), no eigenvalue
//!   reordering (faer's is not public), and it stays accurate when the closed loop has poles very
//!   close to the unit circle, as the lightly damped stage with its rigid body at z = 1 has —
//!   where an ordered Schur method must separate eigenvalues 1e-5 apart and SLICOT SB02OD
//!   reports "roundoff changed values of some complex eigenvalues". A singular or indefinite R
//!   (DAREX 1.1, 1.4) is handled exactly by the shift `X = X̃ + ρI`: X̃ solves the DARE with
//!   `(Q + ρ(AᵀA − I), R + ρBᵀB, S + ρAᵀB)`, whose R is positive definite when B has full
//!   column rank, and whose gain and closed loop are the same.
//! - CARE: the ordered complex Schur form of the Hamiltonian `[A_s −G; −Q_s −A_sᵀ]` (stable
//!   eigenvalues moved to the top by ZTREXC-style swaps, `X = U₂₁U₁₁⁻¹`; Laub 1979). The
//!   eigenvalues are split by the sign of their real parts, however close to the axis (CAREX
//!   2.8 has them ±5e-13 off it at ±1j); the refusal is then decided by the result: fewer or
//!   more than n stable eigenvalues, a singular `U₁₁`, or a refined X whose closed loop
//!   `A − BK` has an eigenvalue with a real part ≥ 0 (its abscissa is reported as
//!   `closed_loop`: the distance of the solution to the axis).
//! - Both: Newton refinement on the original data (Kleinman 1968 / Hewer 1971 as defect
//!   correction: `A_cᵀΔ + ΔA_c = −𝓡(X)` resp. `A_cᵀΔA_c − Δ = −𝓡(X)`, Bartels–Stewart), a step
//!   kept only when it lowers the residual. This is what recovers full accuracy on badly scaled
//!   problems (CAREX 2.6) where the Schur step alone loses digits.
//!
//! **Reported.** Relative residual `‖𝓡(X)‖_F / (‖Q‖ + ‖AᵀXA‖ + ‖X‖ + ‖(AᵀXB + S)K‖)` (DARE;
//! CARE: `‖Q‖ + 2‖AᵀX‖ + ‖(XB + S)K‖`); the closed-loop spectral radius (DARE) or abscissa
//! (CARE); and a relative condition estimate `κ = ‖Ω⁻¹‖(‖Q‖ + 2‖A‖‖X‖ + ‖A‖²‖G‖‖X‖²)/‖X‖`
//! (CT: `‖Q‖ + 2‖A‖‖X‖ + ‖G‖‖X‖²`; Byers 1985, Sun 1998) with `Ω` the closed-loop Lyapunov
//! (Stein) operator, `‖Ω⁻¹‖ = ‖Ω⁻¹(I)‖₂` exactly for these operators, all evaluated in the
//! coordinates that balance `A − BK` (so physical-coordinate scaling does not inflate it; the
//! DARE's `Ω⁻¹(I)` by a Smith sum run to 10⁻⁶ relative, [`tol::CONDITION_SUM`]).
//! Expect a relative error of about `κ·ε` in X (in those coordinates).

use crate::error::{HinfError, Result};
use crate::tol;
use faer::linalg::matmul::triangular::BlockStructure;
use faer::linalg::matmul::{matmul, triangular};
use faer::{Accum, Mat, MatRef, Par};
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::linalg::convert::{eigenvalues, from_faer, generalized_eigenvalues, to_faer};
use sd_model::linalg::expm::balance_diag;
use sd_model::linalg::lyap::{lyap, LyapKind};
use sd_model::linalg::schur::to_complex;
use sd_model::ModelError;

mod care;
mod cayley;
pub mod complex;
pub mod descriptor;
use care::care_residual;
pub(crate) use care::care_separated;
pub use care::{care, care_residual_of};

/// The stabilizing solution of a Riccati equation with its diagnostics.
#[derive(Debug, Clone)]
pub struct RiccatiSolution {
    /// The stabilizing solution X (symmetric).
    pub x: DMatrix<f64>,
    /// The gain K (control `u = −K x`).
    pub gain: DMatrix<f64>,
    /// Relative residual (module documentation).
    pub residual: f64,
    /// DARE: spectral radius of `A − BK` (< 1); CARE: spectral abscissa (< 0).
    pub closed_loop: f64,
    /// Relative condition estimate κ: expect a relative error of about κ·ε in X.
    pub condition: f64,
    /// Doubling (DARE) iterations used.
    pub doubling_steps: usize,
    /// Newton refinement steps kept.
    pub refinement_steps: usize,
}

struct Data {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    q: DMatrix<f64>,
    r: DMatrix<f64>,
    s: DMatrix<f64>,
}

fn symmetrize(m: &DMatrix<f64>) -> DMatrix<f64> {
    (m + m.transpose()) * 0.5
}

fn check(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<Data> {
    let n = a.nrows();
    let m = b.ncols();
    let shape = |what: &str, mat: &DMatrix<f64>, rr: usize, cc: usize| -> Result<()> {
        if mat.shape() != (rr, cc) {
            return Err(ModelError::dim(
                what,
                format!("{rr}x{cc}"),
                format!("{}x{}", mat.nrows(), mat.ncols()),
            )
            .into());
        }
        if mat.iter().any(|v| !v.is_finite()) {
            return Err(ModelError::NonFinite { what: what.into() }.into());
        }
        Ok(())
    };
    shape("A", a, n, n)?;
    shape("B", b, n, m)?;
    shape("Q", q, n, n)?;
    shape("R", r, m, m)?;
    let s = match s {
        Some(s) => {
            shape("S", s, n, m)?;
            s.clone()
        }
        None => DMatrix::zeros(n, m),
    };
    for (what, mat) in [("Q", q), ("R", r)] {
        let nm = mat.norm();
        let asym = (mat - mat.transpose()).norm();
        if asym > tol::SYMMETRY * nm.max(f64::MIN_POSITIVE) {
            return Err(HinfError::NotSymmetric {
                what,
                asymmetry: asym / nm,
            });
        }
    }
    Ok(Data {
        a: a.clone(),
        b: b.clone(),
        q: symmetrize(q),
        r: symmetrize(r),
        s,
    })
}

/// `R⁻¹M` by Cholesky when R is positive definite (well conditioned enough), else `None`.
fn spd_solve(r: &DMatrix<f64>, m: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let ch = r.clone().cholesky()?;
    let l = ch.l();
    let dmin = l
        .diagonal()
        .iter()
        .fold(f64::INFINITY, |acc, v| acc.min(v.abs()));
    let dmax = l.diagonal().iter().fold(0.0f64, |acc, v| acc.max(v.abs()));
    if dmin <= tol::SPD_PIVOT * dmax {
        return None;
    }
    Some(ch.solve(m))
}

/// `R⁻¹M` for a symmetric R that is positive definite ([`spd_solve`]) or indefinite but
/// invertible (the H∞ Riccati equations' `D₁•ᵀD₁• − diag(γ²I, 0)`), by the symmetric
/// eigendecomposition `R = VΛVᵀ`; `None` when `min|λ| ≤ SPD_PIVOT·max|λ|`.
fn sym_solve(r: &DMatrix<f64>, m: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    if let Some(x) = spd_solve(r, m) {
        return Some(x);
    }
    let eig = r.clone().symmetric_eigen();
    let big = eig.eigenvalues.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let small = eig
        .eigenvalues
        .iter()
        .fold(f64::INFINITY, |a, v| a.min(v.abs()));
    if small.is_nan() || small <= tol::SPD_PIVOT * big {
        return None;
    }
    let vt_m = eig.eigenvectors.transpose() * m;
    let scaled = DMatrix::from_fn(vt_m.nrows(), vt_m.ncols(), |i, j| {
        vt_m[(i, j)] / eig.eigenvalues[i]
    });
    Some(&eig.eigenvectors * scaled)
}

fn radius(m: &DMatrix<f64>) -> Result<f64> {
    Ok(eigenvalues(m)?.iter().map(|z| z.norm()).fold(0.0, f64::max))
}

fn abscissa(m: &DMatrix<f64>) -> Result<f64> {
    Ok(eigenvalues(m)?
        .iter()
        .map(|z| z.re)
        .fold(f64::NEG_INFINITY, f64::max))
}

// ---------------------------------------------------------------------------------------------
// DARE

/// DARE residual, its normalisation and the gain at X.
fn dare_residual(d: &Data, x: &DMatrix<f64>) -> Result<(DMatrix<f64>, f64, DMatrix<f64>)> {
    let xb = x * &d.b;
    let m = &d.r + d.b.transpose() * &xb;
    let t = d.a.transpose() * &xb + &d.s; // AᵀXB + S
    let lu = m.clone().lu();
    let k = lu.solve(&t.transpose()).ok_or_else(|| {
        HinfError::Numerical("R + BᵀXB is singular at the current solution".into())
    })?;
    let axa = d.a.transpose() * x * &d.a;
    let tk = &t * &k;
    let res = symmetrize(&(&axa - x - &tk + &d.q));
    let scale = d.q.norm() + axa.norm() + x.norm() + tk.norm();
    let rel = res.norm() / scale.max(f64::MIN_POSITIVE);
    Ok((res, rel, k))
}

pub(crate) fn all_finite(m: &Mat<f64>) -> bool {
    (0..m.ncols()).all(|j| m.col_as_slice(j).iter().all(|v| v.is_finite()))
}

/// `‖m‖_F` by a plain sum of squares over the columns (faer's overflow-safe `norm_l2` was most
/// of the Smith sum's time, more than its products), the safe one only when the plain sum
/// over- or underflows.
pub(crate) fn frobenius(m: &Mat<f64>) -> f64 {
    let mut acc = [0.0f64; 4];
    for j in 0..m.ncols() {
        let col = m.col_as_slice(j);
        let mut chunks = col.chunks_exact(4);
        for c in &mut chunks {
            for k in 0..4 {
                acc[k] += c[k] * c[k];
            }
        }
        for (k, v) in chunks.remainder().iter().enumerate() {
            acc[k] += v * v;
        }
    }
    let s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    if s.is_finite() && s > 1e-280 {
        s.sqrt()
    } else {
        m.norm_l2()
    }
}

/// `dst ← (accumulate ? dst : 0) + lhs·rhs` without allocating.
pub(crate) fn mm(dst: &mut Mat<f64>, add: bool, lhs: MatRef<'_, f64>, rhs: MatRef<'_, f64>) {
    matmul(
        dst.as_mut(),
        if add { Accum::Add } else { Accum::Replace },
        lhs,
        rhs,
        1.0,
        Par::Seq,
    );
}

/// `dst ← dst + lhs·rhs` in the lower triangle only, then mirrored onto the upper one: for a
/// product known to be symmetric (half the flops of [`mm`]; the result exactly symmetric).
pub(crate) fn mm_sym(dst: &mut Mat<f64>, add: bool, lhs: MatRef<'_, f64>, rhs: MatRef<'_, f64>) {
    triangular::matmul(
        dst.as_mut(),
        BlockStructure::TriangularLower,
        if add { Accum::Add } else { Accum::Replace },
        lhs,
        BlockStructure::Rectangular,
        rhs,
        BlockStructure::Rectangular,
        1.0,
        Par::Seq,
    );
    mirror_lower(dst);
}

/// `Σ_k (Mᵀ)^k Q M^k` (the solution of `MᵀPM − P + Q = 0`; Q = I when `None`) by squaring
/// (Smith's iteration: after step j the sum holds the first 2^j terms), for ρ(M) < 1, until a
/// step adds less than `tol` relative (ε for a solution, looser for an estimate: the terms left
/// out then weigh about `tol` too, as they fall off doubly exponentially); `None` when it does
/// not settle within [`tol::MAX_DOUBLING`] squarings. Matrix products only (faer), no Schur
/// form: log₂(log tol / log ρ) steps of `P·M`, the lower triangle of the symmetric `Mᵀ(PM)`
/// and `M²`.
fn stein_sum(m: &DMatrix<f64>, q: Option<&DMatrix<f64>>, tol: f64) -> Option<DMatrix<f64>> {
    let n = m.nrows();
    let mut p = match q {
        Some(q) => to_faer(q),
        None => Mat::<f64>::identity(n, n),
    };
    let mut mk = to_faer(m);
    let (mut t, mut inc, mut sq) = (
        Mat::<f64>::zeros(n, n),
        Mat::<f64>::zeros(n, n),
        Mat::<f64>::zeros(n, n),
    );
    for _ in 0..tol::MAX_DOUBLING {
        mm(&mut t, false, p.as_ref(), mk.as_ref());
        mm_sym(&mut inc, false, mk.transpose(), t.as_ref());
        let (ni, np) = (frobenius(&inc), frobenius(&p));
        p += &inc;
        if !np.is_finite() {
            return None;
        }
        if ni <= tol * np {
            return Some(from_faer(p.as_ref()));
        }
        mm(&mut sq, false, mk.as_ref(), mk.as_ref());
        std::mem::swap(&mut mk, &mut sq);
    }
    None
}

/// The solution P of the continuous Lyapunov equation `A_cᵀP + PA_c + Q = 0` (A_c stable) by
/// the Cayley transform and [`stein_sum`]: with `M = (I − A_c)⁻¹`, `A_d = M(I + A_c)`,
/// `A_dᵀPA_d − P = Mᵀ[(I + A_c)ᵀP(I + A_c) − (I − A_c)ᵀP(I − A_c)]M = 2Mᵀ(A_cᵀP + PA_c)M`,
/// so P solves the Stein equation `A_dᵀPA_d − P + 2MᵀQM = 0` (matrix products only, no Schur
/// form). `None` when `I − A_c` is singular or the sum does not settle (eigenvalues of A_c very
/// far from the unit frequency on either side): the caller then uses Bartels–Stewart.
fn lyap_ct_by_stein(ac: &DMatrix<f64>, q: &DMatrix<f64>, tol: f64) -> Option<DMatrix<f64>> {
    let n = ac.nrows();
    let ident = DMatrix::<f64>::identity(n, n);
    let m = (&ident - ac).try_inverse()?;
    let ad = &m * (&ident + ac);
    let qd = symmetrize(&(m.transpose() * q * &m * 2.0));
    let p = stein_sum(&ad, Some(&qd), tol)?;
    p.iter().all(|v| v.is_finite()).then_some(p)
}

/// Copies the lower triangle of the square `m` onto its upper one.
fn mirror_lower(m: &mut Mat<f64>) {
    for j in 0..m.ncols() {
        for i in (j + 1)..m.nrows() {
            m[(j, i)] = m[(i, j)];
        }
    }
}

/// Stabilizing solution of the DARE (module documentation).
///
/// `s` is the cross term (zero if `None`). R may be singular or indefinite as long as
/// `R + BᵀXB` is invertible at the solution and B has full column rank.
///
/// # Errors
/// Shapes, NaN, asymmetric Q or R; [`HinfError::NoStabilizingSolution`] saying whether the
/// symplectic pencil has eigenvalues on the unit circle, (A, B) is not stabilizable or the
/// problem is not detectable.
pub fn dare(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<RiccatiSolution> {
    let d = check(a, b, q, r, s)?;
    let n = d.a.nrows();
    if n == 0 {
        return Ok(empty(d.b.ncols()));
    }
    let first = dare_initial(&d);
    let (x0, steps) = match first {
        Ok(v) => v,
        Err(e) => return Err(diagnose(&d, Kind::Discrete).unwrap_or(e)),
    };
    finish(&d, x0, steps, Kind::Discrete)
}

fn dare_initial(d: &Data) -> Result<(DMatrix<f64>, usize)> {
    let n = d.a.nrows();
    let m = d.b.ncols();
    let mut rho = 0.0;
    let (r, s, q) = if spd_solve(&d.r, &DMatrix::identity(m, m)).is_some() {
        (d.r.clone(), d.s.clone(), d.q.clone())
    } else {
        // shift X = X̃ + ρI so that R̃ = R + ρBᵀB is positive definite
        let btb = d.b.transpose() * &d.b;
        rho = (d.q.norm() + d.r.norm()).max(1.0) / btb.norm().max(f64::MIN_POSITIVE);
        let ident = DMatrix::<f64>::identity(n, n);
        (
            &d.r + &btb * rho,
            &d.s + d.a.transpose() * &d.b * rho,
            symmetrize(&(&d.q + (d.a.transpose() * &d.a - ident) * rho)),
        )
    };
    let rinv_st = spd_solve(&r, &s.transpose()).ok_or_else(|| {
        HinfError::InvalidArgument(
            "R (after the shift for a singular R) is not positive definite: B must have full \
             column rank"
                .into(),
        )
    })?;
    let rinv_bt = spd_solve(&r, &d.b.transpose())
        .ok_or_else(|| HinfError::Numerical("R is not positive definite".into()))?;
    let a_s = &d.a - &d.b * &rinv_st;
    let q_s = symmetrize(&(&q - &s * &rinv_st));
    let g = symmetrize(&(&d.b * &rinv_bt));
    let (x, it) = crate::sda::doubling(&a_s, &g, &q_s)?;
    let x = if rho != 0.0 {
        x + DMatrix::<f64>::identity(n, n) * rho
    } else {
        x
    };
    Ok((x, it))
}

// ---------------------------------------------------------------------------------------------
// common

#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Continuous,
    Discrete,
}

fn empty(m: usize) -> RiccatiSolution {
    RiccatiSolution {
        x: DMatrix::zeros(0, 0),
        gain: DMatrix::zeros(m, 0),
        residual: 0.0,
        closed_loop: 0.0,
        condition: 1.0,
        doubling_steps: 0,
        refinement_steps: 0,
    }
}

fn residual(d: &Data, x: &DMatrix<f64>, kind: Kind) -> Result<(DMatrix<f64>, f64, DMatrix<f64>)> {
    match kind {
        Kind::Discrete => dare_residual(d, x),
        Kind::Continuous => care_residual(d, x),
    }
}

/// Newton refinement, closed loop, condition; errors if the result is not stabilizing.
fn finish(
    d: &Data,
    x0: DMatrix<f64>,
    doubling_steps: usize,
    kind: Kind,
) -> Result<RiccatiSolution> {
    let mut x = x0;
    let (mut res, mut rel, mut k) = residual(d, &x, kind)?;
    let mut steps = 0;
    for _ in 0..tol::MAX_NEWTON {
        if rel <= tol::NEWTON_STOP {
            break;
        }
        let ac = &d.a - &d.b * &k;
        // the correction solves the (closed-loop) Stein or Lyapunov equation; a step is kept
        // only when it lowers the residual
        let delta = match kind {
            Kind::Discrete => stein_sum(&ac, Some(&res), f64::EPSILON)
                .map_or_else(|| lyap(&ac.transpose(), &res, LyapKind::Discrete), Ok),
            Kind::Continuous => lyap_ct_by_stein(&ac, &res, f64::EPSILON)
                .map_or_else(|| lyap(&ac.transpose(), &res, LyapKind::Continuous), Ok),
        };
        let Ok(delta) = delta else { break };
        let xn = symmetrize(&(&x + &delta));
        let Ok((rn, reln, kn)) = residual(d, &xn, kind) else {
            break;
        };
        if reln.partial_cmp(&rel) != Some(std::cmp::Ordering::Less) {
            break;
        }
        x = xn;
        res = rn;
        rel = reln;
        k = kn;
        steps += 1;
    }
    let ac = &d.a - &d.b * &k;
    // closed-loop eigenvalues and the condition estimate are independent
    let (cl, condition) = rayon::join(
        || match kind {
            Kind::Discrete => radius(&ac),
            Kind::Continuous => abscissa(&ac),
        },
        || condition(d, &x, &ac, kind).unwrap_or(f64::INFINITY),
    );
    let cl = cl?;
    let stabilizing = match kind {
        Kind::Discrete => cl < 1.0,
        Kind::Continuous => cl < 0.0,
    };
    if !stabilizing {
        return Err(
            diagnose(d, kind).unwrap_or_else(|| HinfError::NoStabilizingSolution {
                equation: name(kind).into(),
                reason: format!(
                "the computed solution does not stabilize the closed loop (closed-loop {} = {cl})",
                if kind == Kind::Discrete { "spectral radius" } else { "abscissa" }
            ),
            }),
        );
    }
    Ok(RiccatiSolution {
        x,
        gain: k,
        residual: rel,
        closed_loop: cl,
        condition,
        doubling_steps,
        refinement_steps: steps,
    })
}

fn name(kind: Kind) -> &'static str {
    match kind {
        Kind::Discrete => "DARE",
        Kind::Continuous => "CARE",
    }
}

fn condition(d: &Data, x: &DMatrix<f64>, ac: &DMatrix<f64>, kind: Kind) -> Result<f64> {
    let n = d.a.nrows();
    // evaluate in the coordinates that balance the closed loop (x = D x̃): the estimate is
    // then not inflated by the scale disparity of physical coordinates
    let (acb, dv) = balance_diag(ac);
    let scale = |m: &DMatrix<f64>, left: bool, right: bool| {
        DMatrix::from_fn(m.nrows(), m.ncols(), |i, j| {
            let mut v = m[(i, j)];
            if left {
                v *= dv[i];
            }
            if right {
                v *= dv[j];
            }
            v
        })
    };
    let xb = scale(x, true, true); // DᵀXD
    let qb = scale(&d.q, true, true);
    let ab = balance_with(&d.a, &dv);
    let bb = DMatrix::from_fn(n, d.b.ncols(), |i, j| d.b[(i, j)] / dv[i]);
    let ident = DMatrix::<f64>::identity(n, n);
    let p = match kind {
        Kind::Discrete => match stein_sum(&acb, None, tol::CONDITION_SUM) {
            Some(p) => p,
            None => lyap(&acb.transpose(), &ident, LyapKind::Discrete)?,
        },
        Kind::Continuous => match lyap_ct_by_stein(&acb, &ident, tol::CONDITION_SUM) {
            Some(p) => p,
            None => lyap(&acb.transpose(), &ident, LyapKind::Continuous)?,
        },
    };
    let omega_inv = p.norm();
    let m = match kind {
        Kind::Discrete => &d.r + bb.transpose() * &xb * &bb,
        Kind::Continuous => d.r.clone(),
    };
    let g = match m.clone().lu().solve(&bb.transpose()) {
        Some(mb) => &bb * mb,
        None => return Ok(f64::INFINITY),
    };
    let (na, nx) = (ab.norm(), xb.norm().max(f64::MIN_POSITIVE));
    let num = match kind {
        Kind::Discrete => qb.norm() + 2.0 * na * na * nx + na * na * g.norm() * nx * nx,
        Kind::Continuous => qb.norm() + 2.0 * na * nx + g.norm() * nx * nx,
    };
    Ok(omega_inv * num / nx)
}

/// `D⁻¹ M D` for the diagonal `d`.
fn balance_with(m: &DMatrix<f64>, d: &[f64]) -> DMatrix<f64> {
    DMatrix::from_fn(m.nrows(), m.ncols(), |i, j| m[(i, j)] * d[j] / d[i])
}

/// Says why there is no stabilizing solution, when one of the classical conditions fails.
fn diagnose(d: &Data, kind: Kind) -> Option<HinfError> {
    let n = d.a.nrows();
    let m = d.b.ncols();
    let err = |reason: String| HinfError::NoStabilizingSolution {
        equation: name(kind).into(),
        reason,
    };
    // eigenvalues of the extended pencil on the unit circle / imaginary axis
    let nn = 2 * n + m;
    let mut l = DMatrix::<f64>::zeros(nn, nn);
    let mut e = DMatrix::<f64>::zeros(nn, nn);
    match kind {
        Kind::Discrete => {
            // [A 0 B; −Q I −S; Sᵀ 0 R] − λ [I 0 0; 0 Aᵀ 0; 0 −Bᵀ 0]
            l.view_mut((0, 0), (n, n)).copy_from(&d.a);
            l.view_mut((0, 2 * n), (n, m)).copy_from(&d.b);
            l.view_mut((n, 0), (n, n)).copy_from(&(-&d.q));
            l.view_mut((n, n), (n, n)).fill_with_identity();
            l.view_mut((n, 2 * n), (n, m)).copy_from(&(-&d.s));
            l.view_mut((2 * n, 0), (m, n)).copy_from(&d.s.transpose());
            l.view_mut((2 * n, 2 * n), (m, m)).copy_from(&d.r);
            e.view_mut((0, 0), (n, n)).fill_with_identity();
            e.view_mut((n, n), (n, n)).copy_from(&d.a.transpose());
            e.view_mut((2 * n, n), (m, n))
                .copy_from(&(-d.b.transpose()));
        }
        Kind::Continuous => {
            // [A 0 B; −Q −Aᵀ −S; Sᵀ Bᵀ R] − λ [I 0 0; 0 I 0; 0 0 0]
            l.view_mut((0, 0), (n, n)).copy_from(&d.a);
            l.view_mut((0, 2 * n), (n, m)).copy_from(&d.b);
            l.view_mut((n, 0), (n, n)).copy_from(&(-&d.q));
            l.view_mut((n, n), (n, n)).copy_from(&(-d.a.transpose()));
            l.view_mut((n, 2 * n), (n, m)).copy_from(&(-&d.s));
            l.view_mut((2 * n, 0), (m, n)).copy_from(&d.s.transpose());
            l.view_mut((2 * n, n), (m, n)).copy_from(&d.b.transpose());
            l.view_mut((2 * n, 2 * n), (m, m)).copy_from(&d.r);
            e.view_mut((0, 0), (2 * n, 2 * n)).fill_with_identity();
        }
    }
    if let Ok(ev) = generalized_eigenvalues(&l, &e) {
        for (al, be) in ev {
            if be.norm() <= tol::INFINITE_EIG * al.norm() {
                continue;
            }
            let z = al / be;
            let bad = match kind {
                Kind::Discrete => (z.norm() - 1.0).abs() <= tol::CIRCLE,
                Kind::Continuous => z.re.abs() <= tol::CIRCLE * z.norm().max(1.0),
            };
            if bad {
                return Some(err(format!(
                    "the {} pencil has an eigenvalue on the {} at {:.6}{:+.6}i: a mode there \
                     that the input cannot move or Q does not see, or a loop that cannot be \
                     made strictly stable",
                    if kind == Kind::Discrete {
                        "symplectic"
                    } else {
                        "Hamiltonian"
                    },
                    if kind == Kind::Discrete {
                        "unit circle"
                    } else {
                        "imaginary axis"
                    },
                    z.re,
                    z.im
                )));
            }
        }
    }
    // PBH tests on the modes that need moving
    let scale = d.a.norm() + d.b.norm() + d.q.norm();
    if let Some(z) = unmovable_mode(&d.a, &d.b, kind == Kind::Discrete, scale, tol::PBH) {
        return Some(err(format!(
            "(A, B) is not stabilizable: the mode at {:.6}{:+.6}i cannot be moved by the input",
            z.re, z.im
        )));
    }
    let Ok(eigs) = eigenvalues(&d.a) else {
        return None;
    };
    for z in eigs {
        let unstable = match kind {
            Kind::Discrete => z.norm() >= 1.0 - tol::CIRCLE,
            Kind::Continuous => z.re >= -tol::CIRCLE * z.norm().max(1.0),
        };
        if !unstable {
            continue;
        }
        let shifted = to_complex(&d.a) - DMatrix::<C>::identity(n, n) * z;
        let mut aq = DMatrix::<C>::zeros(2 * n, n);
        aq.view_mut((0, 0), (n, n)).copy_from(&shifted);
        aq.view_mut((n, 0), (n, n)).copy_from(&to_complex(&d.q));
        if smallest_sv(&aq) <= tol::PBH * scale {
            return Some(err(format!(
                "the problem is not detectable: Q does not see the mode at {:.6}{:+.6}i",
                z.re, z.im
            )));
        }
    }
    None
}

/// The first mode of A on or outside the stability boundary (unit circle when `discrete`, else
/// imaginary axis) that B cannot move: the PBH test `σ_min([A − λI  B̃]) ≤ rel_tol·scale` with B
/// rescaled to `B̃ = B·s/‖B‖`, `s = max(‖A‖, scale)` (the rank of `[A − λI  B]` does not depend
/// on B's units; a position sensor in metres, C ~ 1e-9, must not look undetectable), after the
/// states of `[A B]` are balanced by powers of two (nor on the state coordinates: a weight
/// realized with entries of 1e3 must not raise the threshold for the plant's modes).
pub(crate) fn unmovable_mode(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    discrete: bool,
    scale: f64,
    rel_tol: f64,
) -> Option<C> {
    let (n, m) = (a.nrows(), b.ncols());
    let mut padded = DMatrix::<f64>::zeros(n + m, n + m);
    padded.view_mut((0, 0), (n, n)).copy_from(a);
    padded.view_mut((0, n), (n, m)).copy_from(b);
    let (bal, _) = sd_model::linalg::expm::balance_leading(&padded, n);
    let a = &bal.view((0, 0), (n, n)).into_owned();
    let b = &bal.view((0, n), (n, m)).into_owned();
    let eigs = eigenvalues(a).ok()?;
    let s = a.norm().max(scale).max(f64::MIN_POSITIVE);
    let bn = b.norm();
    let bs = if bn > 0.0 { b * (s / bn) } else { b.clone() };
    eigs.into_iter().find(|&z| {
        let unstable = if discrete {
            z.norm() >= 1.0 - tol::CIRCLE
        } else {
            z.re >= -tol::CIRCLE * z.norm().max(1.0)
        };
        if !unstable {
            return false;
        }
        let mut ab = DMatrix::<C>::zeros(n, n + m);
        ab.view_mut((0, 0), (n, n))
            .copy_from(&(to_complex(a) - DMatrix::<C>::identity(n, n) * z));
        ab.view_mut((0, n), (n, m)).copy_from(&to_complex(&bs));
        smallest_sv(&ab) <= rel_tol * s
    })
}

/// σ_min of a tall or wide complex matrix by the SVD of the matrix itself (the Gram matrix
/// `MᴴM` would square the condition and round every σ_min below √ε·σ_max to zero — a PBH test
/// at a defective eigenvalue, computed √ε off, then sees a mode that cannot be moved); the Gram
/// route only if the SVD does not converge.
fn smallest_sv(m: &DMatrix<C>) -> f64 {
    let min_of = |s: &nalgebra::DVector<f64>| s.iter().cloned().fold(f64::INFINITY, f64::min);
    if let Some(s) = nalgebra::linalg::SVD::try_new(m.clone(), false, false, f64::EPSILON, 1000) {
        return min_of(&s.singular_values).max(0.0);
    }
    let g = if m.nrows() >= m.ncols() {
        m.adjoint() * m
    } else {
        m * m.adjoint()
    };
    match nalgebra::linalg::SVD::try_new(g, false, false, f64::EPSILON, 1000) {
        Some(s) => min_of(&s.singular_values).max(0.0).sqrt(),
        None => f64::INFINITY,
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn m(r: usize, c: usize, v: &[f64]) -> DMatrix<f64> {
        DMatrix::from_row_slice(r, c, v)
    }

    /// CAREX 2.8 (Benner, Laub & Mehrmann 1995; ε = 1e-6): the Hamiltonian's eigenvalues are
    /// ±5e-13 off the imaginary axis at ±1j, a stabilizing solution exists: solved, its
    /// closed loop stable (abscissa negative, at rounding distance of the axis) and its
    /// residual `‖AᵀX + XA − XBR⁻¹BᵀX + Q‖_F` at `100·n·ε·(‖Q‖ + 2‖A‖‖X‖ + ‖B‖²‖X‖²)`.
    /// Eigenvalues exactly on the axis with no stabilizing solution (an undamped oscillator
    /// that Q does not see) are still refused.
    #[test]
    fn near_axis_care_is_solved_and_on_axis_refused() {
        let e = 1e-6;
        let a = m(
            4,
            4,
            &[
                -e, 1.0, 0.0, 0.0, -1.0, -e, 0.0, 0.0, 0.0, 0.0, e, 1.0, 0.0, 0.0, -1.0, e,
            ],
        );
        let b = DMatrix::from_element(4, 1, 1.0);
        let q = DMatrix::from_element(4, 4, 1.0);
        let r = m(1, 1, &[1.0]);
        let sol = care(&a, &b, &q, &r, None).expect("CAREX 2.8 has a stabilizing solution");
        let x = &sol.x;
        let res = a.transpose() * x + x * &a - x * &b * b.transpose() * x + &q;
        let scale = q.norm() + 2.0 * a.norm() * x.norm() + b.norm_squared() * x.norm_squared();
        assert!(
            res.norm() <= 100.0 * 4.0 * f64::EPSILON * scale,
            "residual {:e} of {scale:e}",
            res.norm()
        );
        println!(
            "CAREX 2.8: residual {:.2e} (relative {:.2e}), closed-loop abscissa {:.2e}, \
             condition {:.2e}",
            res.norm(),
            sol.residual,
            sol.closed_loop,
            sol.condition
        );
        assert!(
            sol.closed_loop < 0.0 && sol.closed_loop > -1e-6,
            "{}",
            sol.closed_loop
        );
        let osc = m(2, 2, &[0.0, 1.0, -1.0, 0.0]);
        let err = care(&osc, &m(2, 1, &[0.0, 1.0]), &DMatrix::zeros(2, 2), &r, None);
        assert!(
            err.is_err(),
            "an undamped mode Q does not see has no stabilizing solution"
        );
    }

    /// Smith's squaring (`stein_sum`) against the Bartels–Stewart Stein solver on a lightly
    /// damped 2×2 rotation block and a random stable 12×12 matrix with an indefinite Q: the
    /// residual `‖MᵀPM − P + Q‖` within `10·n·ε·(‖M‖²‖P‖ + ‖Q‖)` per squaring (at most
    /// [`tol::MAX_DOUBLING`] of them), and the two solutions as close, relative to `‖P‖/‖Q‖`.
    #[test]
    fn stein_sum_solves_the_stein_equation() {
        let (c, s) = (0.999f64 * 0.3f64.cos(), 0.999f64 * 0.3f64.sin());
        let rot = m(2, 2, &[c, -s, s, c]);
        let mut seed = 7u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let r = DMatrix::from_fn(12, 12, |_, _| rnd());
        let r = &r * (0.9 / r.clone().singular_values().max());
        let q12 = DMatrix::from_fn(12, 12, |_, _| rnd());
        let q12 = &q12 + q12.transpose();
        for (mm_, q) in [(rot, m(2, 2, &[1.0, 0.3, 0.3, -2.0])), (r, q12)] {
            let n = mm_.nrows() as f64;
            let p = stein_sum(&mm_, Some(&q), f64::EPSILON).unwrap();
            let res = (mm_.transpose() * &p * &mm_ - &p + &q).norm();
            let scale = mm_.norm().powi(2) * p.norm() + q.norm();
            let reference = lyap(&mm_.transpose(), &q, LyapKind::Discrete).unwrap();
            let kappa = p.norm() / q.norm();
            let diff = (&p - &reference).norm() / reference.norm();
            let steps = tol::MAX_DOUBLING as f64;
            assert!(
                res <= 10.0 * n * f64::EPSILON * scale * steps,
                "{res} vs {scale}"
            );
            assert!(
                diff <= 10.0 * n * f64::EPSILON * kappa * steps,
                "{diff} κ {kappa}"
            );
        }
    }

    #[test]
    fn scalar_dare_and_care() {
        // DT: x = a²x − a²x²b²/(r + b²x) + q with a = 2, b = 1, q = 1, r = 1:
        // x² − 4x − 1 = 0 → x = 2 + √5
        let s = dare(
            &m(1, 1, &[2.0]),
            &m(1, 1, &[1.0]),
            &m(1, 1, &[1.0]),
            &m(1, 1, &[1.0]),
            None,
        )
        .unwrap();
        assert!((s.x[(0, 0)] - (2.0 + 5f64.sqrt())).abs() < 1e-13);
        assert!(s.closed_loop < 1.0 && s.residual < 1e-15);
        // CT: 2ax − x² + 1 = 0 with a = 1 → x = 1 + √2
        let s = care(
            &m(1, 1, &[1.0]),
            &m(1, 1, &[1.0]),
            &m(1, 1, &[1.0]),
            &m(1, 1, &[1.0]),
            None,
        )
        .unwrap();
        assert!((s.x[(0, 0)] - (1.0 + 2f64.sqrt())).abs() < 1e-13);
        assert!(s.closed_loop < 0.0);
    }

    #[test]
    fn cross_term_equals_completed_square() {
        // S ≠ 0 equals the problem with A − BR⁻¹Sᵀ, Q − SR⁻¹Sᵀ
        let a = m(2, 2, &[0.9, 0.3, -0.2, 1.1]);
        let b = m(2, 1, &[0.0, 1.0]);
        let q = m(2, 2, &[2.0, 0.1, 0.1, 1.0]);
        let r = m(1, 1, &[0.5]);
        let s = m(2, 1, &[0.2, -0.1]);
        let x1 = dare(&a, &b, &q, &r, Some(&s)).unwrap().x;
        let a2 = &a - &b * s.transpose() / 0.5;
        let q2 = &q - &s * s.transpose() / 0.5;
        let x2 = dare(&a2, &b, &q2, &r, None).unwrap().x;
        assert!((&x1 - &x2).norm() < 1e-12 * x2.norm());
        let c1 = care(&a, &b, &q, &r, Some(&s)).unwrap().x;
        let c2 = care(&a2, &b, &q2, &r, None).unwrap().x;
        assert!((&c1 - &c2).norm() < 1e-12 * c2.norm());
    }

    #[test]
    fn says_why_there_is_no_solution() {
        // an unreachable unstable mode
        let a = m(2, 2, &[1.5, 0.0, 0.0, 0.5]);
        let b = m(2, 1, &[0.0, 1.0]);
        let q = DMatrix::identity(2, 2);
        let r = m(1, 1, &[1.0]);
        let e = dare(&a, &b, &q, &r, None).unwrap_err().to_string();
        assert!(
            e.contains("not stabilizable") || e.contains("unit circle"),
            "{e}"
        );
        // an undamped oscillator that Q does not see: eigenvalues on the circle
        let w: f64 = 0.3;
        let a = m(2, 2, &[w.cos(), w.sin(), -w.sin(), w.cos()]);
        let q = DMatrix::zeros(2, 2);
        let e = dare(&a, &b, &q, &r, None).unwrap_err().to_string();
        assert!(e.contains("unit circle") || e.contains("detectable"), "{e}");
        let ac = m(2, 2, &[0.0, 1.0, -1.0, 0.0]);
        let e = care(&ac, &b, &q, &r, None).unwrap_err().to_string();
        assert!(
            e.contains("imaginary axis") || e.contains("detectable"),
            "{e}"
        );
        // bad shapes and asymmetry
        assert!(dare(&a, &b, &m(2, 2, &[1.0, 2.0, 0.0, 1.0]), &r, None).is_err());
        assert!(care(&a, &b, &q, &m(2, 2, &[1.0, 0.0, 0.0, 1.0]), None).is_err());
        // a singular R is refused (an indefinite one is allowed: the H∞ Riccati equations)
        let stable = m(2, 2, &[-1.0, 0.0, 0.0, -2.0]);
        let eye = m(2, 2, &[1.0, 0.0, 0.0, 1.0]);
        let e = care(&stable, &b, &eye, &m(1, 1, &[0.0]), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("invertible"), "{e}");
    }
}
