//! Stage 8 in the diagnosis: the candidate experiments and their predicted separation of two
//! rate-tied hypotheses that explain the data alike (the method in
//! [`crate::next_experiment`]).
//!
//! Candidates: every whole fraction `1/F` of the model experiment's rate, `F` from 2 to
//! [`MAX_FACTOR`], that no slower experiment has and where the template's period is a whole
//! number of samples, with the template's steady periods (at least four: the diagnosis holds
//! the later half out) times [`PERIOD_MULTIPLES`]. The search is in [`propose`].

use super::judged::Judged;
use super::rate_tied::{below_floor, target, NAMING_ALPHA_RATIO, PAIR_DECISIVE};
use super::read::{Data, Val};
use crate::data::{Estimate, Part};
use crate::hypotheses::{Family, Fitted, Target};
use crate::modal::Residues;
use crate::next_experiment::{
    separation_power, Injection, NextExperiment, NoProposal, NEXT_POWER, REALIZED_SHARE,
};
use crate::{RateTied, Result};
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::{Frd, SampleTime};
use std::collections::BTreeMap;

/// Slowest rate proposed: the model experiment's over this.
const MAX_FACTOR: usize = 20;
/// Steady periods proposed, as multiples of the template's.
const PERIOD_MULTIPLES: [usize; 6] = [1, 2, 4, 8, 16, 32];
/// Rates refitted at the template's periods (the refit is the most work).
const MAX_REFITS: usize = 6;
/// Candidates verified by a refit at more periods than the template's.
const MAX_VERIFIED: usize = 3;

/// The slower experiment a proposal repeats at another rate.
struct Template<'v> {
    val: &'v Val<'v>,
    period: usize,
    steady: usize,
    skip: usize,
    rms: f64,
}

impl<'v> Template<'v> {
    /// The periodic slower experiment with the most lines.
    fn of(tied: &[&'v Val<'v>]) -> Option<Self> {
        let v = tied
            .iter()
            .filter(|v| v.exp.spec.period_samples.is_some() && v.whole.frd.variance().is_some())
            .max_by_key(|v| v.whole.frd.len())?;
        let period = v.exp.spec.period_samples?;
        let skip = v.exp.spec.skip_periods;
        let steady = (v.exp.u.len() / period.max(1)).saturating_sub(skip);
        let x = v.exp.r.as_deref().unwrap_or(&v.exp.u);
        let mean = x.iter().sum::<f64>() / x.len().max(1) as f64;
        let rms =
            (x.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / x.len().max(1) as f64).sqrt();
        (steady > 0 && period > 0).then_some(Template {
            val: v,
            period,
            steady,
            skip,
            rms,
        })
    }

    /// The template's period in samples of the model experiment (the proposal keeps the
    /// period's length in seconds, so its lines are the template's frequencies, on the model
    /// experiment's grid as Lemma 6 needs them).
    fn fast_period(&self) -> usize {
        self.period * self.val.factor
    }

    /// Samples per period at rate factor `factor` (`None` when the period is no whole number
    /// of samples there).
    fn period_at(&self, factor: usize) -> Option<usize> {
        (self.fast_period() % factor == 0).then(|| self.fast_period() / factor)
    }

    /// The proposal's lines at rate factor `factor` with `periods` steady periods: the
    /// template's frequencies below the new Nyquist frequency (a faster proposal's lines above
    /// the template's are not counted), each with the larger of two FRF variances of the
    /// template: at the same frequency (a noise fixed in Hz) and at the same fraction of its
    /// sample rate (a loop — controller, the excitation through it — that scales with the rate,
    /// as one designed per rate does: a line near the new Nyquist frequency as hard to measure
    /// as one near the template's); times `P_like/P` for the periods and, at a faster rate,
    /// `F_like/F` (a noise spectrum flat in Hz). Fewer lines sharing the rms at a slower rate
    /// are not credited.
    fn lines(&self, factor: usize, periods: usize, h: f64) -> (Vec<f64>, Vec<f64>) {
        let nyquist = 0.5 / (h * factor as f64);
        let scale = self.val.factor as f64 / factor as f64;
        let more = self.steady as f64 / periods as f64 * scale.max(1.0);
        let f = self.val.whole.frd.freq_hz();
        let Some(v) = self.val.whole.frd.variance() else {
            return (Vec::new(), Vec::new());
        };
        // the template's line nearest a frequency (ascending grid)
        let nearest = |x: f64| {
            let i = f.partition_point(|g| *g < x);
            match (i.checked_sub(1), f.get(i)) {
                (Some(a), Some(b)) if (x - f[a]).abs() <= (b - x).abs() => a,
                (_, Some(_)) => i,
                (Some(a), None) => a,
                (None, None) => 0,
            }
        };
        f.iter()
            .filter(|f| **f < nyquist * (1.0 - 1e-9))
            .map(|f| {
                let worse = v[nearest(f / scale)][(0, 0)].max(v[nearest(*f)][(0, 0)]);
                (*f, worse * more)
            })
            .unzip()
    }
}

