//! A low-order stable weight `W(z)` whose magnitude overbounds a pointwise bound on its lines.
//!
//! **Method.** (1) The bound's upper envelope: on a uniform grid of `N = 1024` points over
//! `[0, f_s/2]`, `log b` interpolated linearly in frequency between the lines (held constant
//! beyond them), then the running maximum over ±`N/128` points, so that a low order can follow
//! it from above. (2) Its minimum-phase response by the real cepstrum (Oppenheim & Schafer,
//! *Discrete-Time Signal Processing*, §13.5): the even extension of `log|W|` to the `2N`-point
//! circle, inverse FFT, the cepstrum folded onto its causal part, FFT, `exp`. (3) A rational
//! fit of that response of the chosen order (`sd_ident::fit`, relative weighting: the toolkit's
//! SK and Levenberg–Marquardt fit, stable poles). (4) The scale `γ = max_k b_k/|W(f_k)|` over the
//! bound's own lines, so that `|γW(f_k)| ≥ b_k` holds on every line: checked, not assumed. What
//! is reported with it is how much it overbounds: the median and largest of `|W|/b`.

use crate::bound::Bound;
use crate::error::{Result, UncertaintyError};
use num_complex::Complex64 as C;
use rustfft::FftPlanner;
use sd_model::{Frd, SampleTime, StateSpace};

/// Points of the uniform grid the envelope and the minimum phase are computed on.
const GRID: usize = 1024;

/// The overbounding weight of a bound.
#[derive(Debug, Clone)]
pub struct Weight {
    /// `W(z)`, discrete at the bound's sample time, stable, scaled so that `|W| ≥ b` on every
    /// line of the bound.
    pub model: StateSpace,
    /// The scale `γ` applied after the fit (≥ 1 when the fit fell below the bound somewhere).
    pub scale: f64,
    /// Median of `|W(f_k)|/b_k` over the lines: how conservative the weight is (≥ 1).
    pub median_ratio: f64,
    /// Largest `|W(f_k)|/b_k`.
    pub max_ratio: f64,
}

/// The upper envelope of `b` on the uniform grid (module documentation, step 1), as log values.
fn envelope(freq: &[f64], b: &[f64], nyquist: f64) -> Vec<f64> {
    let lb: Vec<f64> = b.iter().map(|v| v.max(f64::MIN_POSITIVE).ln()).collect();
    let at = |f: f64| -> f64 {
        let i = freq.partition_point(|x| *x < f);
        match i {
            0 => lb[0],
            i if i >= freq.len() => lb[freq.len() - 1],
            i => {
                let t = (f - freq[i - 1]) / (freq[i] - freq[i - 1]);
                lb[i - 1] + t * (lb[i] - lb[i - 1])
            }
        }
    };
    let grid: Vec<f64> = (0..=GRID)
        .map(|j| at(nyquist * j as f64 / GRID as f64))
        .collect();
    let w = GRID / 128;
    (0..=GRID)
        .map(|j| {
            grid[j.saturating_sub(w)..=(j + w).min(GRID)]
                .iter()
                .cloned()
                .fold(f64::NEG_INFINITY, f64::max)
        })
        .collect()
}

/// The minimum-phase response with log-magnitude `log_mag` on `[0, π]` (`GRID + 1` points).
fn minimum_phase(log_mag: &[f64]) -> Vec<C> {
    let n2 = 2 * GRID;
    let mut buf: Vec<C> = (0..n2)
        .map(|j| C::new(log_mag[if j <= GRID { j } else { n2 - j }], 0.0))
        .collect();
    let mut planner = FftPlanner::<f64>::new();
    planner.plan_fft_inverse(n2).process(&mut buf);
    for v in buf.iter_mut() {
        *v /= n2 as f64;
    }
    // fold the (real, even) cepstrum onto its causal part
    for (j, v) in buf.iter_mut().enumerate() {
        let c = v.re;
        *v = C::new(
            match j {
                0 => c,
                j if j < GRID => 2.0 * c,
                j if j == GRID => c,
                _ => 0.0,
            },
            0.0,
        );
    }
    planner.plan_fft_forward(n2).process(&mut buf);
    buf[..=GRID].iter().map(|v| v.exp()).collect()
}

/// The overbounding weight of `bound` (in its form's units) with `order` poles (module
/// documentation).
///
/// # Errors
/// An order of 0 or above 40; a bound with fewer than 4 lines or a non-finite value; the
/// fit's failure.
pub fn overbound(bound: &Bound, order: usize) -> Result<Weight> {
    if order == 0 || order > 40 {
        return Err(UncertaintyError::Input(format!(
            "weight order {order}: give 1 to 40 (a weight is meant to be low-order)"
        )));
    }
    let b = bound.values();
    if b.len() < 4 || b.iter().any(|v| !v.is_finite() || *v < 0.0) {
        return Err(UncertaintyError::Input(
            "the bound needs at least 4 finite, non-negative lines for a weight".into(),
        ));
    }
    let nyquist = 0.5 / bound.ts;
    let env = envelope(&bound.freq_hz, &b, nyquist);
    let h = minimum_phase(&env);
    // the fit on the open grid (no DC or Nyquist point: both are real and pin the fit)
    let f: Vec<f64> = (1..GRID)
        .map(|j| nyquist * j as f64 / GRID as f64)
        .collect();
    let resp = (1..GRID)
        .map(|j| nalgebra::DMatrix::from_element(1, 1, h[j]))
        .collect();
    let frd = Frd::new(f, resp, None, SampleTime::discrete(bound.ts)?)?;
    let fit = sd_ident::fit(
        &frd,
        &sd_ident::FitOptions {
            order,
            weighting: sd_ident::Weighting::Relative,
            ..Default::default()
        },
    )?;
    let w0: Vec<f64> = fit
        .model
        .freqresp(&bound.freq_hz)?
        .response()
        .iter()
        .map(|m| m[(0, 0)].norm())
        .collect();
    let scale = b
        .iter()
        .zip(&w0)
        .map(|(b, w)| b / w.max(f64::MIN_POSITIVE))
        .fold(0.0, f64::max);
    if !(scale.is_finite() && scale > 0.0) {
        return Err(UncertaintyError::Input(
            "the weight's fit vanishes where the bound does not; try another order".into(),
        ));
    }
    let (a, bm, c, d, time) = fit.model.into_parts();
    let model = StateSpace::new(a, bm, c * scale, d * scale, time)?;
    let ratios: Vec<f64> = b
        .iter()
        .zip(&w0)
        .map(|(b, w)| scale * w / b.max(f64::MIN_POSITIVE))
        .collect();
    Ok(Weight {
        model,
        scale,
        median_ratio: sd_model::median(&ratios),
        max_ratio: ratios.iter().cloned().fold(0.0, f64::max),
    })
}
