//! Input delays of discrete models: whole sample periods exactly (a shift register), a
//! fraction of one by Thiran's first-order allpass.
//!
//! **Whole samples**: `G(z)·z^{−m}`, `m·nu` registers after the model's own states (so its
//! first `n` states stay its own).
//!
//! **A fractional delay** `e^{−jωDT}` is not rational in `z`. Thiran's allpass of order one
//! (J.-P. Thiran, "Recursive digital filters with maximally flat group delay", *IEEE Trans.
//! Circuit Theory* 18(6), 1971; Laakso, Välimäki, Karjalainen & Laine, "Splitting the unit
//! delay", *IEEE Signal Processing Magazine* 13(1), 1996, §3.3) has unit gain at every
//! frequency and a group delay maximally flat at ω = 0 equal to `D`:
//! `H(z) = (a + z⁻¹)/(1 + a·z⁻¹)`, `a = (1 − D)/(1 + D)`, stable for `D > 0`
//! (`|a| < 1`); its phase error grows towards Nyquist and is least for `D ∈ [0.5, 1.5]`, so a
//! delay `τ ≥ 0.5` is split as `τ = m + D` with `D` in that range. The realization is
//! `x⁺ = −a·x + u`, `y = (1 − a²)·x + a·u`. [`phase_error_deg`] states the approximation's
//! worst phase error over given frequencies.

use crate::error::{ModelError, Result};
use crate::ss::StateSpace;
use crate::SampleTime;
use nalgebra::DMatrix;
use std::f64::consts::PI;

/// `sys` preceded by `m` whole sample periods of delay on every input (`m·nu` registers after
/// its states; `D` moves to the output map of the last register).
///
/// # Errors
/// A continuous-time model.
pub fn whole_input_delay(sys: &StateSpace, m: usize) -> Result<StateSpace> {
    if sys.time().is_continuous() {
        return Err(ModelError::InvalidArgument(
            "a whole-sample input delay needs a discrete model".into(),
        ));
    }
    if m == 0 {
        return Ok(sys.clone());
    }
    let (n, nu, ny) = (sys.n(), sys.nu(), sys.ny());
    let nd = m * nu;
    let mut a = DMatrix::<f64>::zeros(n + nd, n + nd);
    let mut b = DMatrix::<f64>::zeros(n + nd, nu);
    let mut c = DMatrix::<f64>::zeros(ny, n + nd);
    a.view_mut((0, 0), (n, n)).copy_from(sys.a());
    // register j (0-based) holds u_{k−1−j}; the model sees the oldest, u_{k−m}
    let last = n + (m - 1) * nu;
    a.view_mut((0, last), (n, nu)).copy_from(sys.b());
    for j in 1..m {
        a.view_mut((n + j * nu, n + (j - 1) * nu), (nu, nu))
            .fill_with_identity();
    }
    b.view_mut((n, 0), (nu, nu)).fill_with_identity();
    c.view_mut((0, 0), (ny, n)).copy_from(sys.c());
    c.view_mut((0, last), (ny, nu)).copy_from(sys.d());
    let out = StateSpace::new(a, b, c, DMatrix::zeros(ny, nu), sys.time())?;
    Ok(out.with_labels_of(sys))
}

/// Thiran's first-order allpass of delay `d` samples (module documentation), SISO at `ts`.
///
/// # Errors
/// `d` not positive and finite, an invalid `ts`.
pub fn thiran(d: f64, ts: f64) -> Result<StateSpace> {
    if !(d.is_finite() && d > 0.0) {
        return Err(ModelError::InvalidArgument(format!(
            "a Thiran allpass needs a positive delay; got {d} samples"
        )));
    }
    let a = thiran_coefficient(d);
    StateSpace::new(
        DMatrix::from_element(1, 1, -a),
        DMatrix::from_element(1, 1, 1.0),
        DMatrix::from_element(1, 1, 1.0 - a * a),
        DMatrix::from_element(1, 1, a),
        SampleTime::discrete(ts)?,
    )
}

/// `a = (1 − D)/(1 + D)` of Thiran's first-order allpass of delay `D`.
fn thiran_coefficient(d: f64) -> f64 {
    (1.0 - d) / (1.0 + d)
}

