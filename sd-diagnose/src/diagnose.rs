//! The diagnosis as named stages (crate documentation): data → FRFs → model → consistency
//! checks → hypotheses → validation → findings.

use crate::amplitude::{
    candidates, describes, fit_level, kinds, level_floor, AmplitudeModel, Level, LevelFit,
};
use crate::data::{
    earlier_label, estimate, held_out_label, level, parts, rate_factor, Estimate, Part,
};
use crate::findings::{bands, dominant_fold, responses, time_domain};
use crate::hypotheses::{penalised, Family, Fitted, Modal, StdErrors, Target};
use crate::lemma6::{compare, Pair, Pred};
use crate::modal::{ModalBasis, Residues};
use crate::stats::{statistic, Line, Statistic};
use crate::{
    joined, merged_parameters, Cause, CornerTrend, Curves, DampingTrend, DiagnoseError,
    DiagnoseOptions, Diagnosis, DriftCheck, DriftSign, Evidence, EvidenceKind, ExperimentReport,
    ExtendedModel, Extension, FreqTrend, Gain, HeldOut, ModelInfo, OwnFit, Ranked, RateTied,
    Result, Verdict,
};
use num_complex::Complex64 as C;
use sd_ident::{DistortionReport, Experiment, Role};
use sd_model::normal_quantile;
use sd_model::{SampleTime, StateSpace};
use sd_multirate::{downsample, NonIdeal};
use std::collections::BTreeMap;

/// Excitation levels within this relative distance count as the same level.
const LEVEL_TOL: f64 = 0.2;

/// A validation experiment with its estimates and the model's simulation at its rate.
struct Val<'a> {
    exp: &'a Experiment,
    factor: usize,
    whole: Estimate,
    /// Training and held-out parts, when both give variances.
    parts: Option<(Estimate, Estimate)>,
    /// Level relative to the model experiment's.
    level: f64,
    /// Compared as if at the model experiment's level: within [`LEVEL_TOL`] of it, or (a
    /// slower experiment) inside the span of fast-rate levels that agree with each other
    /// ([`Data::widen_levels`]).
    comparable: std::cell::Cell<bool>,
    /// The model's simulation at this rate (Lemma 6).
    model: StateSpace,
}

impl Val<'_> {
    /// At the model experiment's level (within [`LEVEL_TOL`]).
    fn same_level(&self) -> bool {
        (self.level - 1.0).abs() <= LEVEL_TOL
    }
    /// Compared with the model experiment as at its level.
    fn comparable(&self) -> bool {
        self.comparable.get()
    }
    /// Rate-tied effects show on it: a comparable level, slower rate.
    fn rate_tied(&self) -> bool {
        self.comparable() && self.factor > 1
    }
}

/// Stage 1: the data and their FRFs.
struct Data<'a> {
    model_exp: &'a Experiment,
    fast: Estimate,
    h: f64,
    vals: Vec<Val<'a>>,
}

fn has_var(e: &Estimate) -> bool {
    e.frd.variance().is_some()
}

impl<'a> Data<'a> {
    fn read(experiments: &'a [Experiment], progress: &mut dyn FnMut(&str)) -> Result<Self> {
        if experiments.len() < 2 {
            return Err(DiagnoseError::Setup(
                "a diagnosis needs a model experiment and at least one validation experiment"
                    .into(),
            ));
        }
        let model_exp = experiments
            .iter()
            .find(|e| e.spec.role == Role::Model)
            .or_else(|| {
                experiments
                    .iter()
                    .max_by(|a, b| a.spec.sample_rate_hz.total_cmp(&b.spec.sample_rate_hz))
            })
            .ok_or_else(|| DiagnoseError::Setup("no model experiment".into()))?;
        // every rate first: a wrong one is said before any work
        for e in experiments.iter().filter(|e| !std::ptr::eq(*e, model_exp)) {
            rate_factor(model_exp, e)?;
        }
        progress(&format!("FRF of `{}`", model_exp.spec.name));
        let fast = estimate(model_exp, Part::Whole)?;
        if !has_var(&fast) {
            return Err(DiagnoseError::Setup(format!(
                "`{}` gives no FRF variance: a periodic experiment needs at least two steady \
                 periods",
                model_exp.spec.name
            )));
        }
        let lm = level(model_exp);
        let vals = experiments
            .iter()
            .filter(|e| !std::ptr::eq(*e, model_exp))
            .map(|e| {
                progress(&format!("FRF of `{}`", e.spec.name));
                Ok((e, rate_factor(model_exp, e)?, estimate(e, Part::Whole)?))
            })
            .collect::<Result<Vec<_>>>()?;
        let data = Data {
            model_exp,
            fast,
            h: 1.0 / model_exp.spec.sample_rate_hz,
            vals: Vec::new(),
        };
        let mut out = Vec::with_capacity(vals.len());
        for (e, factor, whole) in vals {
            if !has_var(&whole) {
                return Err(DiagnoseError::Setup(format!(
                    "`{}` gives no FRF variance: it needs at least two steady periods",
                    e.spec.name
                )));
            }
            let parts = parts(e, &whole);
            out.push(Val {
                exp: e,
                factor,
                whole,
                parts,
                level: level(e) / lm.max(f64::MIN_POSITIVE),
                comparable: std::cell::Cell::new(false),
                model: StateSpace::new(
                    nalgebra::DMatrix::zeros(0, 0),
                    nalgebra::DMatrix::zeros(0, 1),
                    nalgebra::DMatrix::zeros(1, 0),
                    nalgebra::DMatrix::zeros(1, 1),
                    SampleTime::Continuous,
                )?,
            });
        }
        for v in &out {
            v.comparable.set(v.same_level());
        }
        Ok(Data { vals: out, ..data })
    }

    /// When every fast-rate experiment at another level agrees with the model experiment
    /// (its level test passes), the plant is linear over their span: a slower experiment at a
    /// level inside it (widened by [`LEVEL_TOL`]) is compared as if at the model experiment's
    /// level, so that a rate-tied effect on it is tested rather than taken for amplitude.
    fn widen_levels(&self, tests: &[(usize, Statistic)]) {
        if tests.is_empty() || tests.iter().any(|(_, s)| !s.passes()) {
            return;
        }
        let (lo, hi) = tests
            .iter()
            .map(|(i, _)| self.vals[*i].level)
            .fold((1.0f64, 1.0f64), |(lo, hi), l| (lo.min(l), hi.max(l)));
        for v in self.vals.iter().filter(|v| v.factor > 1) {
            let inside = v.level >= lo * (1.0 - LEVEL_TOL) && v.level <= hi * (1.0 + LEVEL_TOL);
            v.comparable.set(v.comparable.get() || inside);
        }
    }

    fn pair(&self, factor: usize) -> Pair<'_> {
        Pair {
            fast: &self.fast.frd,
            factor,
            h: self.h,
            dof: self.fast.dof,
        }
    }
}

/// Stage 2's model with its modal form (the prediction variance of a fitted model and the
/// base of every extension).
struct Judged<'a> {
    model: StateSpace,
    info: ModelInfo,
    given: bool,
    modal: Modal<'a>,
    plain: Residues,
}

impl Judged<'_> {
    /// Lines of `est` (slower by `factor`) against the model's simulation `sim`.
    fn lines(&self, sim: &StateSpace, factor: usize, est: &Estimate) -> Result<Vec<Line>> {
        let f = est.frd.freq_hz();
        let resp = responses(sim, f)?;
        let ts = self.modal.h * factor as f64;
        let ideal = NonIdeal::ideal();
        let phi = if self.given {
            None
        } else {
            let b = &self.modal.basis;
            Some((
                b.responses(ts, ideal, f)?,
                b.pole_sensitivities(&self.plain.r, ts, ideal, f)?,
            ))
        };
        Ok(compare(&est.frd, est.dof, |i, _| {
            let var = phi
                .as_ref()
                .map(|(p, d)| self.plain.predict_full(&p[i], &d[i]).1)
                .unwrap_or(0.0);
            Some(Pred {
                value: resp[i],
                var,
                dof: f64::INFINITY,
                params: if self.given { 0 } else { self.plain.n_params() },
            })
        }))
    }
}

/// Stage 3: the consistency checks of every validation experiment.
struct Checks {
    free: Vec<Vec<Line>>,
    model: Vec<Vec<Line>>,
    fast_model: Vec<Line>,
    /// False-alarm probability per test (α over the number of verdict tests).
    alpha_test: f64,
    evidence: Vec<Evidence>,
}

fn free_lines(p: &Pair<'_>, est: &Estimate) -> Vec<Line> {
    compare(&est.frd, est.dof, |_, f| p.predict(f))
}

