//! Stage 4: the decision — which family of causes the checks point to (rate-tied, level,
//! drift, distortion, the fast model).

use super::checks::*;
use super::judged::*;
use super::levels::*;
use super::rate_tied::*;
use super::read::*;
use crate::data::{held_out_label, Estimate};
use crate::hypotheses::Family;
use crate::stats::{statistic, Line, Statistic};
use crate::{
    Cause, CornerTrend, DampingTrend, DriftCheck, DriftSign, Evidence, EvidenceKind, Extension,
    FreqTrend, Gain, HeldOut, Ranked, Result, Verdict,
};
use sd_model::StateSpace;
use std::collections::BTreeMap;

/// Stages 4–5: the cause, the extension and its gain.
/// The experiment that would separate competing explanations, or why there is none.
pub(super) type Next =
    std::result::Result<crate::NextExperiment, crate::next_experiment::NoProposal>;

pub(super) struct Outcome {
    pub(super) verdict: Verdict,
    pub(super) causes: Vec<Cause>,
    pub(super) extension: Extension,
    pub(super) ranking: Vec<Ranked>,
    pub(super) partial: Option<Ranked>,
    pub(super) gain: Gain,
    /// The extended model per experiment where the extension is not rate-tied (the
    /// amplitude-dependent model at each level).
    pub(super) models: BTreeMap<String, StateSpace>,
    /// Per whole held-out experiment, its statistics before and after.
    pub(super) held: BTreeMap<String, HeldOut>,
    /// The amplitude-dependent model, where that is the extension.
    pub(super) amplitude: Option<Box<crate::amplitude::AmplitudeModel>>,
    /// Where explanations the data cannot tell apart compete: the experiment that would
    /// separate them, or why there is none.
    pub(super) next: Option<Next>,
}

impl Outcome {
    pub(super) fn plain(verdict: Verdict, cause: Cause, gain: Gain) -> Self {
        Outcome {
            verdict,
            causes: vec![cause],
            extension: Extension::None,
            ranking: Vec::new(),
            partial: None,
            gain,
            models: BTreeMap::new(),
            held: BTreeMap::new(),
            amplitude: None,
            next: None,
        }
    }
}

pub(super) fn decide(
    data: &Data<'_>,
    j: &Judged<'_>,
    ch: &mut Checks,
    progress: &mut dyn FnMut(&str),
) -> Result<Outcome> {
    let a = ch.alpha_test;
    let pooled = |sets: &[Vec<Line>], keep: &dyn Fn(&Val<'_>) -> bool| {
        statistic(
            data.vals
                .iter()
                .zip(sets)
                .filter(|(v, _)| keep(v))
                .map(|(v, s)| (s.as_slice(), v.whole.inflation.max(data.fast.inflation))),
            a,
        )
    };
    let s_free = pooled(&ch.free, &|v| v.comparable());
    let s_model = pooled(&ch.model, &|_| true);
    ch.evidence.push(Evidence::of(
        EvidenceKind::AllValidation,
        "the model's simulation of every validation experiment",
        &s_model,
    ));
    // other excitation levels at the same rate that the model-free check rejects
    let nonlinear: Vec<(usize, Statistic)> = level_tests(data, ch)
        .into_iter()
        .filter(|(_, s)| !s.passes())
        .collect();
    if !nonlinear.is_empty() {
        // levels disagree: nonlinearity, unless every experiment involved has non-excited
        // lines and none shows distortion (the FRF changed without distortion: drift)
        let mut involved = vec![(data.model_exp, &data.fast)];
        involved.extend(
            nonlinear
                .iter()
                .map(|(i, _)| (data.vals[*i].exp, &data.vals[*i].whole)),
        );
        if involved.iter().all(|(_, e)| distorted(e, a) == Some(false)) {
            let names = nonlinear
                .iter()
                .map(|(i, _)| data.vals[*i].exp.spec.name.clone());
            return Ok(drift_outcome(
                names.collect(),
                DriftSign::LevelsWithoutDistortion,
            ));
        }
        return nonlinearity(data, j, ch, &nonlinear, progress);
    }
    let seen = distorted_levels(data, ch);
    if !seen.is_empty() {
        return nonlinearity(data, j, ch, &seen, progress);
    }
    if s_free.lines == 0 {
        // only other levels, and they agree model-free; where the model's simulation misses
        // them, the levels' own FRFs may still move beyond their uncertainty (the model
        // smooths the model experiment's noise: more power than the model-free test)
        let moved = if s_model.passes() {
            moves_under_distortion(data, j, ch, progress)?
        } else {
            let a = ch.alpha_test;
            levels_move(data, j, ch, progress, &|v, s| {
                !s.passes() || distorted(&v.whole, a) == Some(true)
            })?
        };
        if let Some(o) = moved {
            return Ok(o);
        }
        let v = if s_model.passes() {
            (Verdict::Consistent, Cause::None)
        } else {
            (Verdict::Discrepancy, Cause::Unexplained)
        };
        return Ok(Outcome::plain(v.0, v.1, Gain::none("nothing to extend")));
    }
    ch.evidence.push(Evidence::of(
        EvidenceKind::ModelFree,
        "Lemma 6 prediction of the same-level experiments (model-free, pooled)",
        &s_free,
    ));
    if s_free.passes() {
        if s_model.passes() {
            if let Some(o) = moves_under_distortion(data, j, ch, progress)? {
                return Ok(o);
            }
            return Ok(Outcome::plain(
                Verdict::Consistent,
                Cause::None,
                Gain::none("consistent: nothing to extend"),
            ));
        }
        // the model-free check has the fast FRF's variance and little power: a rate-tied
        // effect may show in the model's simulation only, so it is tried before the model
        // is blamed
        if data.vals.iter().any(Val::rate_tied) {
            let (o, ambiguous) = rate_tied(data, j, progress)?;
            if ambiguous
                || !matches!(o.causes.first(), Some(Cause::Unexplained) | None)
                || partly_rate_tied(&o, data, ch)
            {
                return Ok(o);
            }
        } else if let Some(o) = distortion_explains(data, ch) {
            return Ok(o);
        }
        return fast_model_error(data, j, ch);
    }
    if !data.vals.iter().any(Val::rate_tied) {
        ch.evidence.push(Evidence::of(
            EvidenceKind::NotRepeatable,
            "same rate and excitation level, yet different FRFs: not repeatable",
            &s_free,
        ));
        return Ok(not_repeatable(data, ch));
    }
    rate_tied_or_distortion(data, j, a, progress)
}

