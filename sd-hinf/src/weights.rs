//! Loopshaping weights for motion systems, continuous or discrete at a given ts.
//!
//! Each weight is built as a series of first- and second-order sections (never one
//! high-order polynomial, whose coefficients span many decades) and discretised by the
//! prewarped Tustin map ([`sd_model::c2d()`]) at its characteristic frequency, so the discrete
//! weight equals the continuous one exactly there (at 347 Hz and 1 kHz, prewarping moves the
//! notch by a factor tan(π·0.347)/(π·0.347) = 1.77 otherwise).
//!
//! - [`pid`]: `W(s) = k · (s + ω_i)/s · (s/ω_z + 1)/(s/ω_p + 1) · ω_l²/(s² + 2ζ_l ω_l s + ω_l²)`
//!   with `ω_z = ω_c/r_lead`, `ω_p = ω_c·r_lead`, `ω_i = ω_c/r_int`, `ω_l = ω_c·r_lp`, and `k`
//!   chosen so that `|W(jω_c)|/(m ω_c²) = 1`: crossover at the bandwidth for a plant whose
//!   high-frequency behaviour is the mass line `1/(m s²)`.
//! - [`notch`]: `(s² + 2ζ_z ω s + ω²)/(s² + 2ζ_p ω s + ω²)`, unit gain far from ω, depth
//!   `ζ_z/ζ_p` at ω.
//! - [`lowpass`]: `ω²/(s² + 2ζ ω s + ω²)`.
//! - [`makeweight`] (MATLAB's `makeweight`): first order `W(s) = (h·s + d·ω₀)/(s + ω₀)` with
//!   `W(0) = d`, `W(∞) = h` and `|W(jω_c)| = g`, which gives
//!   `ω₀ = ω_c·√((g² − h²)/(d² − g²))`; order n is the n-th power of the first-order weight of
//!   the n-th roots `(d^{1/n}, g^{1/n}, h^{1/n})`. Discrete: prewarped at ω_c.

use crate::error::{HinfError, Result};
use num_complex::Complex64 as C;
use sd_model::{c2d, connect::series, Discretization, SampleTime, StateSpace, TransferFunction};
use std::f64::consts::PI;

/// Shape parameters of the PID-like weight (ratios to the crossover frequency ω_c).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidOptions {
    /// `ω_i = ω_c / integrator_ratio`; 0 removes the integrator.
    pub integrator_ratio: f64,
    /// Lead zero at `ω_c / lead_ratio`, pole at `ω_c · lead_ratio` (≥ 1; 1 removes the lead).
    pub lead_ratio: f64,
    /// Second-order low-pass at `ω_c · lowpass_ratio`; 0 (the default) removes it: as a
    /// loopshaping W₁ the plant's own roll-off is usually enough, and a low-pass would hide the
    /// resonances the design must see.
    pub lowpass_ratio: f64,
    /// Damping of the low-pass.
    pub lowpass_zeta: f64,
}

impl Default for PidOptions {
    fn default() -> Self {
        PidOptions {
            integrator_ratio: 5.0,
            lead_ratio: 3.0,
            lowpass_ratio: 0.0,
            lowpass_zeta: 0.7,
        }
    }
}

fn positive(v: f64, what: &str) -> Result<()> {
    if !(v.is_finite() && v > 0.0) {
        return Err(HinfError::InvalidArgument(format!(
            "{what} = {v} must be finite and > 0"
        )));
    }
    Ok(())
}

fn section(num: Vec<f64>, den: Vec<f64>) -> Result<StateSpace> {
    Ok(TransferFunction::new(num, den, SampleTime::Continuous)?.to_ss()?)
}

fn chain(parts: &[StateSpace]) -> Result<StateSpace> {
    let mut it = parts.iter();
    let mut acc = match it.next() {
        Some(p) => p.clone(),
        None => StateSpace::gain(
            nalgebra::DMatrix::from_element(1, 1, 1.0),
            SampleTime::Continuous,
        )?,
    };
    for p in it {
        acc = series(&acc, p)?;
    }
    Ok(acc)
}

/// Continuous → discrete by Tustin prewarped at `f_hz` (which must be below Nyquist).
fn discretize(w: StateSpace, ts: Option<f64>, f_hz: f64) -> Result<StateSpace> {
    match ts {
        None => Ok(w),
        Some(ts) => {
            if f_hz >= 0.5 / ts {
                return Err(HinfError::InvalidArgument(format!(
                    "a weight at {f_hz} Hz cannot be discretised at ts = {ts} s (Nyquist {} Hz)",
                    0.5 / ts
                )));
            }
            Ok(c2d(
                &w,
                ts,
                Discretization::Tustin {
                    prewarp_hz: Some(f_hz),
                },
            )?)
        }
    }
}

