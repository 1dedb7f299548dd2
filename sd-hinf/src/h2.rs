//! Discrete-time LQR, Kalman filter (LQE) and H2 synthesis on a generalized plant.
//!
//! **`dlqr`** — `min Σ xᵀQx + uᵀRu + 2xᵀNu` for `x⁺ = Ax + Bu`: `u = −Kx`,
//! `K = (R + BᵀXB)⁻¹(BᵀXA + Nᵀ)`, X the stabilizing DARE solution (python-control's and
//! MATLAB's `dlqr`).
//!
//! **`dlqe`** — `x⁺ = Ax + Bu + Gw`, `y = Cx + Du + v`, `E[wwᵀ] = Q_N`, `E[vvᵀ] = R_N`,
//! `E[wvᵀ] = N_N` (cross term allowed; python-control 0.10 refuses it): P the stationary
//! one-step prediction error covariance, from the DARE on `(Aᵀ, Cᵀ, GQ_NGᵀ, R_N, GN_N)`;
//! `W = CPCᵀ + R_N`; predictor gain `L = (APCᵀ + GN_N)W⁻¹` (python-control's `dlqe` result:
//! `x̂⁺ = Ax̂ + Bu + L(y − Cx̂ − Du)`), filter gain `M = PCᵀW⁻¹` (MATLAB's `dlqe`:
//! `x̂(k|k) = x̂(k|k−1) + M(y − Cx̂(k|k−1) − Du)`), filtered covariance `Z = P − MCPᵀ`.
//!
//! **`h2syn`** — the controller `u = K y` minimizing `‖F_l(P, K)‖₂` (white unit-intensity w).
//! Discrete time (e.g. Chen & Francis, *Optimal Sampled-Data Control Systems*, 1995, ch. 6):
//! certainty equivalence with the *filtered* estimates. The full-information optimum is
//! `u = Fx + F_w w` with X the DARE on `(A, B₂, C₁ᵀC₁, D₁₂ᵀD₁₂, C₁ᵀD₁₂)`,
//! `H = B₂ᵀXB₂ + D₁₂ᵀD₁₂`, `F = −H⁻¹(B₂ᵀXA + D₁₂ᵀC₁)`, `F_w = −H⁻¹(B₂ᵀXB₁ + D₁₂ᵀD₁₁)`;
//! Y the DARE on `(Aᵀ, C₂ᵀ, B₁B₁ᵀ, D₂₁D₂₁ᵀ, B₁D₂₁ᵀ)`, `W = C₂YC₂ᵀ + D₂₁D₂₁ᵀ`,
//! `L = −(AYC₂ᵀ + B₁D₂₁ᵀ)W⁻¹`, and the innovation `e = y − C₂ξ` (ξ the predicted state) gives
//! `x̂(k|k) = ξ + YC₂ᵀW⁻¹e`, `ŵ(k|k) = D₂₁ᵀW⁻¹e`. With `M = FYC₂ᵀW⁻¹ + F_wD₂₁ᵀW⁻¹`:
//! `K = [A + B₂F + LC₂ − B₂MC₂, B₂M − L; F − MC₂, M]` (for D₂₂ = 0; a D₂₂ is removed by the
//! loop shift [`crate::undo_loop_shift`]). Continuous time (Doyle, Glover, Khargonekar &
//! Francis, IEEE TAC 34, 1989): the CARE analogues, `K = [A + B₂F + LC₂, −L; F, 0]`, which needs
//! `D₁₁ = 0` (otherwise no controller makes the norm finite).
//!
//! The achieved norm is the closed loop's, computed by [`sd_model::StateSpace::h2_norm`]
//! (controllability Gramian) on the user's plant, not taken from the Riccati solutions.

use crate::error::{HinfError, Result};
use crate::lft::{lft_lower, undo_loop_shift, Partition};
use crate::riccati::{care, dare, RiccatiSolution};
use nalgebra::DMatrix;
use num_complex::Complex64;
use sd_model::linalg::convert::eigenvalues;
use sd_model::{ModelError, StateSpace};
use serde::Serialize;

/// The result of [`dlqr`].
#[derive(Debug, Clone)]
pub struct Lqr {
    /// The gain K (`u = −Kx`).
    pub gain: DMatrix<f64>,
    /// The DARE solution X (the cost-to-go `xᵀXx`).
    pub x: DMatrix<f64>,
    /// The closed-loop poles, eigenvalues of `A − BK`.
    pub poles: Vec<Complex64>,
    /// The Riccati equation's relative residual and condition estimate.
    pub riccati: RiccatiSolution,
}