/// A hypothesis's prediction (value, variance) at frequencies `f` of an experiment slower by
/// `factor` whose clock runs `clock` off (its true period `F·h·(1 + clock)`, line f at the true
/// frequency `f/(1 + clock)`, as the hypotheses' own predictions); the variance counts the
/// residues' and the poles' covariance (the naming yardstick's: a pole the fast data hardly
/// determine widens the prediction most where the new rate folds it).
fn predict(
    j: &Judged<'_>,
    (p, clock): (&RateTied, f64),
    factor: usize,
    f: &[f64],
) -> Result<Vec<(C, f64)>> {
    predict_with(
        j,
        &j.modal.residues_full(p.nonideal())?,
        (p, clock),
        factor,
        f,
    )
}

/// [`predict`] with the hypothesis's residues given.
fn predict_with(
    j: &Judged<'_>,
    res: &Residues,
    (p, clock): (&RateTied, f64),
    factor: usize,
    f: &[f64],
) -> Result<Vec<(C, f64)>> {
    let ni = p.nonideal();
    let ts = j.modal.h * factor as f64 * (1.0 + clock);
    let f: Vec<f64> = f.iter().map(|f| f / (1.0 + clock)).collect();
    let phi = j.modal.basis.responses(ts, ni, &f)?;
    let dphi = j.modal.basis.pole_sensitivities(&res.r, ts, ni, &f)?;
    Ok(phi
        .iter()
        .zip(&dphi)
        .map(|(row, d)| res.predict_full(row, d))
        .collect())
}

/// `Σ_k |a_k − b_k|²/(v_k + var a_k)` over the lines where it is finite.
fn excess(pa: &[(C, f64)], truth: &[(C, f64)], var: &[f64]) -> f64 {
    pa.iter()
        .zip(truth)
        .zip(var)
        .map(|((a, b), v)| (a.0 - b.0).norm_sqr() / (v + a.1))
        .filter(|x| x.is_finite())
        .sum()
}

/// The proposal's FRF if `truth` were right, as an estimate with the proposal's variances.
fn synthetic(
    t: &Template<'_>,
    (f, var): (&[f64], &[f64]),
    truth: &[(C, f64)],
    ts: f64,
    periods: usize,
) -> Result<Estimate> {
    let frd = Frd::new(
        f.to_vec(),
        truth
            .iter()
            .map(|p| DMatrix::from_element(1, 1, p.0))
            .collect(),
        Some(
            var.iter()
                .map(|v| DMatrix::from_element(1, 1, *v))
                .collect(),
        ),
        SampleTime::Discrete { ts },
    )?;
    Ok(Estimate {
        frd,
        dof: 4.0 * (periods as f64 - 1.0).max(1.0),
        distortion: None,
        local_distortion: Vec::new(),
        bla: None,
        expected_var: None,
        spectra: None,
        ..t.val.whole.clone()
    })
}

/// One candidate: rate factor and steady periods.
#[derive(Clone, Copy)]
struct Candidate {
    factor: usize,
    periods: usize,
    duration_s: f64,
}

/// What a candidate's separation came to: the smallest power over the contests, each
/// hypothesis's largest expected statistics, and what the power is computed from.
struct Separation {
    power: f64,
    expected: BTreeMap<String, f64>,
    held_out: BTreeMap<String, f64>,
    /// Per contest, the judged hypothesis's excess after its refit.
    lambdas: Vec<f64>,
    /// The proposal's lines and the earlier slower experiments'.
    lines: (usize, usize),
    inflation: f64,
    alpha: f64,
}