/// A SISO discrete model preceded by an input delay of `tau` samples: whole samples exactly,
/// the rest by [`thiran`] (`tau ≥ 0.5` split so that its part is in `[0.5, 1.5)`).
///
/// # Errors
/// A continuous or non-SISO model, `tau` negative or not finite.
pub fn input_delay(sys: &StateSpace, tau: f64) -> Result<StateSpace> {
    let Some(ts) = sys.ts() else {
        return Err(ModelError::InvalidArgument(
            "an input delay needs a discrete model".into(),
        ));
    };
    if sys.nu() != 1 || sys.ny() != 1 {
        return Err(ModelError::InvalidArgument(format!(
            "a fractional input delay is for a SISO model; this one is {}x{}",
            sys.ny(),
            sys.nu()
        )));
    }
    if !(tau.is_finite() && tau >= 0.0) {
        return Err(ModelError::InvalidArgument(format!(
            "an input delay must be finite and not negative; got {tau} samples"
        )));
    }
    let (whole, frac) = split(tau);
    let delayed = whole_input_delay(sys, whole)?;
    if frac == 0.0 {
        return Ok(delayed);
    }
    crate::connect::series(&thiran(frac, ts)?, &delayed)
}

/// `tau = whole + frac` with `frac` 0 (a whole number of samples), in `(0, 0.5)` when
/// `tau < 0.5`, else in `[0.5, 1.5)`.
fn split(tau: f64) -> (usize, f64) {
    let r = tau.round();
    if (tau - r).abs() <= 1e-12 * tau.max(1.0) {
        return (r as usize, 0.0);
    }
    if tau < 0.5 {
        return (0, tau);
    }
    let whole = (tau - 0.5).floor();
    (whole as usize, tau - whole)
}

/// The worst phase error (degrees) of [`input_delay`]'s realization of `tau` samples against
/// the exact `e^{−jωτT}` over `freq_hz` at period `ts` (0 for a whole number of samples).
pub fn phase_error_deg(tau: f64, ts: f64, freq_hz: &[f64]) -> f64 {
    let (_, d) = split(tau);
    if d == 0.0 {
        return 0.0;
    }
    let a = thiran_coefficient(d);
    freq_hz
        .iter()
        .map(|&f| {
            let w = 2.0 * PI * f * ts;
            let z1 = num_complex::Complex64::from_polar(1.0, -w);
            let h = (a + z1) / (1.0 + a * z1);
            let exact = num_complex::Complex64::from_polar(1.0, -w * d);
            (h / exact).arg().abs().to_degrees()
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;

    fn gain() -> StateSpace {
        StateSpace::new(
            DMatrix::from_element(1, 1, 0.5),
            DMatrix::from_element(1, 1, 1.0),
            DMatrix::from_element(1, 1, 0.5),
            DMatrix::from_element(1, 1, 0.25),
            SampleTime::discrete(1e-3).unwrap(),
        )
        .unwrap()
    }

    /// Whole samples: the response is the model's times `e^{−jωmT}` to rounding.
    #[test]
    fn whole_samples_are_exact() {
        let g = gain();
        let f = [1.0, 50.0, 230.0, 499.0];
        let d = input_delay(&g, 3.0).unwrap();
        assert_eq!(d.n(), 4);
        let (r0, r3) = (g.freqresp(&f).unwrap(), d.freqresp(&f).unwrap());
        for (i, &fi) in f.iter().enumerate() {
            let z = num_complex::Complex64::from_polar(1.0, -2.0 * PI * fi * 1e-3 * 3.0);
            let err = (r3.response()[i][(0, 0)] - r0.response()[i][(0, 0)] * z).norm();
            assert!(err < 1e-13, "{fi} Hz: {err}");
        }
        assert_eq!(phase_error_deg(3.0, 1e-3, &f), 0.0);
    }

    /// A fraction: unit gain everywhere, the group delay at low frequency equal to `tau`
    /// (Thiran's flatness), and the stated phase error matches the realization's.
    #[test]
    fn fraction_by_thiran() {
        let g = gain();
        for tau in [0.3, 0.7, 1.25, 2.6] {
            let d = input_delay(&g, tau).unwrap();
            let f = [0.5, 1.0, 100.0, 300.0];
            let (r0, rd) = (g.freqresp(&f).unwrap(), d.freqresp(&f).unwrap());
            let mut worst: f64 = 0.0;
            for (i, &fi) in f.iter().enumerate() {
                let h = rd.response()[i][(0, 0)] / r0.response()[i][(0, 0)];
                assert!((h.norm() - 1.0).abs() < 1e-12, "gain {}", h.norm());
                let exact = num_complex::Complex64::from_polar(1.0, -2.0 * PI * fi * 1e-3 * tau);
                worst = worst.max((h / exact).arg().abs().to_degrees());
            }
            let stated = phase_error_deg(tau, 1e-3, &f);
            assert!((worst - stated).abs() < 1e-9, "{tau}: {worst} vs {stated}");
            // at 0.5 Hz (ω T = 0.003) the phase is the delay's to 1e-6 degrees
            assert!(phase_error_deg(tau, 1e-3, &[0.5]) < 1e-6);
        }
        assert!(thiran(0.0, 1e-3).is_err());
        assert!(input_delay(&g, -1.0).is_err());
    }
}
