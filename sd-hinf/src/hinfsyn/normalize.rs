//! From the user's generalized plant to the continuous, scaled problem the Glover–Doyle formulas
//! solve, and the controller back.
//!
//! 1. **Discrete plant → continuous** by the exact bilinear map ([`crate::bilinear`]): it
//!    preserves the H∞ norm and stability of every loop, so the continuous problem's γ_min and
//!    controllers are the discrete ones (its `D` is the discrete plant at `z = −1`).
//! 2. **Loop shift** (Safonov, Limebeer & Chiang, *Int. J. Control* 50, 1989): design for
//!    `ỹ = y − D₂₂u` (the plant with `D₂₂ = 0`), then `K = K̃(I + D₂₂K̃)⁻¹`.
//! 3. **Scaling**: `D₁₂ = U₁ΣV₁ᵀ` (thin SVD, full column rank required), `Θ₁₂ = [U₂ᵀ; U₁ᵀ]`
//!    (U₂ an orthonormal complement), `R₁₂ = V₁Σ⁻¹`: `Θ₁₂D₁₂R₁₂ = [0; I]`; dually
//!    `D₂₁ = U₁ΣV₁ᵀ`, `Θ₂₁ = [V₂ V₁]`, `R₂₁ = Σ⁻¹U₁ᵀ`: `R₂₁D₂₁Θ₂₁ = [0 I]`. `z̃ = Θ₁₂z`,
//!    `w = Θ₂₁w̃` are orthogonal (norms unchanged); `u = R₁₂ũ`, `ỹ = R₂₁y`, so the
//!    controller of the scaled problem `K̃` gives `K = R₁₂K̃R₂₁`.
//! 4. **State balancing** ([`sd_model::StateSpace::balance_states`]): powers-of-two state
//!    scaling of `[A B; C 0]`.

use crate::bilinear::{bilinear_to_continuous, bilinear_to_discrete};
use crate::error::{HinfError, Result};
use crate::lft::{undo_loop_shift, Blocks, Partition};
use crate::tol;
use nalgebra::DMatrix;
use sd_model::{SampleTime, StateSpace};

/// The continuous scaled problem (`D₁₂ = [0; I]`, `D₂₁ = [0 I]`, `D₂₂ = 0`) and what maps its
/// controller back to the user's plant.
#[derive(Debug, Clone)]
pub(crate) struct Normalized {
    /// The scaled continuous plant's blocks.
    pub bl: Blocks,
    /// The same as a state-space model (for closed-loop checks).
    pub plant: StateSpace,
    /// `u = R₁₂ũ`.
    r12: DMatrix<f64>,
    /// `ỹ = R₂₁y`.
    r21: DMatrix<f64>,
    /// The continuous plant's D₂₂ (undone by the loop shift).
    d22: DMatrix<f64>,
    /// The user's sample time.
    time: SampleTime,
}

/// Thin SVD factors of a full-rank matrix, sorted by decreasing singular value.
struct Svd {
    u: DMatrix<f64>,
    s: Vec<f64>,
    v: DMatrix<f64>,
}

fn svd(m: &DMatrix<f64>) -> Result<Svd> {
    let svd = m.clone().svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Err(HinfError::Numerical(
            "SVD of D₁₂/D₂₁ did not converge".into(),
        ));
    };
    Ok(Svd {
        u,
        s: svd.singular_values.iter().copied().collect(),
        v: vt.transpose(),
    })
}

/// An orthonormal basis of the complement of the range of `q` (orthonormal columns).
fn complement(q: &DMatrix<f64>) -> DMatrix<f64> {
    let (p, r) = q.shape();
    let mut m = DMatrix::<f64>::zeros(p, r + p);
    m.view_mut((0, 0), (p, r)).copy_from(q);
    m.view_mut((0, r), (p, p)).fill_with_identity();
    let full = m.qr().q();
    full.columns(r, p - r).into_owned()
}

/// Why a D₁₂ or D₂₁ does not have full rank, in the user's terms.
fn rank_error(which: &str, rank: usize, need: usize, discrete: bool) -> HinfError {
    let (at, fix) = if which == "D₁₂" {
        (
            "the controls are not penalized",
            "weight the control effort with a nonzero high-frequency gain (a W on u that is \
             not strictly proper)",
        )
    } else {
        (
            "some measurements are noise free",
            "add measurement noise with a nonzero high-frequency gain to every measurement",
        )
    };
    let place = if discrete {
        "the bilinear image's (the plant at z = −1, the Nyquist frequency)"
    } else {
        "the plant's (at infinite frequency)"
    };
    HinfError::InvalidArgument(format!(
        "{place} {which} has rank {rank} < {need}: {at} there, so no H∞ controller is defined \
         by the Riccati formulas; {fix}"
    ))
}

/// The scaling factors of D₁₂: `(Θ₁₂, R₁₂)`.
fn scale_d12(
    d12: &DMatrix<f64>,
    discrete: bool,
    floor: f64,
) -> Result<(DMatrix<f64>, DMatrix<f64>)> {
    let (p1, m2) = d12.shape();
    if p1 < m2 {
        return Err(rank_error("D₁₂", p1, m2, discrete));
    }
    let f = svd(d12)?;
    let big = f.s.first().copied().unwrap_or(0.0).max(floor);
    let rank = f.s.iter().filter(|&&v| v > tol::RANK * big).count();
    if rank < m2 {
        return Err(rank_error("D₁₂", rank, m2, discrete));
    }
    let u2 = complement(&f.u);
    let mut theta = DMatrix::<f64>::zeros(p1, p1);
    theta
        .view_mut((0, 0), (p1 - m2, p1))
        .copy_from(&u2.transpose());
    theta
        .view_mut((p1 - m2, 0), (m2, p1))
        .copy_from(&f.u.transpose());
    let r = DMatrix::from_fn(m2, m2, |i, j| f.v[(i, j)] / f.s[j]);
    Ok((theta, r))
}

