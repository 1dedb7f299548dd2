//! The exact bilinear (Cayley) map between discrete and continuous time, with the √2 scaling
//! that keeps it balanced: `z = (1 + s)/(1 − s)` carries the unit circle onto the imaginary
//! axis (`z = e^{jθ}` ↔ `s = j·tan(θ/2)`, `z = −1` ↔ `s = ∞`), the unit disc onto the open left
//! half plane, so it preserves stability, the H∞ norm and every interconnection (it is a change
//! of variable). Used to solve discrete H∞ problems with the continuous formulas (loopshaping,
//! [`crate::hinfsyn()`]; e.g. Zhou, Doyle & Glover, *Robust and Optimal Control* (1996), ch. 21).

use crate::error::{HinfError, Result};
use nalgebra::DMatrix;
use sd_model::{SampleTime, StateSpace};

/// The bilinear map `z = (1 + s)/(1 − s)`: discrete `(A, B, C, D)` → continuous, with
/// `M = (I + A)⁻¹`: `(M(A − I), √2·MB, √2·CM, D − CMB)`.
pub fn bilinear_to_continuous(g: &StateSpace) -> Result<StateSpace> {
    let n = g.n();
    let ident = DMatrix::<f64>::identity(n, n);
    let m = (&ident + g.a()).try_inverse().ok_or_else(|| {
        HinfError::InvalidArgument(
            "the system has a pole at z = −1 (the Nyquist frequency), which the bilinear map \
             cannot carry; move it (e.g. out of a weight) or remove it"
                .into(),
        )
    })?;
    let r2 = std::f64::consts::SQRT_2;
    let mb = &m * g.b();
    Ok(StateSpace::new(
        &m * (g.a() - &ident),
        &mb * r2,
        g.c() * &m * r2,
        g.d() - g.c() * &mb,
        SampleTime::Continuous,
    )?)
}

/// The inverse map `s = (z − 1)/(z + 1)`: continuous → discrete at period `ts`, with
/// `N = (I − A)⁻¹`: `((I + A)N, √2·NB, √2·CN, D + CNB)`.
pub fn bilinear_to_discrete(g: &StateSpace, ts: f64) -> Result<StateSpace> {
    let n = g.n();
    let ident = DMatrix::<f64>::identity(n, n);
    let nm = (&ident - g.a()).try_inverse().ok_or_else(|| {
        HinfError::Numerical(
            "the system has a pole at s = 1 in the bilinear domain (z = ∞ after the map)".into(),
        )
    })?;
    let r2 = std::f64::consts::SQRT_2;
    let nb = &nm * g.b();
    Ok(StateSpace::new(
        (&ident + g.a()) * &nm,
        &nb * r2,
        g.c() * &nm * r2,
        g.d() + g.c() * &nb,
        SampleTime::discrete(ts)?,
    )?)
}