/// PID-like weight for a crossover at `bandwidth_hz` on a mass `mass` (module documentation);
/// continuous if `ts` is `None`.
///
/// # Errors
/// Non-positive bandwidth or mass, ratios out of range, a low-pass above Nyquist.
pub fn pid(bandwidth_hz: f64, mass: f64, ts: Option<f64>, opt: &PidOptions) -> Result<StateSpace> {
    positive(bandwidth_hz, "bandwidth")?;
    positive(mass, "mass")?;
    if !(opt.lead_ratio.is_finite() && opt.lead_ratio >= 1.0) {
        return Err(HinfError::InvalidArgument(format!(
            "lead ratio {} must be >= 1",
            opt.lead_ratio
        )));
    }
    for (v, what) in [
        (opt.integrator_ratio, "integrator ratio"),
        (opt.lowpass_ratio, "low-pass ratio"),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(HinfError::InvalidArgument(format!(
                "{what} {v} must be >= 0"
            )));
        }
    }
    let wc = 2.0 * PI * bandwidth_hz;
    let mut parts = Vec::new();
    if opt.integrator_ratio > 0.0 {
        parts.push(section(
            vec![1.0, wc / opt.integrator_ratio],
            vec![1.0, 0.0],
        )?);
    }
    if opt.lead_ratio > 1.0 {
        let (wz, wp) = (wc / opt.lead_ratio, wc * opt.lead_ratio);
        parts.push(section(vec![1.0 / wz, 1.0], vec![1.0 / wp, 1.0])?);
    }
    if opt.lowpass_ratio > 0.0 {
        positive(opt.lowpass_zeta, "low-pass damping")?;
        let wl = wc * opt.lowpass_ratio;
        if let Some(ts) = ts {
            if wl / (2.0 * PI) >= 0.5 / ts {
                return Err(HinfError::InvalidArgument(format!(
                    "the low-pass at {} Hz is above the Nyquist frequency {} Hz: lower the \
                     low-pass ratio",
                    wl / (2.0 * PI),
                    0.5 / ts
                )));
            }
        }
        parts.push(section(
            vec![wl * wl],
            vec![1.0, 2.0 * opt.lowpass_zeta * wl, wl * wl],
        )?);
    }
    let shape = chain(&parts)?;
    let g = shape.eval_direct(C::new(0.0, wc))?[(0, 0)].norm();
    if !(g.is_finite() && g > 0.0) {
        return Err(HinfError::Numerical(
            "the weight's gain at crossover is not finite".into(),
        ));
    }
    let k = mass * wc * wc / g;
    let gain = StateSpace::gain(
        nalgebra::DMatrix::from_element(1, 1, k),
        SampleTime::Continuous,
    )?;
    discretize(series(&shape, &gain)?, ts, bandwidth_hz)
}

/// Notch at `freq_hz` with zero damping `zeta_zero` and pole damping `zeta_pole`.
///
/// # Errors
/// Non-positive frequency or dampings, a notch above Nyquist.
pub fn notch(freq_hz: f64, zeta_zero: f64, zeta_pole: f64, ts: Option<f64>) -> Result<StateSpace> {
    positive(freq_hz, "notch frequency")?;
    if !(zeta_zero.is_finite() && zeta_zero >= 0.0) {
        return Err(HinfError::InvalidArgument(format!(
            "notch zero damping {zeta_zero} must be >= 0"
        )));
    }
    positive(zeta_pole, "notch pole damping")?;
    let w = 2.0 * PI * freq_hz;
    let s = section(
        vec![1.0, 2.0 * zeta_zero * w, w * w],
        vec![1.0, 2.0 * zeta_pole * w, w * w],
    )?;
    discretize(s, ts, freq_hz)
}

/// Second-order low-pass at `freq_hz` with damping `zeta`.
///
/// # Errors
/// Non-positive frequency or damping, a corner above Nyquist.
pub fn lowpass(freq_hz: f64, zeta: f64, ts: Option<f64>) -> Result<StateSpace> {
    positive(freq_hz, "low-pass frequency")?;
    positive(zeta, "low-pass damping")?;
    let w = 2.0 * PI * freq_hz;
    let s = section(vec![w * w], vec![1.0, 2.0 * zeta * w, w * w])?;
    discretize(s, ts, freq_hz)
}

