//! Stage 2, the model: given (checked, ZOH-discretised if continuous) or fitted to the model
//! experiment's FRF (SK over the orders, the order chosen by the error on held-out periods —
//! FPE where there are none —, Levenberg–Marquardt on the chosen order; rigid-body poles from
//! the low-frequency slope).

use crate::data::Estimate;
use crate::findings::responses;
use crate::lemma6::{compare, Pred};
use crate::stats::{statistic, Statistic};
use crate::{DiagnoseError, DiagnoseOptions, OrderChoice, OrderRule, Result};
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
) -> Result<(StateSpace, String, Option<OrderChoice>)> {
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
    Ok((m, "given".into(), None))
}

/// Mean score of a model on an estimate's lines (no prediction variance; [`crate::stats`]).
pub(crate) fn own_statistic(m: &StateSpace, est: &Estimate, alpha: f64) -> Result<Statistic> {
    let r = responses(m, est.frd.freq_hz())?;
    let l = compare(est, |i, _| {
        Some(Pred {
            value: r[i],
            var: 0.0,
            dof: f64::INFINITY,
            params: 0,
        })
    });
    Ok(statistic([(l.as_slice(), est.inflation)], alpha))
}

/// What the model experiment's BLA says of an error that repeats from period to period.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Repeats {
    /// Its distortion is measured and significant (detection lines, realisations, a sibling).
    Measured,
    /// The excitation cannot measure it (a full multisine of one realisation).
    Unknown,
    /// Measured and insignificant, a non-periodic record (its halves see independent
    /// excitation, so their distortion differs), or one period.
    No,
}

impl Repeats {
    fn of(fast: &Estimate) -> Repeats {
        let Some(b) = &fast.bla else {
            return Repeats::No;
        };
        match &b.distortion {
            sd_ident::Distortion::NotMeasurable {
                reason: sd_ident::Unmeasurable::OnePeriod,
            }
            | sd_ident::Distortion::InLpmResidual => Repeats::No,
            sd_ident::Distortion::NotMeasurable { .. } => Repeats::Unknown,
            _ if b.distortion_var.iter().any(|&v| v > 0.0) => Repeats::Measured,
            _ => Repeats::No,
        }
    }
}

/// One-sided 95 % normal quantile of [`OrderRule::HeldOutLines`]'s order choice.
const Z95: f64 = 1.645;

/// Orders scanned past the best one before the scan stops.
const ORDER_PATIENCE: usize = 6;

/// Two-fold cross-validation of one order: fitted (SK) on each part, the per-line scores of
/// its prediction of the other part, both folds' lines in turn (`None` when a fit fails).
fn two_fold(a: &Estimate, b: &Estimate, fo: &FitOptions) -> Option<Vec<f64>> {
    let fold = |train: &Estimate, held: &Estimate| -> Option<Vec<f64>> {
        let t = train.thinned().ok()?;
        let model = sd_ident::fit(&t.frd, fo).ok()?.model;
        let r = responses(&model, held.frd.freq_hz()).ok()?;
        let lines = compare(held, |i, _| {
            Some(Pred {
                value: r[i],
                var: 0.0,
                dof: f64::INFINITY,
                params: 0,
            })
        });
        (!lines.is_empty()).then(|| lines.iter().map(|l| l.score()).collect())
    };
    // the two folds are independent fits: in parallel
    let (ab, ba) = rayon::join(|| fold(a, b), || fold(b, a));
    let mut scores = ab?;
    scores.extend(ba?);
    Some(scores)
}

/// The even- and odd-indexed lines of an estimate (thinned first), the two folds of
/// [`OrderRule::HeldOutLines`].
fn interleaved(est: &Estimate) -> Result<(Estimate, Estimate)> {
    let t = est.thinned()?;
    let half = |r: usize| -> Result<Estimate> {
        Ok(Estimate {
            inflation: (t.inflation / 2.0).max(1.0),
            correlation: Vec::new(),
            ..t.select(|i| i % 2 == r)?
        })
    };
    Ok((half(0)?, half(1)?))
}

/// One order of the scan: its criterion (the mean held-out score, or FPE) and, with held-out
/// data, the score of every held-out line.
struct Scanned {
    order: usize,
    crit: f64,
    scores: Vec<f64>,
}