/// The model-free check fails at a slower rate: the rate-tied hypotheses; when none explains
/// the data and the experiments' distortion tests, as one family, show nonlinear distortion,
/// `nonlinearity` at one level (named, not modelled).
fn rate_tied_or_distortion(
    data: &Data<'_>,
    j: &Judged<'_>,
    a: f64,
    progress: &mut dyn FnMut(&str),
) -> Result<Outcome> {
    let (o, _) = rate_tied(data, j, progress)?;
    // distortion over every experiment's tests as one family: one more experiment must not
    // raise the chance that a linear plant is called nonlinear
    let all: Vec<&Estimate> = std::iter::once(&data.fast)
        .chain(data.vals.iter().map(|v| &v.whole))
        .collect();
    let seen = distorted_family(&all, a) == Some(true);
    if seen && matches!(o.causes.first(), Some(Cause::Unexplained)) {
        let one = one_level(data.vals.iter().filter(|v| v.rate_tied()));
        return Ok(Outcome {
            causes: one.causes,
            gain: one.gain,
            ..o
        });
    }
    Ok(o)
}

/// Every experiment agrees with the model, yet other excitation levels at the model
/// experiment's rate show nonlinear distortion at their non-excited lines: the distortion's
/// variance, part of those FRFs' variance, can hide a shift of the best linear approximation.
/// The amplitude model ([`nonlinearity`]) is fitted over the levels; its outcome is taken when a
/// mode's frequency, damping or a friction corner moves beyond its uncertainty (a false alarm
/// on a linear stage needs the distortion test and the trend test to fail together, about
/// `α²`), else `None` (the plant is consistent: its best linear approximation does not change
/// measurably with the level) and the evidence stays as it was.
pub(super) fn moves_under_distortion(
    data: &Data<'_>,
    j: &Judged<'_>,
    ch: &mut Checks,
    progress: &mut dyn FnMut(&str),
) -> Result<Option<Outcome>> {
    let a = ch.alpha_test;
    levels_move(data, j, ch, progress, &|v, _| {
        distorted(&v.whole, a) == Some(true)
    })
}

