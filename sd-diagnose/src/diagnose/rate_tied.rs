//! Stage 5b: the rate-tied hypotheses — search, pick, validation on held-out periods or
//! experiments, and the named causes.

use super::decide::*;
use super::judged::*;
use super::read::*;
use crate::data::{earlier_label, held_out_label, Part};
use crate::hypotheses::{penalised, Family, Fitted, StdErrors, Target};
use crate::stats::{statistic, Line, Statistic};
use crate::{Cause, DiagnoseError, Extension, Gain, Ranked, RateTied, Result, Verdict};
use std::collections::BTreeMap;

pub(super) fn ranked(f: &Fitted, held: Option<f64>) -> Ranked {
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

pub(super) fn target<'v>(v: &'v Val<'_>, part: Part) -> Target<'v> {
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
pub(super) fn pick(fitted: &[Fitted], judge: &dyn Fn(usize) -> Statistic, held: bool) -> usize {
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
    let pen = param_cost(&me);
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

/// What one more parameter costs on the judged data `s`: the criterion's `½ ln K'`.
fn param_cost(s: &Statistic) -> f64 {
    penalised(s, 1) - penalised(s, 0)
}

/// Whether the single cause `f` of parameters `p` is below its physical floor: a hold delay
/// under 1 % of a period, a window under 2 %, clock errors all under 0.02 %. Such a parameter
/// absorbs estimator bias, not an effect. In particular a delayed hold or an averaging sampler
/// of any width `> 0` makes the sample see the previous input through a feedthrough (`D u_k`
/// becomes `D u_{k−1}`), so a vanishing delay or window can buy a fitted model's spurious
/// feedthrough a better fit: the limit `α → 0⁺` is not the plain model.
pub(super) fn below_floor(f: Family, p: &RateTied) -> bool {
    match f {
        Family::Delay => p.hold_delay < 0.01,
        Family::Average => p.averaging < 0.02,
        Family::Clock => p.clock_error.iter().all(|e| e.abs() < 2e-4),
        _ => false,
    }
}

/// Whether every cause of a hypothesis fitted to `targets` is told from zero, so that it may
/// compete for the name: a pair's hold delay and window each beyond `z·σ`, and of clock errors
/// at least one, `σ` the parameter's standard error ([`Modal::std_errors`]) and `z` the
/// two-sided normal quantile of the naming level `α·`[`NAMING_ALPHA_RATIO`] shared out over
/// the tests (Bonferroni: `c` causes, a clock cause counting once per experiment; `z =
/// Φ⁻¹(1 − α/(20 c))`, 3.48 for a pair at α = 1 %). A single delay or window is told by the
/// comparison with `none`. A clock error per experiment is a free parameter each: with a small
/// delay or window mis-fitted one of them takes up 2–3 σ of misfit and buys a pair its place;
/// and a pair's split of a lag into delay and window can be undetermined (standard errors of
/// hundreds on a lag of 1.4 periods) while the pair still fits an estimator bias better than
/// the delay alone. For scale (`SEED=3500 cargo test --release -p sd-tests --test
/// diagnose_next debug -- --ignored --nocapture`): about 2.6·10⁻⁴ for a clock error on 1 kHz
/// data, so a clock error of 0.2 % stands beyond 7 σ; 0.016 for a 0.21-period window beside
/// a delay, 13 σ.
///
/// [`Modal::std_errors`]: crate::hypotheses::Modal::std_errors
pub(super) fn causes_told(j: &Judged<'_>, f: &Fitted, targets: &[Target<'_>]) -> Result<bool> {
    let fam = f.family;
    if !fam.clock() && fam.nested().is_empty() {
        return Ok(true);
    }
    let std = j.modal.std_errors(fam, targets, &f.params)?;
    let m = f.params.clock_error.len().max(1);
    let tests =
        usize::from(fam.delay()) + usize::from(fam.average()) + m * usize::from(fam.clock());
    let z =
        sd_model::normal_quantile(1.0 - j.modal.alpha * NAMING_ALPHA_RATIO / (2.0 * tests as f64));
    let beyond = |e: f64, s: Option<f64>| s.is_some_and(|s| e.abs() > z * s);
    let p = &f.params;
    Ok((!fam.delay() || beyond(p.hold_delay, std.hold_delay))
        && (!fam.average() || beyond(p.averaging, std.averaging))
        && (!fam.clock()
            || (p.clock_error.iter())
                .zip(&std.clock_error)
                .any(|(e, s)| beyond(*e, *s))))
}

/// The hypotheses that compete for the name (those of [`causes_told`]) with their judged
/// statistics; `fitted` stays whole for the ranking the report shows.
fn told(
    j: &Judged<'_>,
    fitted: &[Fitted],
    stats: &[Option<Statistic>],
    targets: &[Target<'_>],
) -> Result<(Vec<Fitted>, Vec<Option<Statistic>>)> {
    let mut out = (Vec::new(), Vec::new());
    for (f, s) in fitted.iter().zip(stats) {
        if causes_told(j, f, targets)? {
            out.0.push(f.clone());
            out.1.push(*s);
        }
    }
    Ok(out)
}

/// Whether family `fam` with parameters `p` may be named at all: a rate-tied family none of
/// whose causes is below its physical floor ([`below_floor`]).
pub(super) fn nameable(fam: Family, p: &RateTied) -> bool {
    fam != Family::None
        && !(fam.delay() && below_floor(Family::Delay, p))
        && !(fam.average() && below_floor(Family::Average, p))
        && !(fam.clock() && below_floor(Family::Clock, p))
}

/// The other hypotheses, sharing no cause with the chosen one (`k`), that explain the data as
/// well: each passes the naming threshold too (`judge`), neither the training data nor the
/// judged (held-out) data put the chosen one's score sum lower by [`PAIR_DECISIVE`], and the
/// training data do not put theirs lower by as much either. With any,
/// the data do not tell the causes apart (a small hold delay and a short averaging window lag
/// the phase alike), and naming either would be a guess.
pub(super) fn rivals(
    fitted: &[Fitted],
    k: usize,
    judge: &dyn Fn(usize) -> Statistic,
    alpha: f64,
) -> Vec<usize> {
    let chosen = fitted[k].family;
    let related =
        |f: Family| f == chosen || chosen.nested().contains(&f) || f.nested().contains(&chosen);
    let sum = |s: Statistic| penalised(&s, 0);
    let mine = sum(judge(k));
    (0..fitted.len())
        .filter(|&i| {
            let f = &fitted[i];
            f.family != Family::None
                && !related(f.family)
                && explains(&judge(i), alpha)
                && !decisive(f, &fitted[k])
                && !decisive(&fitted[k], f)
                && sum(judge(i)) - mine < PAIR_DECISIVE
        })
        .collect()
}

/// The pairs among `all` (every hypothesis, by criterion, also those whose causes are not
/// told from zero, [`causes_told`]) not yet in `others` whose presence the data leave
/// undetermined against the single cause `chosen` nested in them: a pair the criterion ranks
/// above `chosen` (passed over by [`pick`] because its second cause did not pay for itself on
/// the judged data, or not told from zero), unless
/// the judged data reject it (score sum higher than `k`'s by more than its `½ ln K'`: the
/// training data's gain was their own, e.g. an estimator bias, and `k` is named); and a pair
/// whose second cause pays for itself on the judged data (score sum lower by more than its
/// `½ ln K'`) where the criterion preferred `k`. Training and judged data then disagree about
/// the second cause (a small delay with a window lags the phase like a larger delay alone at
/// one slow rate), and naming the single cause would be a guess. Not for a pair that
/// may not be named ([`nameable`]: a second cause below its floor is no cause) or does not
/// explain the judged data, nor for one with clock errors (a free parameter per experiment
/// that is not told from zero takes up misfit, not a cause).
fn with_undetermined_pairs(
    all: &[Fitted],
    chosen: Family,
    others: &[Family],
    judge: &dyn Fn(usize) -> Statistic,
    alpha: f64,
) -> Vec<Fitted> {
    let Some(k) = all.iter().position(|f| f.family == chosen) else {
        return Vec::new();
    };
    let sum = |s: Statistic| penalised(&s, 0);
    let mine = judge(k);
    let pen = param_cost(&mine);
    let mut out = Vec::new();
    for (i, f) in all.iter().enumerate() {
        // a pair the criterion prefers, unless the judged data reject its second cause
        // (worse by more than it costs); or a pair the judged data want
        let gain = sum(mine) - sum(judge(i));
        let undetermined = if f.criterion < all[k].criterion {
            gain > -pen
        } else {
            gain > pen
        };
        if undetermined
            && !f.family.clock()
            && f.family.nested().contains(&chosen)
            && nameable(f.family, &f.params)
            && explains(&judge(i), alpha)
            && !others.contains(&f.family)
        {
            out.push(f.clone());
        }
    }
    out
}

/// The one cause that the chosen pair `k` and every rival pair contain, when it alone explains
/// the data (the naming threshold on the judged data) and may be named: the data demand that
/// cause and cannot tell the second causes apart (a hold delay with an averaging window and
/// the same hold delay with a clock error fit alike), so the shared cause is the answer, not
/// `unexplained`. `None` when `k` is no pair, a rival is no pair, or the pairs share no cause.
pub(super) fn shared_cause(
    fitted: &[Fitted],
    k: usize,
    others: &[usize],
    judge: &dyn Fn(usize) -> Statistic,
    alpha: f64,
) -> Option<usize> {
    if others.is_empty() {
        return None;
    }
    let mut shared = fitted[k].family.nested();
    for &o in others {
        let n = fitted[o].family.nested();
        shared.retain(|f| n.contains(f));
    }
    let [cause] = shared.as_slice() else {
        return None;
    };
    let s = fitted.iter().position(|f| f.family == *cause)?;
    (explains(&judge(s), alpha) && nameable(*cause, &fitted[s].params)).then_some(s)
}

/// Score-sum advantage on the training data beyond which a pair is kept against its nested
/// single cause even when the held-out part cannot tell them apart: the likelihood-ratio test of
/// one extra parameter (twice the score-sum difference is χ²₁ under the single cause) at a
/// false-alarm probability below 1e-5 (χ²₁ quantile 19.5, halved, and doubled for safety).
pub(super) const PAIR_DECISIVE: f64 = 19.5;

/// Whether the training data decide for the pair `pair` against the single `single`: its
/// score sum lower by [`PAIR_DECISIVE`] or more. Later periods of the same experiment share the
/// model's compensation of a wrong single cause (the residues absorb it at the same lines), so
/// they may not separate the two; the training data, with the pair's extra parameter paid for by
/// the test's level, can.
pub(super) fn decisive(pair: &Fitted, single: &Fitted) -> bool {
    penalised(&single.stat, 0) - penalised(&pair.stat, 0) >= PAIR_DECISIVE
}

/// Naming's false-rejection probability relative to the verdict's α: an extension is named when
/// its held-out statistic stays below the `1 − α/10` quantile (a right extension is refused
/// one time in a thousand at α = 1 %; wrong names are kept out by the competition between the
/// hypotheses and the pair rule, not by this threshold).
pub(super) const NAMING_ALPHA_RATIO: f64 = 0.1;

pub(super) fn explains(s: &Statistic, alpha: f64) -> bool {
    s.value <= crate::stats::threshold(s.effective_lines, alpha * NAMING_ALPHA_RATIO)
}

/// What the validation of the rate-tied hypotheses settled on.
pub(super) struct Settled {
    pub(super) family: Family,
    /// Parameters from the training data (the start of the final refit).
    pub(super) params: RateTied,
    pub(super) named: bool,
    /// Not named because two unrelated causes explain the data alike ([`ambiguous`]): a
    /// rate-tied effect is there, so the model is not to blame.
    pub(super) ambiguous: bool,
    pub(super) ranking: Vec<Ranked>,
    pub(super) partial: Ranked,
    pub(super) gain: Gain,
    /// With `ambiguous`: the chosen hypothesis first, then those that explain the data as well.
    pub(super) rivals: Vec<Fitted>,
}

/// The rate-tied search and its validation (earlier/later periods of every same-level slower
/// experiment together — the family and parameters chosen on all their earlier periods, judged
/// on the later ones; whole experiments left out in turn when two or more cannot be split),
/// then the named extension refitted on all data. With two or more slower experiments the
/// gain is measured on each whole experiment left out in turn (the family fixed, its
/// parameters refitted on the others). The flag says the answer is `unexplained` only because two rate-tied
/// causes explain the data alike.
pub(super) fn rate_tied(
    data: &Data<'_>,
    j: &Judged<'_>,
    progress: &mut dyn FnMut(&str),
) -> Result<(Outcome, bool)> {
    let tied: Vec<&Val<'_>> = data.vals.iter().filter(|v| v.rate_tied()).collect();
    // several slower experiments are used together where each can be split into earlier and
    // later periods: a hold delay and an averaging sampler lag the phase alike at one rate
    // and apart at two, so a fold trained on one experiment alone cannot tell them apart;
    // whole experiments are left out in turn only when they cannot be split
    let split = tied.iter().all(|v| v.parts.is_some());
    let mut s = if tied.len() >= 2 && !split {
        leave_one_out(j, &tied, progress)?
    } else {
        halves(j, &tied, progress)?
    };
    if tied.len() >= 2 && split && s.named {
        // the gain on whole experiments the extension was not fitted on: each slower
        // experiment left out in turn, the named family's parameters refitted on the others
        progress("the named extension on each slower experiment left out in turn");
        s.gain = left_out_gain(j, &tied, s.family, &s.params)?;
    }
    if !s.named {
        let next = if s.ambiguous {
            Some(super::next::propose(data, j, &tied, &s.rivals, progress)?)
        } else {
            None
        };
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
                amplitude: None,
                next,
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
            amplitude: None,
            next: None,
        },
        false,
    ))
}

/// One same-level slower experiment: family and parameters on its earlier periods, judged on
/// its later ones; then the chosen family refitted on the later periods and judged on the
/// earlier ones (each part held out once; the family is chosen on the earlier ones only).
pub(super) fn halves(
    j: &Judged<'_>,
    tied: &[&Val<'_>],
    progress: &mut dyn FnMut(&str),
) -> Result<Settled> {
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
    let (all, all_stats) = (fitted, held_stats);
    let (fitted, held_stats) = told(j, &all, &all_stats, &train)?;
    let judge = |i: usize| held_stats[i].unwrap_or(fitted[i].stat);
    let k = pick(&fitted, &judge, held.is_some());
    let others = rivals(&fitted, k, &judge, j.modal.alpha);
    let (k, others) = match shared_cause(&fitted, k, &others, &judge, j.modal.alpha) {
        Some(s) => (s, rivals(&fitted, s, &judge, j.modal.alpha)),
        None => (k, others),
    };
    let chosen = &fitted[k];
    // the chosen hypothesis and those that explain the data as well, for the next experiment;
    // a pair whose causes are not all told from zero may not be named but can leave the
    // single cause in it undetermined
    let mut contest: Vec<Fitted> = std::iter::once(k)
        .chain(others)
        .map(|i| fitted[i].clone())
        .collect();
    let named: Vec<Family> = contest.iter().map(|f| f.family).collect();
    let all_judge = |i: usize| all_stats[i].unwrap_or(all[i].stat);
    let alpha = j.modal.alpha;
    contest.extend(with_undetermined_pairs(
        &all,
        chosen.family,
        &named,
        &all_judge,
        alpha,
    ));
    let unsure = contest.len() > 1;
    if !unsure {
        contest.clear();
    }
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
            rivals: contest,
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
        rivals: contest,
        gain: Gain::measured(before.value, after.value, labels),
    })
}

