//! The model-free Lemma 6 prediction and the line-by-line comparison of a prediction with a
//! measured FRF.

use crate::data::Estimate;
use crate::stats::{satterthwaite, Line, VAR_SMOOTHING};
use num_complex::Complex64 as C;
use sd_ident::moving_mean;
use sd_model::Frd;
use sd_multirate::hold_weight;
use std::f64::consts::PI;

/// The model-free Lemma 6 prediction of the response at `freq_hz` of an experiment `factor`
/// times slower than the one that measured `fast` (period `h`):
/// `P_T(f) = Σ_{k<F} P_h(f − k/T) H_F(f − k/T)/F`; `None` where a fold frequency is not on the
/// fast grid.
pub fn predict(fast: &Frd, h: f64, factor: usize, freq_hz: &[f64]) -> Vec<Option<C>> {
    let pair = Pair {
        fast,
        factor,
        h,
        dof: f64::INFINITY,
    };
    freq_hz
        .iter()
        .map(|&f| pair.predict(f).map(|p| p.value))
        .collect()
}

/// A fast FRF and the factor to a slower experiment.
pub(crate) struct Pair<'a> {
    pub(crate) fast: &'a Frd,
    pub(crate) factor: usize,
    pub(crate) h: f64,
    /// Degrees of freedom of the fast FRF's variances.
    pub(crate) dof: f64,
}

impl Pair<'_> {
    /// The fast FRF (and its variance) at a signed frequency folded into the fast band.
    pub(crate) fn fast_at(&self, f: f64) -> Option<(C, f64)> {
        let (i, mirrored) = sd_model::folded_line(self.fast.freq_hz(), f, 1.0 / self.h)?;
        let v = self.fast.response()[i][(0, 0)];
        let var = self.fast.variance().map(|v| v[i][(0, 0)]).unwrap_or(0.0);
        Some((if mirrored { v.conj() } else { v }, var))
    }

    /// Prediction and its variance `Σ_k |H_F/F|² var P_h(f_k)` at slow frequency f (with
    /// Satterthwaite's degrees of freedom of that sum).
    pub(crate) fn predict(&self, f: f64) -> Option<Pred> {
        let t = self.h * self.factor as f64;
        let mut sum = C::new(0.0, 0.0);
        let mut parts = Vec::with_capacity(self.factor);
        for k in 0..self.factor {
            let fk = f - k as f64 / t;
            let (p, v) = self.fast_at(fk)?;
            let w = hold_weight(2.0 * PI * fk * self.h, self.factor);
            sum += p * w;
            parts.push((w.norm_sqr() * v, self.dof));
        }
        Some(Pred {
            value: sum,
            var: parts.iter().map(|p| p.0).sum(),
            dof: satterthwaite(&parts),
            params: 0,
        })
    }
}

/// A prediction at one line: value, variance and the variance's degrees of freedom.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Pred {
    pub(crate) value: C,
    pub(crate) var: f64,
    pub(crate) dof: f64,
    /// Parameters of a fitted prediction whose errors all lines share (0: independent).
    pub(crate) params: usize,
}

/// The lines of `est` where `pred` (line index, frequency) gives a prediction and the total
/// variance is positive.
///
/// A line's variance is the sum of the measured and the predicted estimate; its degrees of
/// freedom are Satterthwaite's for that sum with the parts' *expected* sizes, not the line's
/// own noisy estimates. With the line's own estimates the effective ν follows their random
/// ratio and the score is biased upwards: for two estimates with ν = 6 each (the LPM's
/// default) whose variances differ 16-fold the mean score is 1.016 instead of 1, 0.992 with
/// the expected ratio; for an estimate (ν = 6) beside a computed prediction variance of 0.1–1
/// times its size it is 1.015–1.036, 0.98–0.99 with the expected size (Monte Carlo, 2·10⁶
/// draws each: `python tools/mc_satterthwaite.py`). On rising records of linear stages the
/// level tests averaged 1.013 and two cases in 40 were called nonlinear (development seeds
/// `3000..3040` of `diagnose_levels_calibration`, run at commit e130e6f). The expected sizes:
/// where both parts are estimates (a measured prediction, finite ν: the model-free tests),
/// the moving mean of each over ±[`VAR_SMOOTHING`] lines; against a fitted model (computed
/// variance, infinite ν) the measured part's [`Estimate::expected_var`] where it has one and
/// the line's own estimate otherwise — not a moving mean of the measured variance itself,
/// whose design factor `1/|U(k)|²` on a noise record is the line's own (an exploratory
/// version that smoothed it, not kept, gave model-test means of 1.05–1.07 on those stages).
pub(crate) fn compare(est: &Estimate, pred: impl Fn(usize, f64) -> Option<Pred>) -> Vec<Line> {
    let val = &est.frd;
    let var = val.variance();
    let raw: Vec<(usize, f64, Pred, f64)> = val
        .freq_hz()
        .iter()
        .enumerate()
        .filter_map(|(i, &f)| {
            let p = pred(i, f)?;
            let vm = var.map(|v| v[i][(0, 0)]).unwrap_or(0.0);
            (vm + p.var > 0.0).then_some((i, f, p, vm))
        })
        .collect();
    // the moving means only where a prediction is itself an estimate (the model-free tests)
    let smoothed = raw.iter().any(|r| r.2.dof.is_finite()).then(|| {
        let vm: Vec<f64> = raw.iter().map(|r| r.3).collect();
        let pv: Vec<f64> = raw.iter().map(|r| r.2.var).collect();
        (
            moving_mean(&vm, VAR_SMOOTHING),
            moving_mean(&pv, VAR_SMOOTHING),
        )
    });
    raw.iter()
        .enumerate()
        .map(|(k, &(i, f, p, vm))| {
            let parts = if let (true, Some((sm, sp))) = (p.dof.is_finite(), &smoothed) {
                [(sm[k], est.dof), (sp[k], p.dof)]
            } else {
                let expected = est.expected_var.as_ref().and_then(|e| e.get(i));
                [(expected.copied().unwrap_or(vm), est.dof), (p.var, p.dof)]
            };
            let v = vm + p.var;
            Line {
                f,
                meas: val.response()[i][(0, 0)],
                pred: p.value,
                var: v,
                dof: satterthwaite(&parts),
                shared: if p.params > 0 { p.var / v } else { 0.0 },
                params: p.params,
            }
        })
        .collect()
}

/// The lines of `est` against a model's response `resp` (one value per line of `est`) with
/// its prediction variance `var` per line (`None`: the model is taken as known), the errors
/// of `params` fitted parameters shared by all lines.
pub(crate) fn model_lines(
    est: &Estimate,
    resp: &[C],
    var: Option<&[f64]>,
    params: usize,
) -> Vec<Line> {
    compare(est, |i, _| {
        Some(Pred {
            value: resp[i],
            var: var.map_or(0.0, |v| v[i]),
            dof: f64::INFINITY,
            params: if var.is_some() { params } else { 0 },
        })
    })
}
