//! The generalized plant's partition and the lower linear fractional transformation.
//!
//! A generalized plant `P` maps `[w; u]` (exogenous inputs, then `ncon` controls) to `[z; y]`
//! (performance outputs, then `nmeas` measurements):
//!
//! ```text
//! ẋ = A x + B₁ w + B₂ u        (x(k+1) in discrete time)
//! z = C₁ x + D₁₁ w + D₁₂ u
//! y = C₂ x + D₂₁ w + D₂₂ u
//! ```
//!
//! and the controller closes `u = K y` (positive feedback: the convention of MATLAB's `hinfsyn`,
//! `lft` and SLICOT's SB10 routines). The closed loop `F_l(P, K)` from `w` to `z` needs
//! `I − D_K D₂₂` invertible (a well-posed loop). Formulas: Zhou, Doyle & Glover, *Robust and
//! Optimal Control* (1996), ch. 10 (linear fractional transformations) — written
//! out below so that the code can be checked against them.

use crate::error::{HinfError, Result};
use nalgebra::DMatrix;
use sd_model::{ModelError, StateSpace};

/// How many of the plant's last outputs are measurements and last inputs are controls.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Partition {
    /// Measurements `y`: the last `nmeas` outputs.
    pub nmeas: usize,
    /// Controls `u`: the last `ncon` inputs.
    pub ncon: usize,
}

/// The plant's matrices cut by a [`Partition`].
#[derive(Debug, Clone)]
pub struct Blocks {
    /// A.
    pub a: DMatrix<f64>,
    /// B₁ (exogenous inputs), B₂ (controls).
    pub b1: DMatrix<f64>,
    /// B₂.
    pub b2: DMatrix<f64>,
    /// C₁ (performance outputs).
    pub c1: DMatrix<f64>,
    /// C₂ (measurements).
    pub c2: DMatrix<f64>,
    /// D₁₁.
    pub d11: DMatrix<f64>,
    /// D₁₂.
    pub d12: DMatrix<f64>,
    /// D₂₁.
    pub d21: DMatrix<f64>,
    /// D₂₂.
    pub d22: DMatrix<f64>,
}

impl Partition {
    /// Checks the partition against the plant and cuts its matrices.
    ///
    /// # Errors
    /// [`HinfError::InvalidArgument`] when `nmeas` or `ncon` is zero or leaves no exogenous
    /// channel (the plant needs at least one `w` and one `z`).
    pub fn split(&self, p: &StateSpace) -> Result<Blocks> {
        let (ny, nu) = (p.ny(), p.nu());
        if self.nmeas == 0 || self.ncon == 0 {
            return Err(HinfError::InvalidArgument(format!(
                "nmeas = {} and ncon = {} must both be at least 1 (the controller reads the \
                 last nmeas outputs and drives the last ncon inputs)",
                self.nmeas, self.ncon
            )));
        }
        if self.nmeas >= ny || self.ncon >= nu {
            return Err(HinfError::InvalidArgument(format!(
                "the plant has {ny} outputs and {nu} inputs: nmeas = {} must be below the \
                 output count and ncon = {} below the input count, leaving at least one \
                 performance output z and one exogenous input w",
                self.nmeas, self.ncon
            )));
        }
        let (p1, m1) = (ny - self.nmeas, nu - self.ncon);
        let n = p.n();
        let (b, c, d) = (p.b(), p.c(), p.d());
        Ok(Blocks {
            a: p.a().clone(),
            b1: b.view((0, 0), (n, m1)).into_owned(),
            b2: b.view((0, m1), (n, self.ncon)).into_owned(),
            c1: c.view((0, 0), (p1, n)).into_owned(),
            c2: c.view((p1, 0), (self.nmeas, n)).into_owned(),
            d11: d.view((0, 0), (p1, m1)).into_owned(),
            d12: d.view((0, m1), (p1, self.ncon)).into_owned(),
            d21: d.view((p1, 0), (self.nmeas, m1)).into_owned(),
            d22: d.view((p1, m1), (self.nmeas, self.ncon)).into_owned(),
        })
    }
}