/// Discrete LQR (module documentation). `n` is the cross weight N (zero if `None`).
///
/// # Errors
/// As [`dare`]: shapes, NaN, asymmetric Q/R, no stabilizing solution (with the reason).
pub fn dlqr(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    n: Option<&DMatrix<f64>>,
) -> Result<Lqr> {
    let sol = dare(a, b, q, r, n)?;
    let poles = eigenvalues(&(a - b * &sol.gain))?;
    Ok(Lqr {
        gain: sol.gain.clone(),
        x: sol.x.clone(),
        poles,
        riccati: sol,
    })
}

/// The result of [`dlqe`].
#[derive(Debug, Clone)]
pub struct Kalman {
    /// Predictor gain L (python-control's `dlqe`).
    pub predictor_gain: DMatrix<f64>,
    /// Filter (innovation) gain M (MATLAB's `dlqe`).
    pub filter_gain: DMatrix<f64>,
    /// Stationary one-step prediction error covariance P.
    pub p: DMatrix<f64>,
    /// Stationary filtered error covariance Z.
    pub z: DMatrix<f64>,
    /// The estimator's poles, eigenvalues of `A − LC`.
    pub poles: Vec<Complex64>,
    /// The Riccati equation's relative residual and condition estimate.
    pub riccati: RiccatiSolution,
}

/// Discrete Kalman filter (module documentation). `nn` is the cross covariance `E[wvᵀ]`.
///
/// # Errors
/// Shapes (G must have as many columns as Q_N has rows, C as many columns as A), NaN, no
/// stabilizing solution (undetectable (C, A) or a noise-free unstable mode, with the reason),
/// a singular innovation covariance.
pub fn dlqe(
    a: &DMatrix<f64>,
    g: &DMatrix<f64>,
    c: &DMatrix<f64>,
    qn: &DMatrix<f64>,
    rn: &DMatrix<f64>,
    nn: Option<&DMatrix<f64>>,
) -> Result<Kalman> {
    let n = a.nrows();
    if g.nrows() != n || qn.shape() != (g.ncols(), g.ncols()) || c.ncols() != n {
        return Err(ModelError::dim(
            "dlqe (G n×q, Q_N q×q, C p×n)",
            format!("G {n}×q, Q_N q×q, C p×{n}"),
            format!(
                "G {}×{}, Q_N {}×{}, C {}×{}",
                g.nrows(),
                g.ncols(),
                qn.nrows(),
                qn.ncols(),
                c.nrows(),
                c.ncols()
            ),
        )
        .into());
    }
    if let Some(nn) = nn {
        if nn.shape() != (g.ncols(), c.nrows()) {
            return Err(ModelError::dim(
                "N_N (q×p)",
                format!("{}x{}", g.ncols(), c.nrows()),
                format!("{}x{}", nn.nrows(), nn.ncols()),
            )
            .into());
        }
    }
    let s = nn.map(|nn| g * nn);
    let sol = dare(
        &a.transpose(),
        &c.transpose(),
        &(g * qn * g.transpose()),
        rn,
        s.as_ref(),
    )?;
    let p = sol.x.clone();
    let w = c * &p * c.transpose() + rn;
    let pct = &p * c.transpose();
    let filter_gain = w
        .clone()
        .lu()
        .solve(&pct.transpose())
        .ok_or_else(|| {
            HinfError::Numerical("the innovation covariance CPCᵀ + R_N is singular".into())
        })?
        .transpose();
    let predictor_gain = sol.gain.transpose();
    let z = &p - &filter_gain * c * &p;
    let poles = eigenvalues(&(a - &predictor_gain * c))?;
    Ok(Kalman {
        predictor_gain,
        filter_gain,
        p,
        z: (&z + z.transpose()) * 0.5,
        poles,
        riccati: sol,
    })
}

/// The result of [`h2syn`].
#[derive(Debug, Clone, Serialize)]
pub struct H2Synthesis {
    /// The controller, `u = K y`, in the plant's time domain (serialized by the caller).
    #[serde(skip)]
    pub controller: StateSpace,
    /// `‖F_l(P, K)‖₂` by the closed loop's Gramian.
    pub achieved_norm: f64,
    /// Whether all closed-loop poles are stable.
    pub closed_loop_stable: bool,
    /// Controller order.
    pub controller_order: usize,
    /// Relative residuals of the control (X) and filter (Y) Riccati equations.
    pub riccati_residuals: [f64; 2],
    /// Their condition estimates.
    pub riccati_conditions: [f64; 2],
}

