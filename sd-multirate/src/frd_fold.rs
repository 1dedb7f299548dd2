//! Lemma 6 on measured data: the slow-rate FRF of a fast-rate FRF, without a model.
//!
//! **Math.** A plant sampled at `h` and driven through a hold at `T = F·h` (the fast input
//! held for `F` samples) and sampled at `T` has, at a slow frequency `f`, the response
//!
//! `P_T(f) = Σ_{k<F} P_h(f_k)·H_F(e^{j2πf_k h})/F`, `f_k = f − k/T`,
//!
//! `H_F(z) = Σ_{i<F} z^{−i}` (Oomen, van de Wal & Bosgra, ACC 2007, Lemma 6 in the frequency
//! domain; [`crate::fold_map`]). Each fold frequency is reduced to the fast grid's
//! `[0, 1/(2h)]`; a negative one reads the conjugate line (a real plant). The map is linear,
//! so independent line errors give `var P_T(f) = Σ_k |H_F/F|²·var P_h(f_k)`.
//!
//! **Which slow lines.** A slow line is kept only when all `F` of its fold frequencies are
//! lines of the fast FRF (within `1e-6·(1/h)/lines`, [`sd_model::folded_line`]): the sum needs
//! every fold, and no fold is interpolated. A fast FRF measured with a line spacing that
//! divides `1/T` gives every fast line below the slow Nyquist frequency.

use crate::alias_map::hold_weight;
use crate::error::{check_factor, MultirateError, Result};
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::{Frd, SampleTime};
use std::f64::consts::PI;

/// A slow-rate FRF made from a fast one, and the slow lines it could not give.
#[derive(Debug, Clone)]
pub struct DownsampledFrd {
    /// The slow-rate FRF (sample time `F·h`; variances folded when the fast FRF has them).
    pub frd: Frd,
    /// Requested slow lines (Hz) left out because a fold frequency is not a fast line.
    pub missing_hz: Vec<f64>,
}

/// The slow FRF of the fast FRF `fast` (sample time `h`) seen through a hold and sampler at
/// `T = factor·h`, at `slow_freq_hz` (default: the fast lines in `(0, 1/(2T)]`), by Lemma 6's
/// fold sum (module documentation).
///
/// # Errors
/// A continuous-time FRF (it has no fast rate to fold), `factor` 0, a requested frequency
/// outside `[0, 1/(2T)]`, no slow line whose folds are all fast lines.
pub fn downsample_frd(
    fast: &Frd,
    factor: usize,
    slow_freq_hz: Option<&[f64]>,
) -> Result<DownsampledFrd> {
    check_factor(factor)?;
    let SampleTime::Discrete { ts: h } = fast.time() else {
        return Err(MultirateError::InvalidArgument(
            "the FRF is continuous-time: Lemma 6 folds a fast-rate (sampled) FRF; give its \
             sampling period as `ts`"
                .into(),
        ));
    };
    let t = h * factor as f64;
    let nyquist = 0.5 / t;
    let default: Vec<f64>;
    let wanted = match slow_freq_hz {
        Some(f) => f,
        None => {
            default = fast
                .freq_hz()
                .iter()
                .copied()
                .filter(|&f| f > 0.0 && f <= nyquist * (1.0 + 1e-12))
                .collect();
            &default
        }
    };
    if let Some(f) = wanted
        .iter()
        .find(|f| !(f.is_finite() && **f >= 0.0 && **f <= nyquist * (1.0 + 1e-12)))
    {
        return Err(MultirateError::InvalidArgument(format!(
            "slow frequency {f} Hz is outside [0, {nyquist}] Hz, the slow rate's band"
        )));
    }
    let (mut freq, mut resp, mut var, mut missing) = (vec![], vec![], vec![], vec![]);
    for &f in wanted {
        match fold_line(fast, f, factor, h) {
            Some((p, v)) => {
                freq.push(f);
                resp.push(p);
                var.push(v);
            }
            None => missing.push(f),
        }
    }
    if freq.is_empty() {
        return Err(MultirateError::InvalidArgument(format!(
            "none of the {} slow lines has all its {factor} fold frequencies on the fast FRF's \
             lines: measure the fast FRF with a line spacing that divides the slow rate {} Hz",
            wanted.len(),
            1.0 / t
        )));
    }
    let variance = fast.variance().is_some().then_some(var);
    let frd = Frd::new(freq, resp, variance, SampleTime::discrete(t)?)?;
    Ok(DownsampledFrd {
        frd,
        missing_hz: missing,
    })
}

/// The fold sum at one slow frequency `f` and its variance, or `None` when a fold is missing.
fn fold_line(fast: &Frd, f: f64, factor: usize, h: f64) -> Option<(DMatrix<C>, DMatrix<f64>)> {
    let t = h * factor as f64;
    let shape = fast.response().first()?.shape();
    let mut p = DMatrix::<C>::zeros(shape.0, shape.1);
    let mut v = DMatrix::<f64>::zeros(shape.0, shape.1);
    for k in 0..factor {
        let fk = f - k as f64 / t;
        let (i, mirrored) = sd_model::folded_line(fast.freq_hz(), fk, 1.0 / h)?;
        let w = hold_weight(2.0 * PI * fk * h, factor);
        let line = &fast.response()[i];
        p += line.map(|x| w * if mirrored { x.conj() } else { x });
        if let Some(var) = fast.variance() {
            v += var[i].map(|x| w.norm_sqr() * x);
        }
    }
    Some((p, v))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use sd_model::stage::paper_stage;
    use sd_model::{c2d, Discretization};

    /// The fold sum of the 5 kHz model's FRF equals the Lemma 6 model's FRF at 1 kHz (two
    /// numerical forms of one identity: a frequency-domain sum and a state-space power).
    #[test]
    fn fold_sum_equals_the_downsampled_model() {
        let p = paper_stage(0.01).unwrap();
        let fast = c2d(&p, 2e-4, Discretization::Zoh).unwrap();
        let df = 2.5;
        let lines: Vec<f64> = (1..=1000).map(|i| i as f64 * df).collect();
        let frd = fast.freqresp(&lines).unwrap();
        let slow = downsample_frd(&frd, 5, None).unwrap();
        assert!(slow.missing_hz.is_empty());
        assert_eq!(slow.frd.len(), 200);
        let model = crate::downsample(&fast, 5).unwrap();
        let want = model.freqresp(slow.frd.freq_hz()).unwrap();
        for (a, b) in slow.frd.response().iter().zip(want.response()) {
            let err = (a - b).norm();
            assert!(err <= 1e-9 * b.norm(), "{err:e} vs {}", b.norm());
        }
        // a line spacing that does not divide 1 kHz leaves lines out, and says so
        let odd: Vec<f64> = (1..=800).map(|i| i as f64 * 3.0).collect();
        let e = downsample_frd(&fast.freqresp(&odd).unwrap(), 7, None).unwrap_err();
        assert!(e.to_string().contains("line spacing"), "{e}");
    }
}