/// The amplitude model ([`nonlinearity`]) over the other levels at the model experiment's
/// rate that `pick` selects (given each level and the model's simulation statistic on it):
/// its outcome when a mode's frequency, damping or a friction corner moves beyond its
/// uncertainty, else `None` with the evidence left as it was.
fn levels_move(
    data: &Data<'_>,
    j: &Judged<'_>,
    ch: &mut Checks,
    progress: &mut dyn FnMut(&str),
    pick: &dyn Fn(&Val<'_>, &Statistic) -> bool,
) -> Result<Option<Outcome>> {
    let a = ch.alpha_test;
    let levels: Vec<(usize, Statistic)> = data
        .vals
        .iter()
        .enumerate()
        .filter(|(_, v)| v.factor == 1 && !v.same_level())
        .map(|(i, v)| {
            (
                i,
                statistic([(ch.model[i].as_slice(), v.whole.inflation)], a),
            )
        })
        .filter(|(i, s)| pick(&data.vals[*i], s))
        .collect();
    if levels.is_empty() {
        return Ok(None);
    }
    let kept = ch.evidence.len();
    let o = nonlinearity(data, j, ch, &levels, progress)?;
    let moves = o.causes.iter().any(|c| {
        matches!(c, Cause::Nonlinearity { kind, damping_trend, corner_trend, .. }
            if *kind != FreqTrend::None
                || *damping_trend != DampingTrend::None
                || *corner_trend != CornerTrend::None)
    });
    if moves {
        return Ok(Some(o));
    }
    ch.evidence.truncate(kept);
    Ok(None)
}

/// Whether an estimate's non-excited lines show nonlinear distortion at `alpha` (odd or
/// even); `None` where it has none to look at (non-periodic records, full multisines).
pub(super) fn distorted(est: &Estimate, alpha: f64) -> Option<bool> {
    let ev = distortion_evidence("", est.distortion.as_ref()?, alpha);
    (!ev.is_empty()).then(|| ev.iter().any(|e| !e.passed))
}

/// Whether any of `ests` shows nonlinear distortion, their odd and even tests taken as one
/// family at `alpha` (Bonferroni: each of the `m` tests at `alpha/m`), so that the chance of
/// a false alarm on a linear plant stays at most `alpha` however many experiments there are
/// (the per-test false-alarm rate is calibrated at every rate and fold pattern:
/// `tests/tests/distortion_calibration.rs`); `None` where none has lines to look at.
pub(super) fn distorted_family(ests: &[&Estimate], alpha: f64) -> Option<bool> {
    let reports: Vec<_> = ests.iter().filter_map(|e| e.distortion.as_ref()).collect();
    let m: usize = reports
        .iter()
        .map(|d| usize::from(d.odd_lines > 0) + usize::from(d.even_lines > 0))
        .sum();
    if m == 0 {
        return None;
    }
    let each = alpha / m as f64;
    Some(
        reports
            .iter()
            .flat_map(|d| distortion_evidence("", d, each))
            .any(|e| !e.passed),
    )
}

/// Other excitation levels at the model experiment's rate that the model-free level test
/// cannot resolve (it carries the model experiment's FRF variance too) but whose simulation by
/// the model fails at the verdict's level, each showing nonlinear distortion at its
/// non-excited lines, while the model describes its own experiment (within the noise, or its
/// misfit there is distortion too): the disagreement comes with distortion, which drift does
/// not bring. Both tests at `α` on a linear stage: a false alarm needs both, about `α²`.
pub(super) fn distorted_levels(data: &Data<'_>, ch: &Checks) -> Vec<(usize, Statistic)> {
    let a = ch.alpha_test;
    let own = statistic([(ch.fast_model.as_slice(), data.fast.inflation)], a);
    if !(own.passes() || distorted(&data.fast, a) == Some(true)) {
        return Vec::new();
    }
    data.vals
        .iter()
        .enumerate()
        .filter(|(_, v)| v.factor == 1 && !v.same_level() && distorted(&v.whole, a) == Some(true))
        .map(|(i, v)| {
            (
                i,
                statistic([(ch.model[i].as_slice(), v.whole.inflation)], a),
            )
        })
        .filter(|(_, s)| !s.passes())
        .collect()
}

/// Same-level experiments at the model experiment's rate that agree with it model-free but
/// not with the model's simulation, nothing rate-tied to test: when the model describes its
/// own experiment within the noise (or its misfit there is distortion, [`OwnFit`]), the pair
/// shows distortion at its non-excited lines, and the simulation of every failing experiment
/// passes once the stochastic distortion of both realisations is counted (per line: the
/// model experiment's local level, which the model followed, and the validation's below the
/// gate its variance leaves out), the misfit is the nonlinearity's stochastic distortion:
/// another phase realisation differs by it. Nonlinearity at one level; `None` otherwise (the
/// model is then blamed).
pub(super) fn distortion_explains(data: &Data<'_>, ch: &mut Checks) -> Option<Outcome> {
    let a = ch.alpha_test;
    let failing: Vec<(&Val<'_>, &Vec<Line>)> = data
        .vals
        .iter()
        .zip(&ch.model)
        .filter(|(v, _)| v.factor == 1 && v.comparable())
        .filter(|(v, l)| !statistic([(l.as_slice(), v.whole.inflation)], a).passes())
        .collect();
    let seen = |e: &Estimate| distorted(e, a) == Some(true);
    if failing.is_empty() || !(seen(&data.fast) || failing.iter().any(|(v, _)| seen(&v.whole))) {
        return None;
    }
    let mut own = ch.fast_model.clone();
    for l in &mut own {
        l.var += data.fast.local_distortion_at(l.f).1;
    }
    if !statistic([(own.as_slice(), data.fast.inflation)], a).passes() {
        return None;
    }
    let mut rows = Vec::new();
    for (v, lines) in &failing {
        let mut with = (*lines).clone();
        for l in &mut with {
            l.var += data.fast.local_distortion_at(l.f).0 + v.whole.local_distortion_at(l.f).1;
        }
        let s = statistic([(with.as_slice(), v.whole.inflation)], a);
        rows.push(Evidence::of(
            EvidenceKind::DistortionVariance,
            format!(
                "the model's simulation of `{}` with the stochastic distortion of both phase \
                 realisations counted (their non-excited lines' local levels)",
                v.exp.spec.name
            ),
            &s,
        ));
        if !s.passes() {
            return None;
        }
    }
    ch.evidence.extend(rows);
    Some(one_level(failing.into_iter().map(|(v, _)| v)))
}

/// Whether an unexplained rate-tied outcome keeps the model from being blamed: the model
/// describes its own experiment within the noise, and the best partial explanation beats
/// `none` decisively on the training data (penalised criterion lower by [`PAIR_DECISIVE`])
/// and on the held-out data where there are some. The misfit is then rate-tied in part (a
/// cataloged effect the search models only approximately, e.g. a sample-clock error on a
/// short drifting record), and `fast_model_error` would be a wrong name: the answer stays
/// `unexplained` with the partial explanation.
pub(super) fn partly_rate_tied(o: &Outcome, data: &Data<'_>, ch: &Checks) -> bool {
    let own = statistic(
        [(ch.fast_model.as_slice(), data.fast.inflation)],
        ch.alpha_test,
    );
    let (Some(p), Some(none)) = (
        o.partial.as_ref(),
        o.ranking.iter().find(|r| r.cause == Family::None.name()),
    ) else {
        return false;
    };
    let held_better = match (p.held_out, none.held_out) {
        (Some(a), Some(b)) => a < b,
        _ => true,
    };
    own.passes() && none.criterion - p.criterion >= PAIR_DECISIVE && held_better
}

/// The plant changed between experiments.
pub(super) fn drift_outcome(experiments: Vec<String>, sign: DriftSign) -> Outcome {
    Outcome::plain(
        Verdict::Discrepancy,
        Cause::Drift { experiments, sign },
        Gain::none(
            "drift: the plant changed with time, which no time-invariant extension predicts",
        ),
    )
}

/// Nonlinearity seen (distortion at the non-excited lines) at one excitation level only:
/// named, not modelled.
pub(super) fn one_level<'v, 'a: 'v>(disagreeing: impl Iterator<Item = &'v Val<'a>>) -> Outcome {
    Outcome {
        extension: Extension::None,
        ..Outcome::plain(
            Verdict::Discrepancy,
            Cause::Nonlinearity {
                relative_levels: disagreeing
                    .map(|v| (v.exp.spec.name.clone(), v.level))
                    .collect(),
                kind: FreqTrend::None,
                damping_trend: DampingTrend::None,
                corner_trend: CornerTrend::None,
                modes: Vec::new(),
                tracks: Vec::new(),
                drift_check: DriftCheck::DistortionSeen,
            },
            Gain::none(
                "the disagreement comes with nonlinear distortion at one excitation level: its \
                 amplitude dependence cannot be fitted; repeat the experiment at two to four \
                 levels (e.g. 1×, 2×, 4×)",
            ),
        )
    }
}

/// Same-level experiments at the model experiment's rate disagree with it and nothing is
/// rate-tied: nonlinearity when the model experiment or a disagreeing one shows distortion,
/// drift when all of them have non-excited lines free of it, else unexplained.
pub(super) fn not_repeatable(data: &Data<'_>, ch: &Checks) -> Outcome {
    let a = ch.alpha_test;
    let failing: Vec<&Val<'_>> = data
        .vals
        .iter()
        .zip(&ch.free)
        .filter(|(v, _)| v.factor == 1 && v.comparable())
        .filter(|(v, fl)| !statistic([(fl.as_slice(), v.whole.inflation)], a).passes())
        .map(|(v, _)| v)
        .collect();
    let involved: Vec<&Estimate> = std::iter::once(&data.fast)
        .chain(failing.iter().map(|v| &v.whole))
        .collect();
    let family = distorted_family(&involved, a);
    let every_one_has_lines = involved.iter().all(|e| distorted(e, a).is_some());
    if family == Some(true) {
        one_level(failing.into_iter())
    } else if !failing.is_empty() && every_one_has_lines && family == Some(false) {
        let names = failing.iter().map(|v| v.exp.spec.name.clone()).collect();
        drift_outcome(names, DriftSign::RepeatWithoutDistortion)
    } else {
        Outcome::plain(
            Verdict::Discrepancy,
            Cause::Unexplained,
            Gain::none(
                "no slower experiment at the model experiment's level: nothing rate-tied to test",
            ),
        )
    }
}

/// The level test of every experiment at the model experiment's rate and another level:
/// the model-free prediction of it from the model experiment.
pub(super) fn level_tests(data: &Data<'_>, ch: &Checks) -> Vec<(usize, Statistic)> {
    data.vals
        .iter()
        .enumerate()
        .filter(|(_, v)| v.factor == 1 && !v.same_level())
        .map(|(i, v)| {
            let s = statistic([(ch.free[i].as_slice(), v.whole.inflation)], ch.alpha_test);
            (i, s)
        })
        .collect()
}

pub(super) fn fast_model_error(data: &Data<'_>, j: &Judged<'_>, ch: &Checks) -> Result<Outcome> {
    let mut worst: Vec<&Line> = ch.fast_model.iter().collect();
    worst.sort_by(|a, b| b.chi2().total_cmp(&a.chi2()));
    let own = statistic(
        [(ch.fast_model.as_slice(), data.fast.inflation)],
        ch.alpha_test,
    );
    let (mut b, mut a, mut held) = (0.0, 0.0, Vec::new());
    let mut repeats = false;
    for v in data.vals.iter().filter(|v| v.comparable()) {
        if let Some((_, v2)) = &v.parts {
            let c = v2.inflation;
            let before = statistic(
                [(j.lines(&v.model, v.factor, v2)?.as_slice(), c)],
                ch.alpha_test,
            );
            repeats |= !before.passes();
            b += before.value;
            let fl = free_lines(&data.pair(v.factor), v2);
            a += statistic([(fl.as_slice(), c)], 1.0).value;
            held.push(held_out_label(v.exp));
        }
    }
    if !held.is_empty() && !repeats {
        // the model's simulation is within the noise on every held-out part: its misfit on the
        // whole records does not repeat, so no fault of the model is named
        return Ok(Outcome::plain(
            Verdict::Discrepancy,
            Cause::Unexplained,
            Gain::none(
                "the model's misfit does not repeat on the held-out parts (its simulation is \
                 within the noise there): nothing to extend",
            ),
        ));
    }
    let n = held.len() as f64;
    Ok(Outcome {
        verdict: Verdict::Discrepancy,
        causes: vec![Cause::FastModelError {
            model_misfit_on_fast_data: own.value,
            worst_fast_hz: worst.iter().take(5).map(|l| l.f).collect(),
        }],
        extension: Extension::FastFrf,
        ranking: Vec::new(),
        partial: None,
        gain: if held.is_empty() {
            Gain::none("no validation experiment has enough periods to hold some out")
        } else {
            Gain::measured(b / n, a / n, held)
        },
        models: BTreeMap::new(),
        held: BTreeMap::new(),
        amplitude: None,
        next: None,
    })
}