/// The lower LFT `F_l(P, K)`: the closed loop from `w` to `z` with `u = K y`.
///
/// With `M = (I − D_K D₂₂)⁻¹`: `u = M(D_K C₂ x + C_K x_K + D_K D₂₁ w)`,
/// `y = C₂ x + D₂₁ w + D₂₂ u`; then `ẋ = A x + B₁ w + B₂ u`, `ẋ_K = A_K x_K + B_K y`,
/// `z = C₁ x + D₁₁ w + D₁₂ u`. States `[x; x_K]`.
///
/// # Errors
/// Different sample times, a controller of the wrong size, or an ill-posed loop.
pub fn lft_lower(p: &StateSpace, k: &StateSpace, part: Partition) -> Result<StateSpace> {
    if !p.time().compatible(&k.time()) {
        return Err(HinfError::InvalidArgument(
            "plant and controller have different sample times".into(),
        ));
    }
    let bl = part.split(p)?;
    if k.nu() != part.nmeas || k.ny() != part.ncon {
        return Err(ModelError::dim(
            "controller (ncon outputs x nmeas inputs)",
            format!("{}x{}", part.ncon, part.nmeas),
            format!("{}x{}", k.ny(), k.nu()),
        )
        .into());
    }
    let (n, nk, m1) = (p.n(), k.n(), bl.b1.ncols());
    let m = (DMatrix::<f64>::identity(part.ncon, part.ncon) - k.d() * &bl.d22)
        .try_inverse()
        .ok_or_else(|| {
            HinfError::InvalidArgument(
                "I − D_K·D₂₂ is singular: the loop is ill-posed (algebraic loop)".into(),
            )
        })?;
    // u = ux·x + uk·x_K + uw·w
    let ux = &m * k.d() * &bl.c2;
    let uk = &m * k.c();
    let uw = &m * k.d() * &bl.d21;
    // y = yx·x + yk·x_K + yw·w
    let yx = &bl.c2 + &bl.d22 * &ux;
    let yk = &bl.d22 * &uk;
    let yw = &bl.d21 + &bl.d22 * &uw;
    let nt = n + nk;
    let mut a = DMatrix::<f64>::zeros(nt, nt);
    a.view_mut((0, 0), (n, n))
        .copy_from(&(&bl.a + &bl.b2 * &ux));
    a.view_mut((0, n), (n, nk)).copy_from(&(&bl.b2 * &uk));
    a.view_mut((n, 0), (nk, n)).copy_from(&(k.b() * &yx));
    a.view_mut((n, n), (nk, nk))
        .copy_from(&(k.a() + k.b() * &yk));
    let mut b = DMatrix::<f64>::zeros(nt, m1);
    b.view_mut((0, 0), (n, m1))
        .copy_from(&(&bl.b1 + &bl.b2 * &uw));
    b.view_mut((n, 0), (nk, m1)).copy_from(&(k.b() * &yw));
    let p1 = bl.c1.nrows();
    let mut c = DMatrix::<f64>::zeros(p1, nt);
    c.view_mut((0, 0), (p1, n))
        .copy_from(&(&bl.c1 + &bl.d12 * &ux));
    c.view_mut((0, n), (p1, nk)).copy_from(&(&bl.d12 * &uk));
    let d = &bl.d11 + &bl.d12 * &uw;
    Ok(StateSpace::new(a, b, c, d, p.time())?)
}

/// Undoes a loop shift: the controller `K̃` designed for `ỹ = y − D₂₂u` (the plant with its
/// D₂₂ removed) becomes `K = K̃(I + D₂₂K̃)⁻¹` for the plant itself (Safonov, Limebeer & Chiang,
/// *Int. J. Control* 50, 1989). In state space, with `M = (I + D_K D₂₂)⁻¹`:
/// `(A_K − B_K D₂₂ M C_K, B_K(I − D₂₂ M D_K), M C_K, M D_K)`.
///
/// # Errors
/// [`HinfError::Numerical`] when `I + D_K D₂₂` is singular (the shifted loop is ill-posed).
pub fn undo_loop_shift(k: &StateSpace, d22: &DMatrix<f64>) -> Result<StateSpace> {
    let m2 = k.ny();
    if d22.shape() != (k.nu(), m2) {
        return Err(ModelError::dim(
            "D₂₂ (nmeas x ncon)",
            format!("{}x{}", k.nu(), m2),
            format!("{}x{}", d22.nrows(), d22.ncols()),
        )
        .into());
    }
    let m = (DMatrix::<f64>::identity(m2, m2) + k.d() * d22)
        .try_inverse()
        .ok_or_else(|| {
            HinfError::Numerical(
                "I + D_K·D₂₂ is singular: the loop shift back to the plant's D₂₂ is ill-posed"
                    .into(),
            )
        })?;
    let bd = k.b() * d22 * &m;
    Ok(StateSpace::new(
        k.a() - &bd * k.c(),
        k.b() - &bd * k.d(),
        &m * k.c(),
        &m * k.d(),
        k.time(),
    )?)
}