fn checks(data: &Data<'_>, j: &Judged<'_>, alpha: f64) -> Result<Checks> {
    let mut free = Vec::new();
    let mut model = Vec::new();
    for v in &data.vals {
        let fl = free_lines(&data.pair(v.factor), &v.whole);
        if fl.is_empty() {
            return Err(DiagnoseError::Setup(format!(
                "no line of `{}` has all its fold frequencies on the model experiment's grid: \
                 the model experiment's line spacing must divide this experiment's ({} Hz \
                 sampling); for non-periodic records make the fast record's duration a whole \
                 multiple of this one's",
                v.exp.spec.name, v.exp.spec.sample_rate_hz
            )));
        }
        free.push(fl);
        model.push(j.lines(&v.model, v.factor, &v.whole)?);
    }
    // the verdict's tests: the pooled model-free test of the same-level experiments, the
    // pooled model test, one level test per same-rate experiment at another level
    let level_tests = data
        .vals
        .iter()
        .filter(|v| v.factor == 1 && !v.same_level())
        .count();
    let alpha_test = alpha / (2 + level_tests) as f64;
    let fast_model = j.lines(&j.model, 1, &data.fast)?;
    let mut evidence = vec![Evidence::of(
        EvidenceKind::OwnData,
        format!(
            "model ({}) against its own data `{}`",
            j.info.source, data.model_exp.spec.name
        ),
        &statistic([(fast_model.as_slice(), data.fast.inflation)], alpha_test),
    )];
    if let Some(d) = &data.fast.distortion {
        evidence.extend(distortion_evidence(
            &data.model_exp.spec.name,
            d,
            alpha_test,
        ));
    }
    for (i, v) in data.vals.iter().enumerate() {
        let c = v.whole.inflation.max(data.fast.inflation);
        evidence.push(Evidence::of(
            EvidenceKind::ModelFree,
            format!(
                "Lemma 6 prediction of `{}` from `{}` (model-free)",
                v.exp.spec.name, data.model_exp.spec.name
            ),
            &statistic([(free[i].as_slice(), c)], alpha_test),
        ));
        evidence.push(Evidence::of(
            EvidenceKind::ModelSimulation,
            format!("the model's simulation of `{}`", v.exp.spec.name),
            &statistic([(model[i].as_slice(), c)], alpha_test),
        ));
        if let Some(d) = &v.whole.distortion {
            evidence.extend(distortion_evidence(&v.exp.spec.name, d, alpha_test));
        }
        if v.factor == 1 {
            evidence.push(Evidence::check(
                EvidenceKind::SameLevel,
                format!(
                    "`{}` at {:.3}× the model experiment's excitation level (|ratio − 1| within \
                     20 %: the same level)",
                    v.exp.spec.name, v.level
                ),
                (v.level - 1.0).abs(),
                LEVEL_TOL,
            ));
        }
    }
    Ok(Checks {
        free,
        model,
        fast_model,
        alpha_test,
        evidence,
    })
}

/// Evidence of nonlinear distortion at the non-excited odd and even lines of the band: each
/// line's power over its own noise estimate, combined by Fisher's method (the mean `−ln p`,
/// [`sd_ident::DistortionReport::odd_score`]), which is `Gamma(L, 1)/L` without distortion
/// whatever the noise spectrum: its threshold is that law's `1 − α` quantile.
fn distortion_evidence(name: &str, d: &DistortionReport, alpha: f64) -> Vec<Evidence> {
    [
        ("odd", d.odd_score, d.odd_lines),
        ("even", d.even_score, d.even_lines),
    ]
    .into_iter()
    .filter(|x| x.2 > 0)
    .map(|(kind, score, lines)| {
        Evidence::check(
            EvidenceKind::Distortion,
            format!(
                "power at the {lines} non-excited {kind} lines of `{name}` over each line's \
                 noise (nonlinear distortion; Fisher's score, 1 without)"
            ),
            score,
            crate::stats::threshold(lines as f64, alpha),
        )
    })
    .collect()
}

/// Stages 4–5: the cause, the extension and its gain.
struct Outcome {
    verdict: Verdict,
    causes: Vec<Cause>,
    extension: Extension,
    ranking: Vec<Ranked>,
    partial: Option<Ranked>,
    gain: Gain,
    /// The extended model per experiment where the extension is not rate-tied (the
    /// amplitude-dependent model at each level).
    models: BTreeMap<String, StateSpace>,
    /// Per whole held-out experiment, its statistics before and after.
    held: BTreeMap<String, HeldOut>,
}

impl Outcome {
    fn plain(verdict: Verdict, cause: Cause, gain: Gain) -> Self {
        Outcome {
            verdict,
            causes: vec![cause],
            extension: Extension::None,
            ranking: Vec::new(),
            partial: None,
            gain,
            models: BTreeMap::new(),
            held: BTreeMap::new(),
        }
    }
}

