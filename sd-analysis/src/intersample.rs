//! Intersample analysis of a slow loop around a fast plant (the paper's §V): the error spectrum
//! at the fast rate next to the at-sample (slow-rate) one, from the disturbance spectra
//! (the lifted closed loop of [`sd_multirate::MultirateLoop`]), and the control sensitivity
//! `|K_d S_d|` — large where the slow controller amplifies what it sees, which is what excites
//! the plant between the samples.

use crate::error::Result;
use sd_model::StateSpace;
use sd_multirate::MultirateLoop;

/// The intersample picture on a frequency grid.
#[derive(Debug, Clone)]
pub struct Intersample {
    /// Fast-rate frequencies (Hz), up to the fast Nyquist frequency.
    pub fast_hz: Vec<f64>,
    /// Predicted fast-rate error density at `fast_hz`.
    pub fast_psd: Vec<f64>,
    /// Slow-rate frequencies (Hz), up to the slow Nyquist frequency.
    pub slow_hz: Vec<f64>,
    /// Predicted at-sample error density at `slow_hz`.
    pub slow_psd: Vec<f64>,
    /// `|K_d S_d|` at `slow_hz`.
    pub control_sensitivity: Vec<f64>,
    /// Predicted rms of the fast-rate error.
    pub rms_fast: f64,
    /// Predicted rms of the at-sample error.
    pub rms_slow: f64,
}

/// `sqrt(∫ Φ df)` of a one-sided density `psd` sampled at `freq_hz` (trapezoidal rule over
/// the grid; rms in the density's units).
pub fn rms_of_density(freq_hz: &[f64], psd: &[f64]) -> f64 {
    freq_hz
        .windows(2)
        .zip(psd.windows(2))
        .map(|(x, y)| 0.5 * (y[0] + y[1]) * (x[1] - x[0]))
        .sum::<f64>()
        .sqrt()
}

/// Predicts the intersample behaviour of `k` (slow) around `p_fast` with one-sided disturbance
/// densities `phi_d` (force) and `phi_n` (sensor), on `points` linear frequencies per band.
///
/// # Errors
/// As [`sd_multirate::MultirateLoop`] (rates, shapes, SISO for the spectra).
pub fn intersample(
    p_fast: &StateSpace,
    k: &StateSpace,
    factor: usize,
    phi_d: &dyn Fn(f64) -> f64,
    phi_n: &dyn Fn(f64) -> f64,
    points: usize,
) -> Result<Intersample> {
    let l = MultirateLoop::new(p_fast, k, factor)?;
    let (h, t) = l.periods();
    let n = points.max(8);
    let fast_hz: Vec<f64> = (1..=n)
        .map(|i| 0.5 / h * i as f64 / n as f64 * (1.0 - 1e-9))
        .collect();
    let slow_hz: Vec<f64> = (1..=n)
        .map(|i| 0.5 / t * i as f64 / n as f64 * (1.0 - 1e-9))
        .collect();
    let fast_psd = l.error_spectrum_fast(&fast_hz, phi_d, phi_n)?;
    let slow_psd = l.error_spectrum_slow(&slow_hz, phi_d, phi_n)?;
    let ks = slow_hz
        .iter()
        .map(|&f| {
            let s = l.sensitivity_slow(f)?;
            let kk = k.freqresp(&[f])?.response()[0].clone();
            Ok((kk * s)[(0, 0)].norm())
        })
        .collect::<Result<Vec<f64>>>()?;
    Ok(Intersample {
        rms_fast: rms_of_density(&fast_hz, &fast_psd),
        rms_slow: rms_of_density(&slow_hz, &slow_psd),
        fast_hz,
        fast_psd,
        slow_hz,
        slow_psd,
        control_sensitivity: ks,
    })
}