impl Separation {
    /// The power with `m` times the periods, each excess taken to grow in proportion (an
    /// estimate: the refit's compromise grows with the new data too).
    fn scaled(&self, m: f64) -> f64 {
        let thr = |k: f64| crate::stats::threshold(k, self.alpha);
        self.lambdas
            .iter()
            .map(|l| separation_power(l * m, self.lines, self.inflation, PAIR_DECISIVE, thr))
            .fold(1.0, f64::min)
    }
}

/// The power of a candidate over every contest of `rivals` ([`contests`]), the judged
/// hypothesis refitted on all data plus the truth's prediction.
fn separation(
    j: &Judged<'_>,
    (t, tied): (&Template<'_>, &[&Val<'_>]),
    rivals: &[Fitted],
    c: Candidate,
) -> Result<Separation> {
    let (f, var) = t.lines(c.factor, c.periods, j.modal.h);
    let k_old: usize = tied.iter().map(|v| v.whole.frd.len()).sum();
    let alpha = j.modal.alpha * NAMING_ALPHA_RATIO;
    let thr = |k: f64| crate::stats::threshold(k, alpha);
    let mut out = Separation {
        power: 1.0,
        expected: BTreeMap::new(),
        held_out: BTreeMap::new(),
        lambdas: Vec::new(),
        lines: (f.len(), k_old),
        inflation: t.val.whole.inflation,
        alpha,
    };
    // a hypothesis with clock errors runs the proposal on `like`'s clock (the same controller
    // hardware; refitted, the proposal's clock error is free within ±0.2 % of it)
    let like = like_index(t, tied);
    let pairs = contests(rivals);
    for (bi, b) in rivals.iter().enumerate() {
        if !pairs.iter().any(|p| p.1 == bi) {
            continue;
        }
        let truth = predict(j, (&b.params, b.params.clock(like)), c.factor, &f)?;
        let est = synthetic(
            t,
            (&f, &var),
            &truth,
            j.modal.h * c.factor as f64,
            c.periods,
        )?;
        for &(ai, _) in pairs.iter().filter(|p| p.1 == bi) {
            let a = &rivals[ai];
            let mut all: Vec<Target<'_>> = tied.iter().map(|v| target(v, Part::Whole)).collect();
            all.push(Target {
                factor: c.factor,
                est: &est,
            });
            let mut start = a.params.clone();
            if a.family.clock() {
                start.clock_error.resize(tied.len(), 0.0);
                start.clock_error.push(a.params.clock(like));
            }
            // the line's variance plus the judged hypothesis's prediction variance
            let pa = predict(j, (&start, start.clock(tied.len())), c.factor, &f)?;
            let v: Vec<f64> = var.iter().zip(&pa).map(|(v, p)| v + p.1).collect();
            let values: Vec<C> = truth.iter().map(|p| p.0).collect();
            let lambda = REALIZED_SHARE
                * j.modal
                    .refit_excess(a.family, &start, &all, (&values, &v))?;
            let inflation = t.val.whole.inflation;
            let p = separation_power(lambda, (f.len(), k_old), inflation, PAIR_DECISIVE, thr);
            out.power = out.power.min(p);
            out.lambdas.push(lambda);
            let e = out.expected.entry(a.family.name()).or_insert(1.0);
            *e = e.max(1.0 + lambda / f.len().max(1) as f64);
            // the later halves of every slower experiment, pooled: half of Λ over all lines
            let h = out.held_out.entry(a.family.name()).or_insert(1.0);
            *h = h.max(1.0 + 0.5 * lambda / (f.len() + k_old).max(1) as f64);
        }
    }
    Ok(out)
}

/// The index of the template among `tied` (whose clock a clock hypothesis runs the proposal
/// on: the same controller hardware).
fn like_index(t: &Template<'_>, tied: &[&Val<'_>]) -> usize {
    tied.iter()
        .position(|v| std::ptr::eq(*v, t.val))
        .unwrap_or(0)
}

/// The ordered pairs `(judged, truth)` that must be told apart: every two rivals but a pair
/// judged where its nested single cause is true (it holds the truth: its second cause then fits
/// near zero and is not named).
fn contests(rivals: &[Fitted]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for (b, tb) in rivals.iter().enumerate() {
        for (a, ta) in rivals.iter().enumerate() {
            if a != b && !ta.family.nested().contains(&tb.family) {
                out.push((a, b));
            }
        }
    }
    out
}