/// H2 synthesis (module documentation).
///
/// # Errors
/// A wrong partition; no stabilizing solution of either Riccati equation (with the reason:
/// not stabilizable/detectable, zeros on the boundary, D₁₂/D₂₁ rank); a continuous plant with
/// D₁₁ ≠ 0; an ill-posed loop shift.
pub fn h2syn(p: &StateSpace, part: Partition) -> Result<H2Synthesis> {
    let bl = part.split(p)?;
    let discrete = p.time().is_discrete();
    if !discrete && bl.d11.iter().any(|v| *v != 0.0) {
        return Err(HinfError::InvalidArgument(
            "continuous H2 synthesis needs D₁₁ = 0 (a direct path from w to z makes every \
             loop's H2 norm infinite): remove it or design in discrete time"
                .into(),
        ));
    }
    let solve = if discrete { dare } else { care };
    let (x, y) = rayon::join(
        || {
            solve(
                &bl.a,
                &bl.b2,
                &(bl.c1.transpose() * &bl.c1),
                &(bl.d12.transpose() * &bl.d12),
                Some(&(bl.c1.transpose() * &bl.d12)),
            )
        },
        || {
            solve(
                &bl.a.transpose(),
                &bl.c2.transpose(),
                &(&bl.b1 * bl.b1.transpose()),
                &(&bl.d21 * bl.d21.transpose()),
                Some(&(&bl.b1 * bl.d21.transpose())),
            )
        },
    );
    let name = |which: &str, e: HinfError| match e {
        HinfError::NoStabilizingSolution { reason, .. } => HinfError::NoStabilizingSolution {
            equation: format!("{which} Riccati equation of the H2 synthesis"),
            reason,
        },
        other => other,
    };
    let x = x.map_err(|e| name("control (X)", e))?;
    let y = y.map_err(|e| name("filter (Y)", e))?;
    let f = -&x.gain;
    let l = -y.gain.transpose();
    let kt = if discrete {
        discrete_controller(&bl, &x, &y, &f, &l, p)?
    } else {
        StateSpace::new(
            &bl.a + &bl.b2 * &f + &l * &bl.c2,
            -&l,
            f.clone(),
            DMatrix::zeros(part.ncon, part.nmeas),
            p.time(),
        )?
    };
    let k = undo_loop_shift(&kt, &bl.d22)?;
    let cl = lft_lower(p, &k, part)?;
    let stable = cl
        .poles()?
        .iter()
        .all(|z| if discrete { z.norm() < 1.0 } else { z.re < 0.0 });
    let achieved_norm = if stable { cl.h2_norm()? } else { f64::INFINITY };
    Ok(H2Synthesis {
        controller_order: k.n(),
        controller: k,
        achieved_norm,
        closed_loop_stable: stable,
        riccati_residuals: [x.residual, y.residual],
        riccati_conditions: [x.condition, y.condition],
    })
}

/// The discrete controller with the filtered state and disturbance estimates.
fn discrete_controller(
    bl: &crate::lft::Blocks,
    x: &RiccatiSolution,
    y: &RiccatiSolution,
    f: &DMatrix<f64>,
    l: &DMatrix<f64>,
    p: &StateSpace,
) -> Result<StateSpace> {
    let singular = |what: &str| HinfError::Numerical(format!("{what} is singular"));
    let h = bl.b2.transpose() * &x.x * &bl.b2 + bl.d12.transpose() * &bl.d12;
    let fw = -(h
        .lu()
        .solve(&(bl.b2.transpose() * &x.x * &bl.b1 + bl.d12.transpose() * &bl.d11))
        .ok_or_else(|| singular("B₂ᵀXB₂ + D₁₂ᵀD₁₂"))?);
    let w = &bl.c2 * &y.x * bl.c2.transpose() + &bl.d21 * bl.d21.transpose();
    let winv = w
        .try_inverse()
        .ok_or_else(|| singular("C₂YC₂ᵀ + D₂₁D₂₁ᵀ"))?;
    let m = f * &y.x * bl.c2.transpose() * &winv + &fw * bl.d21.transpose() * &winv;
    let b2m = &bl.b2 * &m;
    Ok(StateSpace::new(
        &bl.a + &bl.b2 * f + l * &bl.c2 - &b2m * &bl.c2,
        &b2m - l,
        f - &m * &bl.c2,
        m,
        p.time(),
    )?)
}