/// The criterion of every order from the rigid-body count + 1 up to `opt.max_order`
/// (Sanathanan–Koerner fits, two-fold cross-validation between `folds`, FPE without them),
/// stopping [`ORDER_PATIENCE`] orders past the least.
fn scan(
    fast: &Estimate,
    folds: Option<&(Estimate, Estimate)>,
    base: &FitOptions,
    opt: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Vec<Scanned> {
    let mut scanned: Vec<Scanned> = Vec::new();
    for order in base.rigid_body + 1..=opt.max_order.max(base.rigid_body + 1) {
        if least(&scanned).is_some_and(|b| order > b.order + ORDER_PATIENCE) {
            break;
        }
        progress(&format!("fitting order {order}"));
        scanned.extend(judge(fast, folds, base, order));
    }
    scanned
}

/// One order's criterion: two-fold cross-validation between `folds` (the mean of the per-line
/// held-out scores, kept), FPE without them; `None` when a fit fails or the criterion is not
/// finite.
fn judge(
    fast: &Estimate,
    folds: Option<&(Estimate, Estimate)>,
    base: &FitOptions,
    order: usize,
) -> Option<Scanned> {
    let opt_n = FitOptions {
        order,
        ..base.clone()
    };
    let (crit, scores) = match folds {
        Some((a, b)) => {
            let v = two_fold(a, b, &opt_n)?;
            (v.iter().sum::<f64>() / v.len() as f64, v)
        }
        None => {
            let r = sd_ident::fit(&fast.frd, &opt_n).ok()?;
            let fpe = sd_ident::final_prediction_error(r.cost, &opt_n, fast.frd.len());
            (fpe, Vec::new())
        }
    };
    crit.is_finite().then_some(Scanned {
        order,
        crit,
        scores,
    })
}

/// The order with the least criterion.
fn least(scanned: &[Scanned]) -> Option<&Scanned> {
    scanned.iter().min_by(|a, b| a.crit.total_cmp(&b.crit))
}

/// Whether order `lower`'s held-out scores are not significantly above `best`'s: the paired
/// one-sided test on the per-line differences `d = s_lower − s_best` (the same held-out
/// lines judge both, so their costs are correlated and a test of the two means alone would
/// be far too lenient), `mean(d) ≤ z₀.₉₅·sd(d)/√K`.
fn no_worse(lower: &Scanned, best: &Scanned) -> bool {
    let k = lower.scores.len().min(best.scores.len());
    if k < 2 || lower.scores.len() != best.scores.len() {
        return lower.crit <= best.crit;
    }
    let d: Vec<f64> = lower
        .scores
        .iter()
        .zip(&best.scores)
        .map(|(a, b)| a - b)
        .collect();
    let mean = d.iter().sum::<f64>() / k as f64;
    let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (k - 1) as f64;
    mean <= Z95 * (var / k as f64).sqrt()
}

/// The real parameters of an order: pole and residue per free pole, a residue per rigid-body
/// pole, the feedthrough.
fn parameters(order: usize, rigid: usize) -> usize {
    2 * (order - rigid.min(order)) + rigid + 1
}

/// Whether the least held-out-periods score shows a misfit the periods share: a model that
/// reaches the noise predicts a held-out part at `1 + p/L` on average (its own parameter
/// error adds its variance; p real parameters, L lines), and a score above twice that is
/// neither noise nor parameter error but something every period repeats.
fn periods_repeat_a_misfit(best: &Scanned, rigid: usize, lines: usize) -> bool {
    let expected = 1.0 + parameters(best.order, rigid) as f64 / lines.max(1) as f64;
    best.crit > 2.0 * expected
}

/// The order scan ([`scan`]) under the rule the data allow, and the rule with why.
///
/// - **Held-out periods** ([`OrderRule::HeldOutPeriods`]): fitted on the earlier periods,
///   judged on the later ones and the other way; a fit that follows one part's noise, or
///   misses a mode, predicts the other part worse, so the score turns up past the order the
///   data support; the least score wins.
/// - **Held-out lines** ([`OrderRule::HeldOutLines`]) when the periods cannot show a fit
///   error because what no linear model describes repeats from period to period: the
///   distortion is measured and significant, or the excitation cannot measure it and the
///   periods' least score is above what noise and parameter error explain
///   ([`periods_repeat_a_misfit`]). Stochastic distortion does not repeat from line to line:
///   each order is also fitted on the even-indexed lines and judged on the odd-indexed ones
///   (and the other way). The periods' order is kept when its interleaved-line scores are no
///   worse than the best order's ([`no_worse`]: the modes it resolves are real); otherwise it
///   chases the distortion and the lowest order no worse than the best is taken.
/// - **FPE** without held-out periods (a non-periodic record).
fn choose_order(
    fast: &Estimate,
    parts: Option<&(Estimate, Estimate)>,
    base: &FitOptions,
    opt: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<(usize, OrderRule, String)> {
    let none = || {
        DiagnoseError::Setup("no model order could be fitted to the model experiment's FRF".into())
    };
    let repeats = Repeats::of(fast);
    let mut periods_best = None;
    let mut why = String::from("the distortion is measured and the periods share it");
    if parts.is_some() || repeats == Repeats::No {
        let scanned = scan(fast, parts, base, opt, progress);
        let best = least(&scanned).ok_or_else(none)?;
        let Some((a, _)) = parts else {
            return Ok((
                best.order,
                OrderRule::Fpe,
                "by FPE: no held-out part".into(),
            ));
        };
        let misfit = periods_repeat_a_misfit(best, base.rigid_body, a.frd.len());
        if repeats == Repeats::No || (repeats == Repeats::Unknown && !misfit) {
            let how = "by held-out error".into();
            return Ok((best.order, OrderRule::HeldOutPeriods, how));
        }
        if repeats == Repeats::Unknown {
            why = format!(
                "the periods' least score {:.3} at order {} is a misfit every period repeats \
                 (distortion this excitation cannot measure)",
                best.crit, best.order
            );
        }
        periods_best = Some(best.order);
    }
    progress("judging the orders on interleaved lines");
    let lines = interleaved(fast)?;
    let mut scanned = scan(fast, Some(&lines), base, opt, progress);
    if let Some(p) = periods_best.filter(|&p| scanned.iter().all(|s| s.order != p)) {
        scanned.extend(judge(fast, Some(&lines), base, p));
    }
    let best = least(&scanned).ok_or_else(none)?;
    let kept = periods_best.and_then(|p| scanned.iter().find(|s| s.order == p));
    if let Some(k) = kept.filter(|k| no_worse(k, best)) {
        let how = format!(
            "by held-out error, confirmed on interleaved lines ({why}; the periods' order \
             predicts them as well as any)"
        );
        return Ok((k.order, OrderRule::HeldOutLines, how));
    }
    let order = scanned
        .iter()
        .filter(|s| no_worse(s, best))
        .map(|s| s.order)
        .min()
        .unwrap_or(best.order);
    let chased = periods_best.map_or(String::new(), |p| {
        format!("; the periods' order {p} chases it: the interleaved lines say worse")
    });
    Ok((
        order,
        OrderRule::HeldOutLines,
        format!("by held-out interleaved lines ({why}{chased})"),
    ))
}

/// The diagnosis's own model: the order chosen by [`choose_order`], fitted to the whole
/// estimate and refined by Levenberg–Marquardt; rigid-body poles from the low-frequency slope
/// ([`rigid_body_count`]).
fn fit_model(
    fast: &Estimate,
    parts: Option<&(Estimate, Estimate)>,
    opt: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<(StateSpace, String, Option<OrderChoice>)> {
    let rigid = rigid_body_count(&fast.frd);
    let base = FitOptions {
        rigid_body: rigid,
        feedthrough: true,
        weighting: Weighting::Variance,
        lm_iterations: 0,
        ..Default::default()
    };
    let (order, rule, how) = choose_order(fast, parts, &base, opt, progress)?;
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
    let choice = OrderChoice {
        rule,
        order,
        max_order: opt.max_order.max(rigid + 1),
        rigid_body: rigid,
    };
    Ok((
        model,
        format!("fitted to the model experiment (order {order} {how}, {rigid} rigid-body poles)"),
        Some(choice),
    ))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;

    fn scanned(order: usize, scores: Vec<f64>) -> Scanned {
        let crit = scores.iter().sum::<f64>() / scores.len() as f64;
        Scanned {
            order,
            crit,
            scores,
        }
    }

    /// A lower order that misses a mode is worse on the mode's few lines only: the paired test
    /// sees it although the means differ by 2.5 % (a test of the two means against the
    /// score's spread would not); a lower order that differs by zero-mean scatter is no worse.
    #[test]
    fn paired_test_sees_a_mode_on_few_lines() {
        let best = scanned(12, vec![1.0; 400]);
        let missing: Vec<f64> = (0..400).map(|i| if i < 20 { 1.5 } else { 1.0 }).collect();
        assert!(!no_worse(&scanned(8, missing), &best));
        let scatter: Vec<f64> = (0..400)
            .map(|i| 1.0 + if i % 2 == 0 { 0.3 } else { -0.3 })
            .collect();
        assert!(no_worse(&scanned(8, scatter), &best));
        // better than the best on average: trivially no worse
        assert!(no_worse(&scanned(8, vec![0.9; 400]), &best));
    }

    /// At the noise the held-out score of order n is about `1 + p/L`; twice that is a misfit.
    #[test]
    fn repeating_misfit_is_twice_the_noise_expectation() {
        let at = |crit: f64| Scanned {
            order: 10,
            crit,
            scores: Vec::new(),
        };
        // p = 2·8 + 2 + 1 = 19 parameters over 200 lines: expectation 1.095
        assert!(!periods_repeat_a_misfit(&at(1.3), 2, 200));
        assert!(!periods_repeat_a_misfit(&at(2.18), 2, 200));
        assert!(periods_repeat_a_misfit(&at(2.2), 2, 200));
        assert!(periods_repeat_a_misfit(&at(4.5), 2, 200));
    }
}