/// The screening at rate factor `factor`: per contest, the noncentrality at the template's
/// own steady periods with the hypotheses as fitted (it grows in proportion to the periods),
/// and the number of lines.
fn screen(
    j: &Judged<'_>,
    (t, tied): (&Template<'_>, &[&Val<'_>]),
    rivals: &[(Fitted, Residues)],
    factor: usize,
) -> Result<(Vec<f64>, usize)> {
    let (f, var) = t.lines(factor, t.steady, j.modal.h);
    let like = like_index(t, tied);
    let preds = rivals
        .iter()
        .map(|(r, res)| predict_with(j, res, (&r.params, r.params.clock(like)), factor, &f))
        .collect::<Result<Vec<_>>>()?;
    let fitted: Vec<Fitted> = rivals.iter().map(|r| r.0.clone()).collect();
    let excess = contests(&fitted)
        .into_iter()
        .map(|(a, b)| REALIZED_SHARE * excess(&preds[a], &preds[b], &var))
        .collect();
    Ok((excess, f.len()))
}

/// `rivals` with every clock error below its physical floor ([`below_floor`]) taken out: a
/// `clock_error+hold_delay` whose clock errors are all negligible is the hold delay (the pair
/// rule would never name its clock). Families that then repeat are kept once (the first).
fn without_idle_clocks(rivals: &[Fitted]) -> Vec<Fitted> {
    let mut out: Vec<Fitted> = Vec::new();
    for r in rivals {
        let mut r = r.clone();
        if r.family.clock() && below_floor(Family::Clock, &r.params) {
            let Some(f) = r.family.nested().into_iter().find(|f| !f.clock()) else {
                continue;
            };
            r.family = f;
            r.params.clock_error.clear();
        }
        if !out.iter().any(|o| o.family == r.family) {
            out.push(r);
        }
    }
    out
}