fn decide(
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
        // only other levels, and they agree
        if s_model.passes() {
            if let Some(o) = moves_under_distortion(data, j, ch, progress)? {
                return Ok(o);
            }
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
    let (o, _) = rate_tied(data, j, progress)?;
    let seen = std::iter::once(&data.fast)
        .chain(data.vals.iter().map(|v| &v.whole))
        .any(|e| distorted(e, a) == Some(true));
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
fn moves_under_distortion(
    data: &Data<'_>,
    j: &Judged<'_>,
    ch: &mut Checks,
    progress: &mut dyn FnMut(&str),
) -> Result<Option<Outcome>> {
    let a = ch.alpha_test;
    let levels: Vec<(usize, Statistic)> = data
        .vals
        .iter()
        .enumerate()
        .filter(|(_, v)| v.factor == 1 && !v.same_level() && distorted(&v.whole, a) == Some(true))
        .map(|(i, v)| {
            (
                i,
                statistic([(ch.model[i].as_slice(), v.whole.inflation)], a),
            )
        })
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
fn distorted(est: &Estimate, alpha: f64) -> Option<bool> {
    let ev = distortion_evidence("", est.distortion.as_ref()?, alpha);
    (!ev.is_empty()).then(|| ev.iter().any(|e| !e.passed))
}

/// Other excitation levels at the model experiment's rate that the model-free level test
/// cannot resolve (it carries the model experiment's FRF variance too) but whose simulation by
/// the model fails at the verdict's level, each showing nonlinear distortion at its
/// non-excited lines, while the model describes its own experiment (within the noise, or its
/// misfit there is distortion too): the disagreement comes with distortion, which drift does
/// not bring. Both tests at `α` on a linear stage: a false alarm needs both, about `α²`.
fn distorted_levels(data: &Data<'_>, ch: &Checks) -> Vec<(usize, Statistic)> {
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
fn distortion_explains(data: &Data<'_>, ch: &mut Checks) -> Option<Outcome> {
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
fn partly_rate_tied(o: &Outcome, data: &Data<'_>, ch: &Checks) -> bool {
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
fn drift_outcome(experiments: Vec<String>, sign: DriftSign) -> Outcome {
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
fn one_level<'v, 'a: 'v>(disagreeing: impl Iterator<Item = &'v Val<'a>>) -> Outcome {
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
fn not_repeatable(data: &Data<'_>, ch: &Checks) -> Outcome {
    let a = ch.alpha_test;
    let failing: Vec<&Val<'_>> = data
        .vals
        .iter()
        .zip(&ch.free)
        .filter(|(v, _)| v.factor == 1 && v.comparable())
        .filter(|(v, fl)| !statistic([(fl.as_slice(), v.whole.inflation)], a).passes())
        .map(|(v, _)| v)
        .collect();
    let seen: Vec<Option<bool>> = std::iter::once(&data.fast)
        .chain(failing.iter().map(|v| &v.whole))
        .map(|e| distorted(e, a))
        .collect();
    if seen.contains(&Some(true)) {
        one_level(failing.into_iter())
    } else if !failing.is_empty() && seen.iter().all(|s| *s == Some(false)) {
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
fn level_tests(data: &Data<'_>, ch: &Checks) -> Vec<(usize, Statistic)> {
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

/// Every level's modal fit on `basis`: the candidates, less those the model experiment
/// itself does not determine or finds elsewhere than the linear model
/// ([`LevelFit::agrees_with_linear`]), fitted again without them; `None` when a fit fails or
/// no candidate is left.
fn level_fits(
    basis: &ModalBasis,
    data: &Data<'_>,
    levels: &[Level<'_>],
) -> Option<(Vec<usize>, Vec<LevelFit>)> {
    let fit = |cand: &[usize]| -> Option<Vec<LevelFit>> {
        levels
            .iter()
            .map(|lv| fit_level(basis, cand, data.h, lv))
            .collect::<Result<Vec<_>>>()
            .ok()
    };
    let cand = candidates(basis, &data.fast);
    let first = fit(&cand)?;
    let cand: Vec<usize> = cand
        .iter()
        .enumerate()
        .filter(|(m, _)| {
            first
                .first()
                .is_some_and(|f| f.determines(*m) && f.agrees_with_linear(*m))
        })
        .map(|(_, c)| *c)
        .collect();
    if cand.is_empty() {
        return None;
    }
    let fits = fit(&cand)?;
    Some((cand, fits))
}

/// Slack on the model experiment's statistic within which a slow pole counts as unneeded.
const SLOW_POLE_SLACK: f64 = 1.1;

/// The statistic a changed basis may reach on the model experiment `reference` and still
/// describe it: [`SLOW_POLE_SLACK`] times the larger of the verdict's threshold and `basis`'s
/// own statistic.
fn slack_bound(basis: &ModalBasis, h: f64, reference: &Level<'_>, alpha: f64) -> Result<f64> {
    let full = describes(basis, h, reference, alpha)?;
    Ok(SLOW_POLE_SLACK * full.threshold.max(full.value))
}

/// A friction-damped rigid body's basis without the slow real poles and overdamped pairs
/// ([`ModalBasis::slow_extras`]) the model experiment does not need: each, slowest first, is
/// dropped when the basis without it still describes the model experiment `reference`
/// within [`SLOW_POLE_SLACK`] times the larger of the verdict's threshold and the full
/// basis's statistic (a sensor filter's pole raises it several-fold and stays; a pole the
/// fit spent on the friction's distortion does not).
fn without_unneeded_slow_poles(
    damped: &ModalBasis,
    h: f64,
    reference: &Level<'_>,
    alpha: f64,
) -> Result<ModalBasis> {
    let extras = damped.slow_extras();
    if extras.is_empty() {
        return Ok(damped.clone());
    }
    let bound = slack_bound(damped, h, reference, alpha)?;
    let mut dropped: Vec<num_complex::Complex64> = Vec::new();
    let mut basis = damped.clone();
    for p in extras {
        dropped.push(p);
        let trial = damped.without_poles(&dropped)?;
        if describes(&trial, h, reference, alpha).is_ok_and(|s| s.value <= bound) {
            basis = trial;
        } else {
            dropped.pop();
        }
    }
    Ok(basis)
}

/// One basis the levels may be modelled on, with its candidates and every level's fit.
struct Variant {
    basis: ModalBasis,
    cand: Vec<usize>,
    fits: Vec<LevelFit>,
}

/// The other corners a friction-damped rigid body may have: where several real poles below
/// the modes could be the corner (a fit at the friction's strongest level may spend one on
/// the friction's distortion, slower or faster than the corner), the bases with the second,
/// third… as the corner ([`ModalBasis::with_damped_rigid_body_at`]), each without the slow
/// poles the model experiment does not need, with their level fits. Which one models the
/// levels is decided on the levels a model is fitted on ([`choose`]).
fn other_corners(
    j: &Judged<'_>,
    data: &Data<'_>,
    levels: &[Level<'_>],
    alpha: f64,
) -> Result<Vec<Variant>> {
    let near_zero = std::f64::consts::TAU * data.fast.frd.freq_hz().first().copied().unwrap_or(0.0);
    let basis = &j.modal.basis;
    let mut out = Vec::new();
    for nth in 1..basis.corner_choices(near_zero) {
        let Some(b) = basis.with_damped_rigid_body_at(near_zero, nth)? else {
            continue;
        };
        let trial = without_unneeded_slow_poles(&b, data.h, &levels[0], alpha)?;
        if let Some((cand, fits)) = level_fits(&trial, data, levels) {
            out.push(Variant {
                basis: trial,
                cand,
                fits,
            });
        }
    }
    Ok(out)
}

/// The friction-damped rigid body without every slow extra ([`ModalBasis::slow_extras`])
/// as a variant with its level fits, when it has extras: a fit of the model experiment may
/// spend real poles on lines the friction distorts most at its level (the lowest lines,
/// where the record's drift leaks in, or the stochastic distortion near the corner), which
/// the other levels do not share; whether the bare corner models the levels better is
/// decided on the training levels ([`choose`]).
fn without_slow_extras(
    damped: &ModalBasis,
    data: &Data<'_>,
    levels: &[Level<'_>],
) -> Option<Variant> {
    let extras = damped.slow_extras();
    if extras.is_empty() {
        return None;
    }
    let basis = damped.without_poles(&extras).ok()?;
    let (cand, fits) = level_fits(&basis, data, levels)?;
    Some(Variant { basis, cand, fits })
}

/// Of `variants`, the one whose amplitude model, fitted on the levels `on` (indices into
/// `levels`), describes those same levels best (the pooled statistic of its predictions
/// over all their lines): a structural choice made on the training levels only. Every
/// variant fits each level about as well with free residues; the amplitude model shares the
/// model experiment's residues across levels, so only the basis whose moving pole carries
/// the amplitude dependence describes them all. The first variant where none can be fitted.
fn choose(variants: &[Variant], levels: &[Level<'_>], on: &[usize], h: f64, alpha: f64) -> usize {
    if variants.len() < 2 {
        return 0;
    }
    let score = |v: &Variant| -> Option<f64> {
        let lv: Vec<&Level<'_>> = on.iter().map(|&q| &levels[q]).collect();
        let fits: Vec<&LevelFit> = on.iter().map(|&q| &v.fits[q]).collect();
        let m = AmplitudeModel::fit(&v.basis, h, &v.cand, &lv, &fits, alpha).ok()?;
        let lines: Vec<(Vec<Line>, f64)> = lv
            .iter()
            .map(|l| m.lines(l).map(|x| (x, l.est.inflation)))
            .collect::<Result<_>>()
            .ok()?;
        let s = statistic(lines.iter().map(|(l, c)| (l.as_slice(), *c)), alpha).value;
        s.is_finite().then_some(s)
    };
    // a variant that cannot be fitted scores +∞; ties (and all unfitted) keep the first
    let scores: Vec<f64> = variants
        .iter()
        .map(|v| score(v).unwrap_or(f64::INFINITY))
        .collect();
    (1..variants.len()).fold(0, |best, i| if scores[i] < scores[best] { i } else { best })
}

/// A friction-damped reading of a basis that shows no damped rigid body, when it still
/// describes the model experiment `reference` within [`SLOW_POLE_SLACK`] times the larger of
/// the verdict's threshold and the plain basis's statistic; `None` otherwise. Tried in turn:
/// its two slowest real poles as the integrator and the corner
/// ([`ModalBasis::with_slow_poles_as_damped_rigid_body`]); its double integrator as one
/// integrator and its first real pole below the modes as the corner
/// ([`ModalBasis::with_one_integrator`], then [`ModalBasis::with_damped_rigid_body`]; an
/// undamped rigid body with a sensor's real pole is not described: its low-frequency
/// response `1/s²` becomes `1/(a s)`).
fn damped_reading(
    plain: &ModalBasis,
    near_zero: f64,
    h: f64,
    reference: &Level<'_>,
    alpha: f64,
) -> Result<Option<ModalBasis>> {
    let mut readings = Vec::new();
    if let Some(b) = plain.with_slow_poles_as_damped_rigid_body()? {
        readings.push(b);
    }
    if let Some(one) = plain.with_one_integrator()? {
        let b = one.with_damped_rigid_body(near_zero)?;
        if b.is_damped() {
            readings.push(b);
        }
    }
    if readings.is_empty() {
        return Ok(None);
    }
    let bound = slack_bound(plain, h, reference, alpha)?;
    Ok(readings
        .into_iter()
        .find(|b| describes(b, h, reference, alpha).is_ok_and(|s| s.value <= bound)))
}

/// A same-level repeat at the model experiment's rate that disagrees while neither of the
/// pair shows distortion: drift (a pair that shows distortion differs by the nonlinearity's
/// stochastic contributions, another phase realisation, and is no evidence of drift).
fn repeat_drifts(data: &Data<'_>, ch: &mut Checks) -> Option<Outcome> {
    let alpha = ch.alpha_test;
    let (v, s) = data
        .vals
        .iter()
        .enumerate()
        .filter(|(_, v)| v.factor == 1 && v.same_level())
        .map(|(i, v)| {
            let s = statistic([(ch.free[i].as_slice(), v.whole.inflation)], alpha);
            (v, s)
        })
        .find(|(v, s)| {
            let pair = [&data.fast, &v.whole];
            !s.passes() && !pair.iter().any(|e| distorted(e, alpha) == Some(true))
        })?;
    ch.evidence.push(Evidence::of(
        EvidenceKind::Drift,
        format!(
            "`{}` repeats the model experiment's level and rate yet disagrees: the plant \
             changed with time, not with amplitude",
            v.exp.spec.name
        ),
        &s,
    ));
    Some(drift_outcome(
        vec![v.exp.spec.name.clone()],
        DriftSign::RepeatWithoutDistortion,
    ))
}

/// What rules drift out for a nonlinearity: distortion seen at any experiment at the model
/// experiment's rate, else a same-level repeat that agrees, else nothing.
fn drift_check(data: &Data<'_>, alpha: f64) -> DriftCheck {
    let seen = std::iter::once(&data.fast)
        .chain(data.vals.iter().filter(|v| v.factor == 1).map(|v| &v.whole))
        .any(|e| distorted(e, alpha) == Some(true));
    if seen {
        DriftCheck::DistortionSeen
    } else if data.vals.iter().any(|v| v.factor == 1 && v.same_level()) {
        DriftCheck::RepeatAgrees
    } else {
        DriftCheck::Unchecked
    }
}

/// Experiments at other levels disagree: the amplitude-dependent modal model
/// ([`crate::amplitude`]) over every experiment at the model experiment's rate, its gain on
/// whole levels left out in turn (three or more levels) or on the later periods of the other
/// level (two). A same-level repeat that disagrees as well is drift, not nonlinearity.
fn nonlinearity(
    data: &Data<'_>,
    j: &Judged<'_>,
    ch: &mut Checks,
    found: &[(usize, Statistic)],
    progress: &mut dyn FnMut(&str),
) -> Result<Outcome> {
    let alpha = ch.alpha_test;
    let relative_levels: BTreeMap<String, f64> = found
        .iter()
        .map(|(i, _)| (data.vals[*i].exp.spec.name.clone(), data.vals[*i].level))
        .collect();
    if let Some(o) = repeat_drifts(data, ch) {
        return Ok(o);
    }
    let check = drift_check(data, alpha);
    let mut levels = vec![Level {
        name: data.model_exp.spec.name.clone(),
        exp: data.model_exp,
        est: &data.fast,
    }];
    let mut at: Vec<Option<usize>> = vec![None];
    for (i, v) in data.vals.iter().enumerate().filter(|(_, v)| v.factor == 1) {
        levels.push(Level {
            name: v.exp.spec.name.clone(),
            exp: v.exp,
            est: &v.whole,
        });
        at.push(Some(i));
    }
    // a rigid body damped at the model experiment's level (friction) becomes one block whose
    // damping moves (a pole below the first line is an integrator for the data)
    let f0 = data.fast.frd.freq_hz().first().copied().unwrap_or(0.0);
    let mut damped = j
        .modal
        .basis
        .with_damped_rigid_body(std::f64::consts::TAU * f0)?;
    if !damped.is_damped() {
        let near_zero = std::f64::consts::TAU * f0;
        if let Some(b) = damped_reading(&damped, near_zero, data.h, &levels[0], alpha)? {
            damped = b;
        }
    }
    progress("modal fit of every level");
    // the damped rigid body without the slow poles the model experiment does not need, then
    // with them; if its fits fail, the model's own basis; a mode the model split into two
    // close pairs as one pair
    let mut bases = vec![without_unneeded_slow_poles(
        &damped, data.h, &levels[0], alpha,
    )?];
    if damped.is_damped() {
        bases.push(damped.clone());
        bases.push(j.modal.basis.clone());
    }
    bases.extend(damped.without_close_pairs()?);
    bases.dedup_by(|a, b| a.poles() == b.poles() && a.is_damped() == b.is_damped());
    let tried = bases
        .iter()
        .find_map(|b| level_fits(b, data, &levels).map(|x| (b, x)));
    let Some((basis, (cand, fits))) = tried else {
        return Ok(per_level(data, found, (relative_levels, check), alpha));
    };
    let mut variants = vec![Variant {
        basis: basis.clone(),
        cand,
        fits,
    }];
    if damped.is_damped() && levels.len() >= 3 {
        variants.extend(other_corners(j, data, &levels, alpha)?);
        variants.extend(without_slow_extras(&damped, data, &levels));
    }
    let every: Vec<usize> = (0..levels.len()).collect();
    let chosen = choose(&variants, &levels, &every, data.h, alpha);
    let Variant { basis, cand, fits } = &variants[chosen];
    let all: Vec<&Level<'_>> = levels.iter().collect();
    let fit_refs: Vec<&LevelFit> = fits.iter().collect();
    let model = AmplitudeModel::fit(basis, data.h, cand, &all, &fit_refs, alpha)?;
    progress("amplitude model: levels left out in turn");
    let (gain, loo, held) = if levels.len() >= 3 {
        levels_left_out(data, ch, &levels, &at, (&variants, chosen, alpha))?
    } else {
        (
            later_periods(data, j, &levels, fits, (basis, cand), alpha)?,
            Vec::new(),
            BTreeMap::new(),
        )
    };
    let modes = model.report(&all, &fit_refs, &loo);
    let (kind, damping_trend, corner_trend) = kinds(&modes, normal_quantile(1.0 - alpha / 2.0));
    let mut models = BTreeMap::new();
    for lv in &levels {
        models.insert(lv.name.clone(), model.model_at(lv)?);
    }
    Ok(Outcome {
        verdict: Verdict::Discrepancy,
        causes: vec![Cause::Nonlinearity {
            relative_levels,
            kind,
            damping_trend,
            corner_trend,
            modes: modes.clone(),
            drift_check: check,
        }],
        extension: Extension::Amplitude(modes),
        ranking: Vec::new(),
        partial: None,
        gain,
        models,
        held,
    })
}

/// Per level, the frequencies and dampings the model fitted without it predicted.
type LeftOut = Vec<Option<Vec<(f64, f64)>>>;

/// Three or more levels: each validation level left out in turn, the amplitude model fitted
/// on the others (the model experiment always among them) and judged on it; before: the
/// linear model's simulation of it.
fn levels_left_out(
    data: &Data<'_>,
    ch: &Checks,
    levels: &[Level<'_>],
    at: &[Option<usize>],
    (variants, chosen, alpha): (&[Variant], usize, f64),
) -> Result<(Gain, LeftOut, BTreeMap<String, HeldOut>)> {
    let (mut before, mut after, mut held) = (Vec::new(), Vec::new(), Vec::new());
    let mut per = BTreeMap::new();
    let mut loo: LeftOut = vec![None; levels.len()];
    // each level's excitation relative to the model experiment's
    let level_of = |q: usize| at[q].map_or(1.0, |i| data.vals[i].level);
    for (k, lv) in levels.iter().enumerate().skip(1) {
        let Some(i) = at[k] else { continue };
        let train: Vec<&Level<'_>> = levels
            .iter()
            .enumerate()
            .filter(|(m, _)| *m != k)
            .map(|(_, l)| l)
            .collect();
        // the basis chosen on the training levels alone ([`choose`])
        let on: Vec<usize> = (0..levels.len()).filter(|m| *m != k).collect();
        let fold = choose(variants, levels, &on, data.h, alpha);
        let Variant { basis, cand, fits } = &variants[fold];
        let tf: Vec<&LevelFit> = on.iter().map(|&q| &fits[q]).collect();
        let m = AmplitudeModel::fit(basis, data.h, cand, &train, &tf, alpha)?;
        // per-candidate predictions only where the fold's basis is the final one's
        loo[k] = (fold == chosen).then(|| m.predicted(lv));
        let c = lv.est.inflation;
        let bands = m.moving_bands(lv);
        let (a, b) = (
            in_bands(m.lines(lv)?, &bands),
            in_bands(ch.model[i].clone(), &bands),
        );
        let (sa, sb) = (
            statistic([(a.as_slice(), c)], alpha).value,
            statistic([(b.as_slice(), c)], alpha).value,
        );
        let own = level_floor((basis, cand), &fits[k], data.h, lv, &bands, alpha)?;
        // beyond the fitted amplitudes of a moving mode; or, where nothing moves on the
        // training levels, beyond their excitation levels
        let (lo, hi) = (0..levels.len())
            .filter(|q| *q != k)
            .map(level_of)
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), x| {
                (lo.min(x), hi.max(x))
            });
        let beyond = level_of(k) < lo * 0.999 || level_of(k) > hi * 1.001;
        let extrapolated = m.extrapolates(lv, &tf) || (!m.moves_any() && beyond);
        per.insert(
            lv.name.clone(),
            HeldOut {
                before: sb,
                after: sa,
                ratio: sb / sa,
                floor: own,
                lines: a.len(),
                extrapolated,
            },
        );
        after.push((a, c));
        before.push((b, c));
        held.push(format!(
            "{} (whole experiment, left out{})",
            lv.name,
            if extrapolated {
                "; beyond the fitted amplitudes: extrapolated"
            } else {
                ""
            }
        ));
    }
    let pooled =
        |sets: &[(Vec<Line>, f64)]| statistic(sets.iter().map(|(l, c)| (l.as_slice(), *c)), alpha);
    Ok((
        Gain::measured(pooled(&before).value, pooled(&after).value, held)
            .with_metric(Gain::METRIC_BANDS),
        loo,
        per,
    ))
}

/// The lines inside any of `bands` (all of them when there are no bands).
fn in_bands(lines: Vec<Line>, bands: &[(f64, f64)]) -> Vec<Line> {
    if bands.is_empty() {
        return lines;
    }
    lines
        .into_iter()
        .filter(|l| bands.iter().any(|(lo, hi)| l.f >= *lo && l.f <= *hi))
        .collect()
}

/// Two levels: the amplitude model fitted on the model experiment and the other level's
/// earlier periods, judged on its later ones (labelled so).
fn later_periods(
    data: &Data<'_>,
    j: &Judged<'_>,
    levels: &[Level<'_>],
    fits: &[LevelFit],
    (basis, cand): (&ModalBasis, &[usize]),
    alpha: f64,
) -> Result<Gain> {
    let Some(other) = levels.get(1) else {
        return Ok(Gain::none("one level only"));
    };
    let Some(v) = data.vals.iter().find(|v| std::ptr::eq(v.exp, other.exp)) else {
        return Ok(Gain::none("one level only"));
    };
    let Some((early, late)) = &v.parts else {
        return Ok(Gain::none(
            "two levels only, and the other level has fewer than four steady periods (or too \
             short a record) to hold part of it out",
        ));
    };
    let train_lv = Level {
        name: other.name.clone(),
        exp: other.exp,
        est: early,
    };
    let held_lv = Level {
        name: other.name.clone(),
        exp: other.exp,
        est: late,
    };
    let tf = fit_level(basis, cand, data.h, &train_lv)?;
    let m = AmplitudeModel::fit(
        basis,
        data.h,
        cand,
        &[&levels[0], &train_lv],
        &[&fits[0], &tf],
        alpha,
    )?;
    let bands = m.moving_bands(&held_lv);
    let after = statistic(
        [(
            in_bands(m.lines(&held_lv)?, &bands).as_slice(),
            late.inflation,
        )],
        alpha,
    );
    let before = statistic(
        [(
            in_bands(j.lines(&v.model, 1, late)?, &bands).as_slice(),
            late.inflation,
        )],
        alpha,
    );
    Ok(Gain::measured(
        before.value,
        after.value,
        vec![format!(
            "{} (two levels only: fitted on its earlier periods)",
            held_out_label(v.exp)
        )],
    )
    .with_metric(Gain::METRIC_BANDS))
}

/// Without in-band modes to move: one FRF per level (the level's own earlier periods predict
/// its later ones).
fn per_level(
    data: &Data<'_>,
    found: &[(usize, Statistic)],
    (relative_levels, check): (BTreeMap<String, f64>, DriftCheck),
    alpha: f64,
) -> Outcome {
    let (mut b, mut af, mut held) = (0.0, 0.0, Vec::new());
    for (i, _) in found {
        let v = &data.vals[*i];
        if let Some((v1, v2)) = &v.parts {
            b += statistic(
                [(free_lines(&data.pair(1), v2).as_slice(), v2.inflation)],
                alpha,
            )
            .value;
            let own = Pair {
                fast: &v1.frd,
                factor: 1,
                h: data.h,
                dof: v1.dof,
            };
            af += statistic([(free_lines(&own, v2).as_slice(), v2.inflation)], alpha).value;
            held.push(held_out_label(v.exp));
        }
    }
    let n = held.len() as f64;
    let gain = if held.is_empty() {
        Gain::none("no experiment at another level has enough periods to hold some out")
    } else {
        Gain::measured(b / n, af / n, held)
    };
    Outcome {
        verdict: Verdict::Discrepancy,
        causes: vec![Cause::Nonlinearity {
            relative_levels,
            kind: FreqTrend::None,
            damping_trend: DampingTrend::None,
            corner_trend: CornerTrend::None,
            modes: Vec::new(),
            drift_check: check,
        }],
        extension: Extension::PerLevel,
        ranking: Vec::new(),
        partial: None,
        gain,
        models: BTreeMap::new(),
        held: BTreeMap::new(),
    }
}

fn fast_model_error(data: &Data<'_>, j: &Judged<'_>, ch: &Checks) -> Result<Outcome> {
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
    })
}

fn ranked(f: &Fitted, held: Option<f64>) -> Ranked {
    Ranked {
        cause: f.family.name(),
        cost: f.stat.value,
        criterion: f.criterion,
        held_out: held,
        n_params: f.params.clock_error.len()
            + usize::from(f.family.delay())
            + usize::from(f.family.average()),
    }
}

fn target<'v>(v: &'v Val<'_>, part: Part) -> Target<'v> {
    Target {
        factor: v.factor,
        est: match (&v.parts, part) {
            (Some(p), Part::Training) => &p.0,
            (Some(p), Part::HeldOut) => &p.1,
            _ => &v.whole,
        },
    }
}

/// The pick among `fitted` (ranked by criterion): the best, unless it is a pair whose second
/// parameter does not pay for itself on the held-out data (`judge`), then its best nested
/// single cause.
fn pick(fitted: &[Fitted], judge: &dyn Fn(usize) -> Statistic, held: bool) -> usize {
    let nested = fitted[0].family.nested();
    if nested.is_empty() {
        return 0;
    }
    // a second cause below its physical floor is not named ([`below_floor`])
    let p = &fitted[0].params;
    let tiny = |f: Family| below_floor(f, p);
    let (d, a, c) = (Family::Delay, Family::Average, Family::Clock);
    let keep = match fitted[0].family {
        Family::DelayAverage if tiny(d) => Some(a),
        Family::DelayAverage if tiny(a) => Some(d),
        Family::DelayClock if tiny(d) => Some(c),
        Family::DelayClock if tiny(c) => Some(d),
        Family::AverageClock if tiny(a) => Some(c),
        Family::AverageClock if tiny(c) => Some(a),
        _ => None,
    };
    if let Some(i) = keep.and_then(|k| fitted.iter().position(|f| f.family == k)) {
        return i;
    }
    // on the held-out data the pair's extra parameter must pay ½ ln K' like in the criterion
    let sum = |s: Statistic| penalised(&s, 0);
    let me = judge(0);
    let pen = penalised(&me, 1) - sum(me);
    let better = (0..fitted.len())
        .filter(|&i| nested.contains(&fitted[i].family))
        .min_by(|x, y| sum(judge(*x)).total_cmp(&sum(judge(*y))));
    match better {
        // without held-out data the pair must win the likelihood-ratio test outright
        Some(i) if !held && !decisive(&fitted[0], &fitted[i]) => i,
        Some(i) if sum(me) + pen >= sum(judge(i)) && !decisive(&fitted[0], &fitted[i]) => i,
        _ => 0,
    }
}

/// Whether the single cause `f` of parameters `p` is below its physical floor: a hold delay
/// under 1 % of a period, a window under 2 %, clock errors all under 0.02 %. Such a parameter
/// absorbs estimator bias, not an effect. In particular a delayed hold or an averaging sampler
/// of any width `> 0` makes the sample see the previous input through a feedthrough (`D u_k`
/// becomes `D u_{k−1}`), so a vanishing delay or window can buy a fitted model's spurious
/// feedthrough a better fit: the limit `α → 0⁺` is not the plain model.
fn below_floor(f: Family, p: &RateTied) -> bool {
    match f {
        Family::Delay => p.hold_delay < 0.01,
        Family::Average => p.averaging < 0.02,
        Family::Clock => p.clock_error.iter().all(|e| e.abs() < 2e-4),
        _ => false,
    }
}

/// Whether family `fam` with parameters `p` may be named at all: a rate-tied family none of
/// whose causes is below its physical floor ([`below_floor`]).
fn nameable(fam: Family, p: &RateTied) -> bool {
    fam != Family::None
        && !(fam.delay() && below_floor(Family::Delay, p))
        && !(fam.average() && below_floor(Family::Average, p))
        && !(fam.clock() && below_floor(Family::Clock, p))
}

/// Whether another hypothesis, sharing no cause with the chosen one (`k`), explains the data as
/// well: it passes the naming threshold too (`judge`), and neither the training data nor the
/// judged (held-out) data put the chosen one's score sum lower by [`PAIR_DECISIVE`]. Then the
/// data do not tell the causes apart (a small hold delay and a short averaging window lag the
/// phase alike), and naming either would be a guess.
fn ambiguous(fitted: &[Fitted], k: usize, judge: &dyn Fn(usize) -> Statistic, alpha: f64) -> bool {
    let chosen = fitted[k].family;
    let related =
        |f: Family| f == chosen || chosen.nested().contains(&f) || f.nested().contains(&chosen);
    let sum = |s: Statistic| penalised(&s, 0);
    let mine = sum(judge(k));
    fitted.iter().enumerate().any(|(i, f)| {
        f.family != Family::None
            && !related(f.family)
            && explains(&judge(i), alpha)
            && !decisive(f, &fitted[k])
            && sum(judge(i)) - mine < PAIR_DECISIVE
    })
}

/// Score-sum advantage on the training data beyond which a pair is kept against its nested
/// single cause even when the held-out part cannot tell them apart: the likelihood-ratio test of
/// one extra parameter (twice the score-sum difference is χ²₁ under the single cause) at a
/// false-alarm probability below 1e-5 (χ²₁ quantile 19.5, halved, and doubled for safety).
const PAIR_DECISIVE: f64 = 19.5;

/// Whether the training data decide for the pair `pair` against the single `single`: its
/// score sum lower by [`PAIR_DECISIVE`] or more. Later periods of the same experiment share the
/// model's compensation of a wrong single cause (the residues absorb it at the same lines), so
/// they may not separate the two; the training data, with the pair's extra parameter paid for by
/// the test's level, can.
fn decisive(pair: &Fitted, single: &Fitted) -> bool {
    penalised(&single.stat, 0) - penalised(&pair.stat, 0) >= PAIR_DECISIVE
}

/// Naming's false-rejection probability relative to the verdict's α: an extension is named when
/// its held-out statistic stays below the `1 − α/10` quantile (a right extension is refused
/// one time in a thousand at α = 1 %; wrong names are kept out by the competition between the
/// hypotheses and the pair rule, not by this threshold).
const NAMING_ALPHA_RATIO: f64 = 0.1;

fn explains(s: &Statistic, alpha: f64) -> bool {
    s.value <= crate::stats::threshold(s.effective_lines, alpha * NAMING_ALPHA_RATIO)
}

/// What the validation of the rate-tied hypotheses settled on.
struct Settled {
    family: Family,
    /// Parameters from the training data (the start of the final refit).
    params: RateTied,
    named: bool,
    /// Not named because two unrelated causes explain the data alike ([`ambiguous`]): a
    /// rate-tied effect is there, so the model is not to blame.
    ambiguous: bool,
    ranking: Vec<Ranked>,
    partial: Ranked,
    gain: Gain,
}

/// The rate-tied search and its validation (leave one experiment out with two or more
/// same-level slower experiments, else earlier/later periods), then the named extension
/// refitted on all data. The flag says the answer is `unexplained` only because two rate-tied
/// causes explain the data alike.
fn rate_tied(
    data: &Data<'_>,
    j: &Judged<'_>,
    progress: &mut dyn FnMut(&str),
) -> Result<(Outcome, bool)> {
    let tied: Vec<&Val<'_>> = data.vals.iter().filter(|v| v.rate_tied()).collect();
    let s = if tied.len() >= 2 {
        leave_one_out(j, &tied, progress)?
    } else {
        halves(j, &tied, progress)?
    };
    if !s.named {
        let gain = if s.ambiguous {
            Gain::none(
                "two unrelated rate-tied causes explain the data alike (see `partial` and the \
                 ranking): none is named, so no extension is measured",
            )
        } else {
            s.gain
        };
        return Ok((
            Outcome {
                verdict: Verdict::Discrepancy,
                causes: vec![Cause::Unexplained],
                extension: Extension::None,
                partial: Some(s.partial),
                ranking: s.ranking,
                gain,
                models: BTreeMap::new(),
                held: BTreeMap::new(),
            },
            s.ambiguous,
        ));
    }
    progress("refitting the chosen extension on all data");
    let all: Vec<Target<'_>> = tied.iter().map(|v| target(v, Part::Whole)).collect();
    let params = j.modal.refine(s.family, &all, &s.params)?;
    let std = j.modal.std_errors(s.family, &all, &params)?;
    let names: Vec<String> = tied.iter().map(|v| v.exp.spec.name.clone()).collect();
    Ok((
        Outcome {
            verdict: Verdict::Discrepancy,
            causes: causes_of(s.family, (&params, &std), &names, data),
            extension: Extension::RateTied(params),
            ranking: s.ranking,
            partial: None,
            gain: s.gain,
            models: BTreeMap::new(),
            held: BTreeMap::new(),
        },
        false,
    ))
}

/// One same-level slower experiment: family and parameters on its earlier periods, judged on
/// its later ones; then the chosen family refitted on the later periods and judged on the
/// earlier ones (each part held out once; the family is chosen on the earlier ones only).
fn halves(j: &Judged<'_>, tied: &[&Val<'_>], progress: &mut dyn FnMut(&str)) -> Result<Settled> {
    let split = tied.iter().all(|v| v.parts.is_some());
    let part = if split { Part::Training } else { Part::Whole };
    let train: Vec<Target<'_>> = tied.iter().map(|v| target(v, part)).collect();
    let fitted = j.modal.search(&train, progress)?;
    let held: Option<Vec<Target<'_>>> =
        split.then(|| tied.iter().map(|v| target(v, Part::HeldOut)).collect());
    let held_stats: Vec<Option<Statistic>> = fitted
        .iter()
        .map(|f| {
            // hypotheses are compared with the residue covariance only: a hypothesis under
            // which a pole is ill-determined must not win by the width of its prediction
            held.as_ref()
                .map(|h| j.modal.stat(&f.params, h))
                .transpose()
        })
        .collect::<Result<_>>()?;
    let ranking: Vec<Ranked> = fitted
        .iter()
        .zip(&held_stats)
        .map(|(f, h)| ranked(f, h.map(|s| s.value)))
        .collect();
    let judge = |i: usize| held_stats[i].unwrap_or(fitted[i].stat);
    let k = pick(&fitted, &judge, held.is_some());
    let unsure = ambiguous(&fitted, k, &judge, j.modal.alpha);
    let chosen = &fitted[k];
    let Some(held) = held else {
        // without held-out data the discrepancy must stand at the naming level itself, on the
        // naming yardstick (residue and pole covariance)
        let would = nameable(chosen.family, &chosen.params)
            && explains(&j.modal.stat_full(&chosen.params, &train)?, j.modal.alpha)
            && !explains(
                &j.modal.stat_full(&RateTied::default(), &train)?,
                j.modal.alpha,
            );
        return Ok(Settled {
            family: chosen.family,
            params: chosen.params.clone(),
            named: would && !unsure,
            ambiguous: would && unsure,
            partial: ranked(chosen, None),
            ranking,
            gain: Gain::none(
                "the validation experiment has fewer than four steady periods (or too short a \
                 record) to hold part of it out: the cause was chosen and judged on all of its \
                 data",
            ),
        });
    };
    // the second fold: the chosen family refitted on the later part, judged on the earlier
    progress("cross-check: the chosen extension fitted on the later part");
    let alpha = j.modal.alpha;
    let second = j.modal.refine(chosen.family, &held, &chosen.params)?;
    let after = j
        .modal
        .stat_full(&chosen.params, &held)?
        .pool(&j.modal.stat_full(&second, &train)?, alpha);
    let none = RateTied::default();
    let before = j
        .modal
        .stat_full(&none, &held)?
        .pool(&j.modal.stat_full(&none, &train)?, alpha);
    let mut labels: Vec<String> = tied.iter().map(|v| held_out_label(v.exp)).collect();
    labels.extend(tied.iter().map(|v| earlier_label(v.exp)));
    // the discrepancy must replicate on the held-out data, and the extension explain it
    let would =
        nameable(chosen.family, &chosen.params) && !before.passes() && explains(&after, alpha);
    Ok(Settled {
        family: chosen.family,
        params: chosen.params.clone(),
        named: would && !unsure,
        ambiguous: would && unsure,
        partial: ranked(chosen, Some(after.value)),
        ranking,
        gain: Gain::measured(before.value, after.value, labels),
    })
}

/// The lines of held-out experiment `v` under an extension fitted without it: on the whole
/// experiment, or — when the extension has clock errors, which belong to each experiment —
/// its clock error fitted on the earlier periods and the lines of the later ones.
fn held_out_lines(j: &Judged<'_>, f: &Fitted, v: &Val<'_>, full: bool) -> Result<Vec<Line>> {
    if !f.family.clock() {
        return j
            .modal
            .lines_for(&f.params, 0.0, &target(v, Part::Whole), full);
    }
    let Some((a, b)) = &v.parts else {
        return Ok(Vec::new());
    };
    let (ta, tb) = (
        Target {
            factor: v.factor,
            est: a,
        },
        Target {
            factor: v.factor,
            est: b,
        },
    );
    let e = j.modal.clock_of(&f.params, &ta)?;
    j.modal.lines_for(&f.params, e, &tb, full)
}

/// Two or more same-level slower experiments: each left out in turn, the family and
/// parameters chosen on the others; named only when every fold picks the same family and the
/// left-out experiments together pass the threshold.
fn leave_one_out(
    j: &Judged<'_>,
    tied: &[&Val<'_>],
    progress: &mut dyn FnMut(&str),
) -> Result<Settled> {
    let mut picks: Vec<Family> = Vec::new();
    let (mut before, mut after) = (Vec::new(), Vec::new());
    let mut ranking = Vec::new();
    let mut first: Option<Fitted> = None;
    // the folds are independent: their hypothesis searches run side by side
    progress(&format!(
        "leaving each of {} out in turn (the folds in parallel)",
        tied.iter()
            .map(|v| format!("`{}`", v.exp.spec.name))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    let trains: Vec<Vec<Target<'_>>> = (0..tied.len())
        .map(|k| {
            tied.iter()
                .enumerate()
                .filter(|(i, _)| *i != k)
                .map(|(_, w)| target(w, Part::Whole))
                .collect()
        })
        .collect();
    let modal = &j.modal;
    let searched: Vec<Result<Vec<Fitted>>> = {
        use rayon::prelude::*;
        trains
            .par_iter()
            .map(|train| modal.search(train, &mut |_| {}))
            .collect()
    };
    for ((k, v), fitted) in tied.iter().enumerate().zip(searched) {
        let fitted = fitted?;
        let held = fitted
            .iter()
            .map(|f| held_out_lines(j, f, v, false))
            .collect::<Result<Vec<_>>>()?;
        let c = v.whole.inflation;
        let stat_of = |i: usize| statistic([(held[i].as_slice(), c)], j.modal.alpha);
        let p = pick(&fitted, &stat_of, true);
        if k == 0 {
            ranking = fitted
                .iter()
                .enumerate()
                .map(|(i, f)| ranked(f, Some(stat_of(i).value)))
                .collect();
            first = Some(fitted[p].clone());
        }
        picks.push(fitted[p].family);
        let none_idx = fitted
            .iter()
            .position(|f| f.family == Family::None)
            .unwrap_or(p);
        before.push((held_out_lines(j, &fitted[none_idx], v, true)?, c));
        after.push((held_out_lines(j, &fitted[p], v, true)?, c));
    }
    let pooled = |sets: &[(Vec<Line>, f64)]| {
        statistic(sets.iter().map(|(l, c)| (l.as_slice(), *c)), j.modal.alpha)
    };
    let (b, a) = (pooled(&before), pooled(&after));
    let first = first.ok_or_else(|| DiagnoseError::Numerical("no fold".into()))?;
    let same = picks.iter().all(|f| *f == first.family);
    Ok(Settled {
        family: first.family,
        params: first.params.clone(),
        named: same
            && nameable(first.family, &first.params)
            && !b.passes()
            && explains(&a, j.modal.alpha),
        ambiguous: false,
        partial: ranked(&first, Some(a.value)),
        ranking,
        gain: Gain::measured(
            b.value,
            a.value,
            tied.iter()
                .map(|v| format!("{} (whole experiment, left out)", v.exp.spec.name))
                .collect(),
        ),
    })
}

/// The named causes of a family with its parameters and their standard errors.
fn causes_of(
    fam: Family,
    (p, std): (&RateTied, &StdErrors),
    names: &[String],
    data: &Data<'_>,
) -> Vec<Cause> {
    let mut out = Vec::new();
    if fam.average() {
        out.push(Cause::AveragingSampler {
            window_frac: p.averaging,
            window_frac_std: std.averaging,
        });
    }
    if fam.clock() {
        out.push(Cause::ClockError {
            clock_error: names
                .iter()
                .cloned()
                .zip(p.clock_error.iter().copied())
                .collect(),
            clock_error_std: names
                .iter()
                .zip(&std.clock_error)
                .filter_map(|(n, s)| Some((n.clone(), (*s)?)))
                .collect(),
        });
    }
    if fam.delay() {
        let mut delay_s = BTreeMap::new();
        delay_s.insert(data.model_exp.spec.name.clone(), p.hold_delay * data.h);
        for v in &data.vals {
            delay_s.insert(
                v.exp.spec.name.clone(),
                p.hold_delay / v.exp.spec.sample_rate_hz,
            );
        }
        let both = fam.average();
        out.push(Cause::HoldDelay {
            delay_frac: p.hold_delay,
            delay_frac_std: std.hold_delay,
            delay_s,
            combined_lag_frac: both.then_some(p.hold_delay + 0.5 * p.averaging),
            combined_lag_frac_std: std.combined_lag,
        });
    }
    out
}

/// Mean score of a model on the model experiment's own lines (no prediction variance).
fn own_statistic(m: &StateSpace, fast: &Estimate, alpha: f64) -> Result<f64> {
    Ok(crate::model::own_statistic(m, fast, alpha)?.value)
}

/// Stage 2: the model (given, or fitted and then its residues refitted on the continuous
/// modal basis of its poles, kept when it fits its data as well: the basis drops poles
/// without a continuous counterpart), its source, and that basis.
fn judged_model(
    data: &Data<'_>,
    opt: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<(StateSpace, String, ModalBasis)> {
    let parts = if opt.model.is_none() {
        progress("FRFs of the model experiment's earlier and later periods");
        parts(data.model_exp, &data.fast)
    } else {
        None
    };
    let (fitted, mut source) =
        crate::model::model_for(&data.fast, parts.as_ref(), data.h, opt, progress)?;
    let basis = ModalBasis::from_model(&fitted)?;
    if opt.model.is_some() {
        return Ok((fitted, source, basis));
    }
    let phi = basis.responses(data.h, NonIdeal::ideal(), data.fast.frd.freq_hz())?;
    let res = Residues::fit(&data.fast.frd, &phi)?;
    let refit = basis.model(&res.r, data.h, NonIdeal::ideal())?;
    let own = |m: &StateSpace| own_statistic(m, &data.fast, opt.alpha);
    if own(&refit)? <= own(&fitted)? * 1.02 {
        source.push_str("; residues refitted on the continuous modal basis");
        return Ok((refit, source, basis));
    }
    Ok((fitted, source, basis))
}

/// The model with its modal form and prediction covariance: residues and poles, for a fitted
/// model scaled by its misfit on its own data when above 1 (the residual-variance factor of
/// least squares: unmodelled detail widens its prediction).
fn judge_model<'a>(
    data: &'a Data<'_>,
    opt: &DiagnoseOptions,
    model: StateSpace,
    source: String,
    basis: ModalBasis,
) -> Result<Judged<'a>> {
    let given = opt.model.is_some();
    let modal = Modal {
        basis,
        fast: &data.fast,
        h: data.h,
        alpha: opt.alpha,
    };
    let mut plain = modal.residues_full(NonIdeal::ideal())?;
    if !given {
        plain = plain.scaled(own_statistic(&model, &data.fast, opt.alpha)?.max(1.0));
    }
    Ok(Judged {
        info: ModelInfo {
            source,
            order: model.n(),
            ts: model.ts(),
            own_data: None,
            own_fit: None,
        },
        given,
        model,
        modal,
        plain,
    })
}

/// How far the model is from its own experiment, and whether that excess is noise,
/// distortion (the non-excited lines) or fit error.
fn own_fit(data: &Data<'_>, ch: &Checks, info: &mut ModelInfo) {
    let own = statistic(
        [(ch.fast_model.as_slice(), data.fast.inflation)],
        ch.alpha_test,
    );
    let distorted = data.fast.distortion.as_ref().is_some_and(|d| {
        distortion_evidence(&data.model_exp.spec.name, d, ch.alpha_test)
            .iter()
            .any(|e| !e.passed)
    });
    info.own_fit = Some(if own.passes() {
        OwnFit::Noise
    } else if distorted {
        OwnFit::Distortion
    } else {
        OwnFit::FitError
    });
    info.own_data = Some(own);
}

/// [`diagnose_with_progress`] without progress messages.
///
/// # Errors
/// As [`diagnose_with_progress`].
pub fn diagnose(experiments: &[Experiment], opt: &DiagnoseOptions) -> Result<Diagnosis> {
    diagnose_with_progress(experiments, opt, &mut |_| {})
}

/// Diagnoses the model experiment's model against the validation experiments (crate
/// documentation), reporting each step to `progress`.
///
/// # Errors
/// Fewer than two experiments, an experiment with several inputs or outputs, rates that are
/// not whole fractions of the model experiment's, experiments without enough periods for
/// variances, a given model that is not SISO or not at
/// the model experiment's rate, a model that cannot be fitted, `alpha` outside (0, 0.5].
pub fn diagnose_with_progress(
    experiments: &[Experiment],
    opt: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<Diagnosis> {
    crate::stats::check_alpha(opt.alpha)?;
    if let Some(e) = experiments.iter().find(|e| e.spec.is_mimo()) {
        return Err(DiagnoseError::Setup(format!(
            "experiment `{}` has {} inputs and {} outputs: this diagnosis takes SISO \
             experiments (one input column, one output column); diagnose_mimo (what `sdctl \
             diagnose` runs on such a manifest) takes MIMO ones",
            e.spec.name,
            e.spec.inputs().len(),
            e.spec.outputs().len()
        )));
    }
    for e in experiments {
        if let Some(w) = sd_ident::feedback_only(&e.u, &e.y)? {
            return Err(DiagnoseError::Setup(format!(
                "experiment `{}`: {w}; leave it out of the manifest",
                e.spec.name
            )));
        }
    }
    let cut = crate::pieces::cut_records(experiments);
    let (experiments, pieces) = match &cut {
        Some((exps, pieces)) => {
            progress(&format!(
                "{} record(s) of changing amplitude cut into {} pieces",
                pieces
                    .iter()
                    .map(|p| &p.record)
                    .collect::<std::collections::BTreeSet<_>>()
                    .len(),
                pieces.len()
            ));
            (exps.as_slice(), pieces.clone())
        }
        None => (experiments, Vec::new()),
    };
    let mut data = Data::read(experiments, progress)?;
    let (model, source, basis) = judged_model(&data, opt, progress)?;
    for v in &mut data.vals {
        v.model = if v.factor == 1 {
            model.clone()
        } else {
            downsample(&model, v.factor)?
        };
    }
    let mut judged = judge_model(&data, opt, model, source, basis)?;
    let mut ch = checks(&data, &judged, opt.alpha)?;
    data.widen_levels(&level_tests(&data, &ch));
    own_fit(&data, &ch, &mut judged.info);
    let outcome = decide(&data, &judged, &mut ch, progress)?;
    progress("reports");
    let tied = match &outcome.extension {
        Extension::RateTied(p) => Some((judged.modal.residues(p.nonideal())?, p)),
        _ => None,
    };
    let mut experiments = reports(
        &data,
        &judged,
        &ch,
        (&outcome.extension, &outcome.models),
        tied.as_ref(),
    )?;
    let extended_model = extended_continuous(&judged, tied.as_ref())?;
    for x in &mut experiments {
        x.held_out = outcome.held.get(&x.name).copied();
    }
    Ok(Diagnosis {
        verdict: outcome.verdict,
        cause: joined(&outcome.causes),
        parameters: merged_parameters(&outcome.causes),
        causes: outcome.causes,
        partial: outcome.partial,
        alpha: opt.alpha,
        evidence: ch.evidence,
        ranking: outcome.ranking,
        gain: outcome.gain,
        extension: outcome.extension,
        model: judged.model,
        model_info: judged.info,
        experiments,
        pieces,
        extended_model,
    })
}

/// The extended model of an experiment slower by `factor` with clock error `e`, labelled
/// with its nominal period (its responses on the nominal frequency axis).
fn extended_model(
    j: &Judged<'_>,
    res: &Residues,
    p: &RateTied,
    factor: usize,
    e: f64,
) -> Result<StateSpace> {
    let ts = j.modal.h * factor as f64;
    let m = j.modal.basis.model(&res.r, ts * (1.0 + e), p.nonideal())?;
    Ok(StateSpace::new(
        m.a().clone(),
        m.b().clone(),
        m.c().clone(),
        m.d().clone(),
        SampleTime::discrete(ts)?,
    )?)
}

/// Stage 6: the findings of every experiment.
fn reports(
    data: &Data<'_>,
    j: &Judged<'_>,
    ch: &Checks,
    (ext, models): (&Extension, &BTreeMap<String, StateSpace>),
    res: Option<&(Residues, &RateTied)>,
) -> Result<Vec<ExperimentReport>> {
    let tied: Vec<&str> = data
        .vals
        .iter()
        .filter(|v| v.rate_tied())
        .map(|v| v.exp.spec.name.as_str())
        .collect();
    let clock_of = |name: &str| -> f64 {
        match res {
            Some((_, p)) => tied
                .iter()
                .position(|n| *n == name)
                .map(|k| p.clock(k))
                .unwrap_or(0.0),
            None => 0.0,
        }
    };
    let mut out = Vec::with_capacity(1 + data.vals.len());
    let ctx = ReportCtx {
        alpha: ch.alpha_test,
        data,
        j,
        ext,
    };
    let em = |factor: usize, name: &str| -> Result<Option<StateSpace>> {
        if let Some(m) = models.get(name) {
            return Ok(Some(m.clone()));
        }
        res.map(|(r, p)| extended_model(j, r, p, factor, clock_of(name)))
            .transpose()
    };
    out.push(ctx.report(
        data.model_exp,
        &data.fast,
        1,
        ch.fast_model.clone(),
        &j.model,
        None,
        em(1, &data.model_exp.spec.name)?,
        1.0,
    )?);
    for (i, v) in data.vals.iter().enumerate() {
        let c = v.whole.inflation.max(data.fast.inflation);
        out.push(ctx.report(
            v.exp,
            &v.whole,
            v.factor,
            ch.model[i].clone(),
            &v.model,
            Some(statistic([(ch.free[i].as_slice(), c)], ch.alpha_test)),
            em(v.factor, &v.exp.spec.name)?,
            v.level,
        )?);
    }
    Ok(out)
}

struct ReportCtx<'a, 'b> {
    alpha: f64,
    data: &'a Data<'b>,
    j: &'a Judged<'b>,
    ext: &'a Extension,
}

impl ReportCtx<'_, '_> {
    #[allow(clippy::too_many_arguments)]
    fn report(
        &self,
        e: &Experiment,
        est: &Estimate,
        factor: usize,
        lines: Vec<Line>,
        model_at: &StateSpace,
        free: Option<Statistic>,
        em: Option<StateSpace>,
        level: f64,
    ) -> Result<ExperimentReport> {
        let p = self.data.pair(factor);
        let alpha = self.alpha;
        let freq: Vec<f64> = lines.iter().map(|l| l.f).collect();
        let extended: Option<Vec<C>> = match (&em, self.ext) {
            (Some(m), _) => Some(responses(m, &freq)?),
            (None, Extension::FastFrf) => Some(
                lines
                    .iter()
                    .map(|l| p.predict(l.f).map(|x| x.value).unwrap_or(l.pred))
                    .collect(),
            ),
            _ => None,
        };
        // the extension judged with the model's yardstick
        let extended_stat = match (&em, self.ext) {
            (Some(m), _) => Some(self.j.lines(m, factor, est)?),
            (None, Extension::FastFrf) if factor > 1 => Some(free_lines(&p, est)),
            _ => None,
        }
        .map(|l| statistic([(l.as_slice(), est.inflation)], alpha));
        let found = bands(&lines, |f| dominant_fold(&self.j.model, &p, f));
        let ext_fn = |bins: &[f64]| -> Result<Vec<C>> {
            match &em {
                Some(m) => responses(m, bins),
                None => {
                    let base = responses(model_at, bins)?;
                    Ok(bins
                        .iter()
                        .zip(base)
                        .map(|(&f, b)| {
                            if found.iter().any(|x| f >= x.f_lo && f <= x.f_hi) {
                                p.predict(f).map(|x| x.value).unwrap_or(b)
                            } else {
                                b
                            }
                        })
                        .collect())
                }
            }
        };
        let td = time_domain(
            e,
            model_at,
            extended
                .as_ref()
                .map(|_| &ext_fn as &crate::findings::ResponseFn<'_>),
            em.as_ref(),
            &found,
        )?;
        Ok(ExperimentReport {
            name: e.spec.name.clone(),
            role: if std::ptr::eq(e, self.data.model_exp) {
                Role::Model
            } else {
                Role::Validation
            },
            rate_hz: e.spec.sample_rate_hz,
            factor,
            relative_level: level,
            model_free: free,
            model_stat: statistic([(lines.as_slice(), est.inflation)], alpha),
            extended_stat,
            bands: found,
            curves: Curves {
                freq_hz: freq,
                measured: lines.iter().map(|l| l.meas).collect(),
                noise_var: lines.iter().map(|l| l.var).collect(),
                model: lines.iter().map(|l| l.pred).collect(),
                extended,
            },
            time_domain: td,
            distortion: est.distortion.clone(),
            held_out: None,
            extended_model: em,
        })
    }
}

/// The rate-tied extension (its residues and parameters) as a continuous model with its hold
/// delay and averaging window (`None` for any other extension).
fn extended_continuous(
    j: &Judged<'_>,
    tied: Option<&(Residues, &RateTied)>,
) -> Result<Option<ExtendedModel>> {
    let Some((res, p)) = tied else {
        return Ok(None);
    };
    Ok(Some(ExtendedModel {
        continuous: j.modal.basis.continuous(&res.r)?,
        hold_delay: p.hold_delay,
        averaging: p.averaging,
    }))
}
