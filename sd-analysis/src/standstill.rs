//! Standstill (disturbance) simulation: reference zero, a force disturbance at the plant input
//! and a sensor disturbance on the measurement.
//!
//! Single rate ([`standstill`]): `y = P(u + d)`, measured `m = y + v`, `u = −K m`; the
//! error is the measured output `e = m` (the servo error up to sign). With a slow controller
//! around a fast plant ([`standstill_multirate`], via [`sd_multirate::MultirateLoop`]) the same
//! loop with a slow hold and sampler gives the error at the fast rate and at the slow rate.

use crate::error::{AnalysisError, Result};
use nalgebra::{DMatrix, DVector};
use sd_model::StateSpace;
use sd_multirate::{MultirateLoop, MultirateSimulation};

/// Signals of a single-rate standstill simulation.
#[derive(Debug, Clone)]
pub struct Standstill {
    /// Error (measured output), N×ny.
    pub error: DMatrix<f64>,
    /// Controller output, N×nu.
    pub control: DMatrix<f64>,
}

/// Single-rate standstill simulation of discrete P and K from rest: `d` (N×nu) force, `v`
/// (N×ny) sensor disturbance.
///
/// # Errors
/// Continuous or mismatched models, wrong signal shapes, NaN, an ill-posed loop.
pub fn standstill(
    p: &StateSpace,
    k: &StateSpace,
    d: &DMatrix<f64>,
    v: &DMatrix<f64>,
) -> Result<Standstill> {
    if p.time().is_continuous() || !p.time().compatible(&k.time()) {
        return Err(AnalysisError::InvalidArgument(
            "standstill simulation needs a discrete plant and controller with the same ts".into(),
        ));
    }
    let (nu, ny) = (p.nu(), p.ny());
    if k.nu() != ny || k.ny() != nu {
        return Err(AnalysisError::InvalidArgument(format!(
            "the controller must be {nu}x{ny}, got {}x{}",
            k.ny(),
            k.nu()
        )));
    }
    if d.ncols() != nu || v.ncols() != ny || d.nrows() != v.nrows() {
        return Err(AnalysisError::InvalidArgument(format!(
            "disturbances must be N x {nu} (force) and N x {ny} (sensor) with the same N"
        )));
    }
    if d.iter().chain(v.iter()).any(|x| !x.is_finite()) {
        return Err(AnalysisError::InvalidArgument(
            "disturbances contain NaN or infinite values".into(),
        ));
    }
    // m = C x + D(u + d) + v, u = −(C_k ξ + D_k m)  ⇒  (I + D D_k) m = C x − D C_k ξ + D d + v
    let e = (DMatrix::<f64>::identity(ny, ny) + p.d() * k.d())
        .try_inverse()
        .ok_or_else(|| {
            AnalysisError::InvalidArgument("the loop is ill-posed (I + D_P D_K singular)".into())
        })?;
    let n = d.nrows();
    let mut x = DVector::<f64>::zeros(p.n());
    let mut xi = DVector::<f64>::zeros(k.n());
    let mut err = DMatrix::zeros(n, ny);
    let mut ctl = DMatrix::zeros(n, nu);
    for j in 0..n {
        let dj = d.row(j).transpose();
        let vj = v.row(j).transpose();
        let m = &e * (p.c() * &x - p.d() * (k.c() * &xi) + p.d() * &dj + &vj);
        let u = -(k.c() * &xi + k.d() * &m);
        xi = k.a() * &xi + k.b() * &m;
        x = p.a() * &x + p.b() * (&u + &dj);
        err.row_mut(j).copy_from(&m.transpose());
        ctl.row_mut(j).copy_from(&u.transpose());
    }
    Ok(Standstill {
        error: err,
        control: ctl,
    })
}

/// Multirate standstill: slow controller `k` (period F·h) around the fast plant `p_fast`
/// (period h); `d`, `v` at the fast rate. The fast error is `z_fast`, the slow one (every F-th
/// fast sample) `y_slow`, the controller's output `u_slow`.
///
/// # Errors
/// As [`sd_multirate::MultirateLoop::new`] and its simulation.
pub fn standstill_multirate(
    p_fast: &StateSpace,
    k: &StateSpace,
    factor: usize,
    d: &DMatrix<f64>,
    v: &DMatrix<f64>,
) -> Result<MultirateSimulation> {
    let l = MultirateLoop::new(p_fast, k, factor)?;
    Ok(l.simulate(d, v)?)
}