/// The lines of held-out experiment `v` under an extension fitted without it: on the whole
/// experiment, or — when the extension has clock errors, which belong to each experiment —
/// its clock error fitted on the earlier periods and the lines of the later ones.
pub(super) fn held_out_lines(
    j: &Judged<'_>,
    (family, params): (Family, &RateTied),
    v: &Val<'_>,
    full: bool,
) -> Result<Vec<Line>> {
    if !family.clock() {
        return j
            .modal
            .lines_for(params, 0.0, &target(v, Part::Whole), full);
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
    let e = j.modal.clock_of(params, &ta)?;
    j.modal.lines_for(params, e, &tb, full)
}

/// The gain of family `family` on whole left-out experiments: each of `tied` left out in
/// turn, the family's parameters refitted on the others from `start`, the left-out
/// experiment's statistic before (the plain modal model) and after, pooled.
pub(super) fn left_out_gain(
    j: &Judged<'_>,
    tied: &[&Val<'_>],
    family: Family,
    start: &RateTied,
) -> Result<Gain> {
    let none = RateTied::default();
    let (mut before, mut after) = (Vec::new(), Vec::new());
    for (k, v) in tied.iter().enumerate() {
        let others: Vec<Target<'_>> = tied
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != k)
            .map(|(_, w)| target(w, Part::Whole))
            .collect();
        let params = j.modal.refine(family, &others, start)?;
        let c = v.whole.inflation;
        before.push((held_out_lines(j, (Family::None, &none), v, true)?, c));
        after.push((held_out_lines(j, (family, &params), v, true)?, c));
    }
    let pooled = |sets: &[(Vec<Line>, f64)]| {
        statistic(sets.iter().map(|(l, c)| (l.as_slice(), *c)), j.modal.alpha)
    };
    let (b, a) = (pooled(&before), pooled(&after));
    Ok(Gain::measured(
        b.value,
        a.value,
        tied.iter()
            .map(|v| format!("{} (whole experiment, left out)", v.exp.spec.name))
            .collect(),
    ))
}

/// Two or more same-level slower experiments: each left out in turn, the family and
/// parameters chosen on the others; named only when every fold picks the same family and the
/// left-out experiments together pass the threshold.
pub(super) fn leave_one_out(
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
        let all = fitted?;
        let c = v.whole.inflation;
        let all_stats = all
            .iter()
            .map(|f| {
                let lines = held_out_lines(j, (f.family, &f.params), v, false)?;
                Ok(Some(statistic([(lines.as_slice(), c)], j.modal.alpha)))
            })
            .collect::<Result<Vec<_>>>()?;
        if k == 0 {
            ranking = (all.iter().zip(&all_stats))
                .map(|(f, s)| ranked(f, s.map(|s| s.value)))
                .collect();
        }
        let (fitted, stats) = told(j, &all, &all_stats, &trains[k])?;
        let stat_of = |i: usize| stats[i].unwrap_or(fitted[i].stat);
        let p = pick(&fitted, &stat_of, true);
        if k == 0 {
            first = Some(fitted[p].clone());
        }
        picks.push(fitted[p].family);
        let none_idx = fitted
            .iter()
            .position(|f| f.family == Family::None)
            .unwrap_or(p);
        let (none, chosen) = (&fitted[none_idx], &fitted[p]);
        before.push((held_out_lines(j, (none.family, &none.params), v, true)?, c));
        after.push((
            held_out_lines(j, (chosen.family, &chosen.params), v, true)?,
            c,
        ));
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
        rivals: Vec::new(),
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
pub(super) fn causes_of(
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