/// MATLAB-like `makeweight` (module documentation): low-frequency gain `dc`, gain `mag` at
/// `freq_hz`, high-frequency gain `hf`, of order 1 or 2; continuous if `ts` is `None`.
///
/// # Errors
/// Non-positive or non-finite gains or frequency, `mag` not strictly between `dc` and `hf`,
/// an order other than 1 or 2, a frequency at or above Nyquist.
pub fn makeweight(
    dc: f64,
    freq_hz: f64,
    mag: f64,
    hf: f64,
    order: usize,
    ts: Option<f64>,
) -> Result<StateSpace> {
    positive(dc, "low-frequency gain")?;
    positive(hf, "high-frequency gain")?;
    positive(mag, "gain at the given frequency")?;
    positive(freq_hz, "frequency")?;
    if !((dc < mag && mag < hf) || (dc > mag && mag > hf)) {
        return Err(HinfError::InvalidArgument(format!(
            "the gain {mag} at {freq_hz} Hz must lie strictly between the low-frequency gain \
             {dc} and the high-frequency gain {hf}"
        )));
    }
    if !(1..=2).contains(&order) {
        return Err(HinfError::InvalidArgument(format!(
            "makeweight order {order}: 1 or 2 are supported"
        )));
    }
    let k = 1.0 / order as f64;
    let (d, g, h) = (dc.powf(k), mag.powf(k), hf.powf(k));
    let w0 = 2.0 * PI * freq_hz * ((g * g - h * h) / (d * d - g * g)).sqrt();
    let first = section(vec![h, d * w0], vec![1.0, w0])?;
    let w = if order == 1 {
        first
    } else {
        series(&first, &first)?
    };
    discretize(w, ts, freq_hz)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn mag(w: &StateSpace, f: f64) -> f64 {
        w.freqresp(&[f]).unwrap().response()[0][(0, 0)].norm()
    }

    #[test]
    fn pid_crosses_over_at_the_bandwidth() {
        for ts in [None, Some(1e-3)] {
            let w = pid(65.0, 20.0, ts, &PidOptions::default()).unwrap();
            let wc = 2.0 * PI * 65.0;
            // |W/(m s²)| = 1 at ω_c, exactly also in discrete time (prewarped there)
            assert!(
                (mag(&w, 65.0) / (20.0 * wc * wc) - 1.0).abs() < 1e-9,
                "{ts:?}"
            );
            assert!(mag(&w, 1.0) > mag(&w, 10.0)); // integrator
        }
        assert!(pid(
            65.0,
            20.0,
            Some(1e-3),
            &PidOptions {
                lowpass_ratio: 10.0,
                ..Default::default()
            }
        )
        .is_err());
        assert!(pid(-1.0, 20.0, None, &PidOptions::default()).is_err());
    }

    /// `makeweight`: the three gains, continuous and discrete (prewarped at the frequency),
    /// first and second order; refused when the middle gain is not between the others.
    #[test]
    fn makeweight_has_its_three_gains() {
        for ts in [None, Some(1e-3)] {
            for order in [1, 2] {
                let w = makeweight(1000.0, 65.0, 1.0, 0.5, order, ts).unwrap();
                assert!((mag(&w, 65.0) - 1.0).abs() < 1e-9, "{ts:?} {order}");
                assert!(
                    (mag(&w, 1e-4) / 1000.0 - 1.0).abs() < 1e-3,
                    "{ts:?} {order}"
                );
                let top = if ts.is_some() { 499.999 } else { 1e7 };
                assert!((mag(&w, top) / 0.5 - 1.0).abs() < 1e-2, "{ts:?} {order}");
                assert_eq!(w.n(), order);
            }
        }
        assert!(makeweight(1.0, 10.0, 2.0, 0.5, 1, None).is_err());
        assert!(makeweight(10.0, 600.0, 1.0, 0.1, 1, Some(1e-3)).is_err());
        assert!(makeweight(10.0, 6.0, 1.0, 0.1, 3, None).is_err());
    }

    #[test]
    fn notch_depth_and_prewarping() {
        let n = notch(347.0, 0.01, 0.2, Some(1e-3)).unwrap();
        assert!((mag(&n, 347.0) - 0.05).abs() < 1e-9);
        assert!((mag(&n, 5.0) - 1.0).abs() < 1e-3);
        let lp = lowpass(100.0, 0.5, Some(1e-3)).unwrap();
        assert!((mag(&lp, 100.0) - 1.0).abs() < 1e-9); // |ω²/(2jζω²)| = 1/(2ζ) = 1
        assert!(notch(600.0, 0.01, 0.2, Some(1e-3)).is_err());
    }
}
