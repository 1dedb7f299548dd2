//! Stage 2, the model: given (checked, ZOH-discretised if continuous) or fitted to the model
//! experiment's FRF (SK over the orders, the order chosen by the error on held-out periods —
//! FPE where there are none —, Levenberg–Marquardt on the chosen order; rigid-body poles from
//! the low-frequency slope).

use crate::data::Estimate;
use crate::findings::responses;
use crate::lemma6::{compare, Pred};
use crate::stats::{statistic, Statistic};
use crate::{DiagnoseError, DiagnoseOptions, Result};
use sd_ident::{FitOptions, Weighting};
use sd_model::{Frd, SampleTime, StateSpace};

/// Rigid-body poles suggested by the low-frequency slope of |G| (−2: two, −1: one), over the
/// lowest octave pair of lines measured well (|G| above 3σ: a stiff loop leaves the lowest
/// lines in the noise).
pub(crate) fn rigid_body_count(frd: &Frd) -> usize {
    let f = frd.freq_hz();
    let good = |i: usize| {
        let g = frd.response()[i][(0, 0)].norm();
        let v = frd.variance().map(|v| v[i][(0, 0)]).unwrap_or(0.0);
        f[i] > 0.0 && g > 0.0 && g * g > 9.0 * v
    };
    let Some(f0) = (0..f.len()).find(|&i| good(i)).map(|i| f[i]) else {
        return 0;
    };
    let pts: Vec<(f64, f64)> = (0..f.len())
        .filter(|&i| f[i] <= 4.0 * f0 && good(i))
        .map(|i| (f[i].ln(), frd.response()[i][(0, 0)].norm().ln()))
        .collect();
    if pts.len() < 3 {
        return 0;
    }
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let slope = sxy / sxx.max(f64::MIN_POSITIVE);
    if slope < -1.5 {
        2
    } else if slope < -0.5 {
        1
    } else {
        0
    }
}

/// The model at the fast period: given (checked, ZOH-discretised if continuous) or fitted
/// ([`fit_model`]).
pub(crate) fn model_for(
    fast: &Estimate,
    parts: Option<&(Estimate, Estimate)>,
    h: f64,
    opt: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<(StateSpace, String)> {
    let Some(m) = &opt.model else {
        return fit_model(fast, parts, opt, progress);
    };
    if m.nu() != 1 || m.ny() != 1 {
        return Err(DiagnoseError::Setup(format!(
            "the given model has {} inputs and {} outputs; the diagnosis needs a SISO model",
            m.nu(),
            m.ny()
        )));
    }
    let m = match m.time() {
        SampleTime::Continuous => sd_model::c2d(m, h, sd_model::Discretization::Zoh)?,
        SampleTime::Discrete { ts } if (ts - h).abs() <= 1e-9 * h => m.clone(),
        SampleTime::Discrete { ts } => {
            return Err(DiagnoseError::Setup(format!(
                "the given model samples at {ts} s but the model experiment at {h} s: give \
                 it at the model experiment's rate, or as a continuous model"
            )))
        }
    };
    Ok((m, "given".into()))
}

/// Mean score of a model on an estimate's lines (no prediction variance; [`crate::stats`]).
pub(crate) fn own_statistic(m: &StateSpace, est: &Estimate, alpha: f64) -> Result<Statistic> {
    let r = responses(m, est.frd.freq_hz())?;
    let l = compare(&est.frd, est.dof, |i, _| {
        Some(Pred {
            value: r[i],
            var: 0.0,
            dof: f64::INFINITY,
            params: 0,
        })
    });
    Ok(statistic([(l.as_slice(), est.inflation)], alpha))
}

/// How the order of a fitted model is chosen.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum OrderRule {
    /// Fitted on the earlier periods (or first half of the record), judged on the later ones.
    HeldOut,
    /// Akaike's final prediction error on the whole estimate (no held-out part).
    Fpe,
}

/// Orders scanned past the best one before the scan stops.
const ORDER_PATIENCE: usize = 6;

/// Two-fold cross-validation of one order: fitted (SK) on each part, the mean score of its
/// prediction of the other part, averaged over the two folds (infinite when a fit fails).
fn two_fold(a: &Estimate, b: &Estimate, fo: &FitOptions, alpha: f64) -> f64 {
    let fold = |train: &Estimate, held: &Estimate| -> f64 {
        train
            .thinned()
            .ok()
            .and_then(|t| sd_ident::fit(&t.frd, fo).ok())
            .and_then(|r| own_statistic(&r.model, held, alpha).ok())
            .map_or(f64::INFINITY, |s| s.value)
    };
    0.5 * (fold(a, b) + fold(b, a))
}

/// The order scan: Sanathanan–Koerner fits of every order from the rigid-body count + 1 up to
/// `opt.max_order`, each judged by two-fold cross-validation between the earlier and later
/// periods ([`OrderRule::HeldOut`]: a fit that follows one part's noise, or misses a mode,
/// predicts the other part worse, so the score turns up past the order the data support) or,
/// without held-out data, by FPE. The scan stops [`ORDER_PATIENCE`] orders past the best; the
/// best order is fitted to the whole estimate and refined by Levenberg–Marquardt.
fn fit_model(
    fast: &Estimate,
    parts: Option<&(Estimate, Estimate)>,
    opt: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<(StateSpace, String)> {
    let rigid = rigid_body_count(&fast.frd);
    let base = FitOptions {
        rigid_body: rigid,
        feedthrough: true,
        weighting: Weighting::Variance,
        lm_iterations: 0,
        ..Default::default()
    };
    let rule = if parts.is_some() {
        OrderRule::HeldOut
    } else {
        OrderRule::Fpe
    };
    let mut best: Option<(usize, f64)> = None;
    for order in rigid + 1..=opt.max_order.max(rigid + 1) {
        if best.is_some_and(|b| order > b.0 + ORDER_PATIENCE) {
            break;
        }
        progress(&format!("fitting order {order}"));
        let opt_n = FitOptions {
            order,
            ..base.clone()
        };
        let crit = match parts {
            Some((a, b)) => two_fold(a, b, &opt_n, opt.alpha),
            None => sd_ident::fit(&fast.frd, &opt_n)
                .map(|r| sd_ident::final_prediction_error(r.cost, &opt_n, fast.frd.len()))
                .unwrap_or(f64::INFINITY),
        };
        if crit.is_finite() && best.is_none_or(|b| crit < b.1) {
            best = Some((order, crit));
        }
    }
    let Some((order, _)) = best else {
        return Err(DiagnoseError::Setup(
            "no model order could be fitted to the model experiment's FRF".into(),
        ));
    };
    progress(&format!("fitting order {order} to the whole record"));
    let whole = |lm: usize| {
        sd_ident::fit(
            &fast.frd,
            &FitOptions {
                order,
                lm_iterations: lm,
                ..base.clone()
            },
        )
    };
    let sk = whole(0)?;
    let refined = whole(FitOptions::default().lm_iterations)
        .ok()
        .filter(|r| r.cost <= sk.cost);
    let model = refined.map_or(sk.model, |r| r.model);
    let how = match rule {
        OrderRule::HeldOut => "by held-out error",
        OrderRule::Fpe => "by FPE: no held-out part",
    };
    Ok((
        model,
        format!("fitted to the model experiment (order {order} {how}, {rigid} rigid-body poles)"),
    ))
}