/// The cheapest experiment that separates `rivals` (the chosen hypothesis first), or why there
/// is none ([`NoProposal`]).
///
/// The search: every rate screened at the template's periods (at least four) with the
/// hypotheses as fitted; the [`MAX_REFITS`] most promising rates refitted there; from each
/// refit the least multiple of the periods whose power, the excesses scaled with the periods,
/// reaches [`NEXT_POWER`]; the shortest of those (at one length the most powerful) verified by
/// a refit at its periods, the next ones while the verification fails (at most
/// [`MAX_VERIFIED`]).
pub(super) fn propose(
    data: &Data<'_>,
    j: &Judged<'_>,
    tied: &[&Val<'_>],
    rivals: &[Fitted],
    progress: &mut dyn FnMut(&str),
) -> Result<std::result::Result<NextExperiment, NoProposal>> {
    let rivals = without_idle_clocks(rivals);
    if rivals.len() < 2 {
        return Ok(Err(NoProposal::OneCause));
    }
    let rivals = rivals.as_slice();
    let Some(t) = Template::of(tied) else {
        return Ok(Err(NoProposal::NoPeriodicTemplate));
    };
    progress("the next experiment: predicting the competing hypotheses at other rates");
    let taken: Vec<usize> = data.vals.iter().map(|v| v.factor).collect();
    let base = t.steady.max(4);
    let candidate = |factor: usize, periods: usize| Candidate {
        factor,
        periods,
        duration_s: ((periods + t.skip) * t.fast_period()) as f64 * data.h,
    };
    let promising = screened_factors(j, (&t, tied), rivals, &taken)?;
    let mut refitted: Vec<(usize, Separation)> = Vec::new();
    for &factor in promising.iter().take(MAX_REFITS) {
        refitted.push((
            factor,
            separation(j, (&t, tied), rivals, candidate(factor, base))?,
        ));
    }
    // per rate the least multiple whose scaled power reaches the goal
    let mut plans: Vec<(Candidate, f64)> = refitted
        .iter()
        .filter_map(|(factor, s)| {
            let m = PERIOD_MULTIPLES
                .iter()
                .find(|m| s.scaled(**m as f64) >= NEXT_POWER)?;
            Some((candidate(*factor, base * m), s.scaled(*m as f64)))
        })
        .collect();
    plans.sort_by(|a, b| {
        a.0.duration_s
            .total_cmp(&b.0.duration_s)
            .then(b.1.total_cmp(&a.1))
    });
    let mut best_power = refitted.iter().map(|r| r.1.power).fold(0.0f64, f64::max);
    let mut chosen: Option<(Candidate, Separation)> = None;
    for (c, _) in plans.iter().take(MAX_VERIFIED) {
        let s = if c.periods == base {
            let Some(k) = refitted.iter().position(|(f, _)| *f == c.factor) else {
                continue;
            };
            refitted.swap_remove(k).1
        } else {
            separation(j, (&t, tied), rivals, *c)?
        };
        best_power = best_power.max(s.power);
        if s.power >= NEXT_POWER {
            chosen = Some((*c, s));
            break;
        }
    }
    let Some((c, s)) = chosen else {
        return Ok(Err(NoProposal::NothingSeparates {
            best_power,
            most_periods: base * PERIOD_MULTIPLES[PERIOD_MULTIPLES.len() - 1],
            slowest_factor: MAX_FACTOR,
        }));
    };
    // other rates verified at the same periods
    let alternatives_hz = refitted
        .iter()
        .filter(|(f, r)| *f != c.factor && c.periods == base && r.power >= NEXT_POWER)
        .map(|(f, _)| 1.0 / (data.h * *f as f64))
        .take(3)
        .collect();
    Ok(Ok(proposal(&t, data.h, rivals, (c, s), alternatives_hz)))
}

/// The rates worth a refit, most promising first: every whole fraction not yet measured whose
/// period is a whole number of samples, screened at the template's periods with the
/// hypotheses as fitted, kept when the screening's power with the most periods (32 times the
/// template's) reaches [`NEXT_POWER`] (the screening is optimistic: no refit).
fn screened_factors(
    j: &Judged<'_>,
    ctx: (&Template<'_>, &[&Val<'_>]),
    rivals: &[Fitted],
    taken: &[usize],
) -> Result<Vec<usize>> {
    let (t, tied) = ctx;
    let with_res = rivals
        .iter()
        .map(|r| Ok((r.clone(), j.modal.residues_full(r.params.nonideal())?)))
        .collect::<Result<Vec<_>>>()?;
    let k_old: usize = tied.iter().map(|v| v.whole.frd.len()).sum();
    let alpha = j.modal.alpha * NAMING_ALPHA_RATIO;
    let most = PERIOD_MULTIPLES[PERIOD_MULTIPLES.len() - 1] as f64;
    let base = t.steady.max(4) as f64 / t.steady as f64;
    let mut out: Vec<(usize, f64)> = Vec::new();
    for factor in (2..=MAX_FACTOR).filter(|f| !taken.contains(f) && t.period_at(*f).is_some()) {
        let (excess, k_new) = screen(j, ctx, &with_res, factor)?;
        let power = |m: f64| {
            excess
                .iter()
                .map(|l0| {
                    separation_power(
                        l0 * m,
                        (k_new, k_old),
                        t.val.whole.inflation,
                        PAIR_DECISIVE,
                        |k| crate::stats::threshold(k, alpha),
                    )
                })
                .fold(1.0f64, f64::min)
        };
        if power(base * most) >= NEXT_POWER {
            // ranked by the smallest excess over the contests
            out.push((factor, excess.iter().copied().fold(f64::INFINITY, f64::min)));
        }
    }
    out.sort_by(|a, b| b.1.total_cmp(&a.1));
    Ok(out.into_iter().map(|(f, _)| f).collect())
}

/// The proposal's record from the chosen candidate.
fn proposal(
    t: &Template<'_>,
    h: f64,
    rivals: &[Fitted],
    (c, s): (Candidate, Separation),
    alternatives_hz: Vec<f64>,
) -> NextExperiment {
    let (f, _) = t.lines(c.factor, c.periods, h);
    NextExperiment {
        like: t.val.exp.spec.name.clone(),
        rate_hz: 1.0 / (h * c.factor as f64),
        factor: c.factor,
        band_hz: [
            f.iter().copied().fold(f64::INFINITY, f64::min),
            f.iter().copied().fold(0.0, f64::max),
        ],
        level: t.val.level,
        injection: if t.val.exp.r.is_some() {
            Injection::Reference
        } else {
            Injection::Input
        },
        rms: t.rms,
        period_samples: t.period_at(c.factor).unwrap_or(t.period),
        periods: c.periods,
        transient_periods: t.skip,
        duration_s: c.duration_s,
        separates: rivals.iter().map(|r| r.family.name()).collect(),
        expected_statistic: s.expected,
        expected_held_out: s.held_out,
        power: s.power,
        alternatives_hz,
    }
}