/// The scaling factors of D₂₁: `(Θ₂₁, R₂₁)`.
fn scale_d21(
    d21: &DMatrix<f64>,
    discrete: bool,
    floor: f64,
) -> Result<(DMatrix<f64>, DMatrix<f64>)> {
    let (p2, m1) = d21.shape();
    if m1 < p2 {
        return Err(rank_error("D₂₁", m1, p2, discrete));
    }
    // D₂₁ᵀ = V₁ΣU₁ᵀ
    let f = svd(&d21.transpose())?;
    let big = f.s.first().copied().unwrap_or(0.0).max(floor);
    let rank = f.s.iter().filter(|&&v| v > tol::RANK * big).count();
    if rank < p2 {
        return Err(rank_error("D₂₁", rank, p2, discrete));
    }
    let (v1, u1) = (&f.u, &f.v);
    let v2 = complement(v1);
    let mut theta = DMatrix::<f64>::zeros(m1, m1);
    theta.view_mut((0, 0), (m1, m1 - p2)).copy_from(&v2);
    theta.view_mut((0, m1 - p2), (m1, p2)).copy_from(v1);
    let r = DMatrix::from_fn(p2, p2, |i, j| u1[(j, i)] / f.s[i]);
    Ok((theta, r))
}

/// Steps 1–3 of the module documentation.
pub(crate) fn normalize(p: &StateSpace, part: Partition) -> Result<Normalized> {
    part.split(p)?;
    let time = p.time();
    let discrete = time.is_discrete();
    let pc = if discrete {
        bilinear_to_continuous(p)?
    } else {
        p.clone()
    };
    let bl = part.split(&pc)?;
    let floor = tol::RANK * pc.d().norm().max(f64::MIN_POSITIVE);
    let (t12, r12) = scale_d12(&bl.d12, discrete, floor)?;
    let (t21, r21) = scale_d21(&bl.d21, discrete, floor)?;
    let (p1, m1) = bl.d11.shape();
    let (p2, m2) = bl.d22.shape();
    let mut d12 = DMatrix::<f64>::zeros(p1, m2);
    d12.view_mut((p1 - m2, 0), (m2, m2)).fill_with_identity();
    let mut d21 = DMatrix::<f64>::zeros(p2, m1);
    d21.view_mut((0, m1 - p2), (p2, p2)).fill_with_identity();
    let scaled = Blocks {
        a: bl.a.clone(),
        b1: &bl.b1 * &t21,
        b2: &bl.b2 * &r12,
        c1: &t12 * &bl.c1,
        c2: &r21 * &bl.c2,
        d11: &t12 * &bl.d11 * &t21,
        d12,
        d21,
        d22: DMatrix::zeros(p2, m2),
    };
    // step 4: balanced states (`StateSpace::balance_states`): a plant in metres and newtons
    // with a weight of 1e-7 on the force otherwise puts the Hamiltonian's entries 25 decades
    // apart; the controller's transfer function does not depend on the plant's coordinates
    let plant = assemble(&scaled)?.balance_states()?;
    let scaled = Partition {
        nmeas: p2,
        ncon: m2,
    }
    .split(&plant)?;
    Ok(Normalized {
        bl: scaled,
        plant,
        r12,
        r21,
        d22: bl.d22,
        time,
    })
}

/// The blocks as one state-space model (continuous).
fn assemble(bl: &Blocks) -> Result<StateSpace> {
    let n = bl.a.nrows();
    let (p1, m1) = bl.d11.shape();
    let (p2, m2) = bl.d22.shape();
    let mut b = DMatrix::<f64>::zeros(n, m1 + m2);
    b.view_mut((0, 0), (n, m1)).copy_from(&bl.b1);
    b.view_mut((0, m1), (n, m2)).copy_from(&bl.b2);
    let mut c = DMatrix::<f64>::zeros(p1 + p2, n);
    c.view_mut((0, 0), (p1, n)).copy_from(&bl.c1);
    c.view_mut((p1, 0), (p2, n)).copy_from(&bl.c2);
    let mut d = DMatrix::<f64>::zeros(p1 + p2, m1 + m2);
    d.view_mut((0, 0), (p1, m1)).copy_from(&bl.d11);
    d.view_mut((0, m1), (p1, m2)).copy_from(&bl.d12);
    d.view_mut((p1, 0), (p2, m1)).copy_from(&bl.d21);
    d.view_mut((p1, m1), (p2, m2)).copy_from(&bl.d22);
    Ok(StateSpace::new(
        bl.a.clone(),
        b,
        c,
        d,
        SampleTime::Continuous,
    )?)
}

impl Normalized {
    /// The scaled problem's partition (the user's).
    pub(crate) fn partition(&self) -> Partition {
        Partition {
            nmeas: self.bl.c2.nrows(),
            ncon: self.bl.b2.ncols(),
        }
    }

    /// The controller of the user's plant (its sample time, `u = K y`) from the scaled
    /// continuous problem's `K̃`: unscale, undo the loop shift, map back to discrete time.
    pub(crate) fn restore(&self, kt: &StateSpace) -> Result<StateSpace> {
        let (ak, bk, ck, dk) = (
            kt.a().clone(),
            kt.b() * &self.r21,
            &self.r12 * kt.c(),
            &self.r12 * kt.d() * &self.r21,
        );
        let k = undo_loop_shift(
            &StateSpace::new(ak, bk, ck, dk, SampleTime::Continuous)?,
            &self.d22,
        )?;
        match self.time.ts() {
            Some(ts) => bilinear_to_discrete(&k, ts),
            None => Ok(k),
        }
    }
}
