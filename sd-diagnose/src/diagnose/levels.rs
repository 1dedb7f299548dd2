//! Stage 5a: nonlinearity as a model — the amplitude-dependent modal model over the levels
//! (its gain on levels left out: [`super::held_out`]).

use super::checks::*;
use super::decide::*;
use super::held_out::{later_periods, levels_left_out};
use super::judged::*;
use super::read::*;
use crate::amplitude::{
    candidates, describes, fit_level, kinds, on_tracks, AmplitudeModel, Level, LevelFit,
};
use crate::data::held_out_label;
use crate::lemma6::Pair;
use crate::modal::ModalBasis;
use crate::stats::{statistic, Line, Statistic};
use crate::{
    Cause, CornerTrend, DampingTrend, DriftCheck, DriftSign, Evidence, EvidenceKind, Extension,
    FreqTrend, Gain, ModePoint, MovingMode, PoleKind, Result, Verdict,
};
use rayon::prelude::*;
use sd_model::normal_quantile;
use std::collections::BTreeMap;

/// Every level's modal fit on `basis`: the candidates, less those the model experiment
/// itself does not determine or finds elsewhere than the linear model
/// ([`LevelFit::agrees_with_linear`]), fitted again without them; `None` when a fit fails or
/// no candidate is left.
pub(super) fn level_fits(
    basis: &ModalBasis,
    (h, fast): (f64, &crate::data::Estimate),
    levels: &[Level<'_>],
) -> Option<(Vec<usize>, Vec<LevelFit>)> {
    // the levels' fits are independent: in parallel, collected in order
    let fit = |cand: &[usize]| -> Option<Vec<LevelFit>> {
        levels
            .par_iter()
            .map(|lv| fit_level(basis, cand, h, lv))
            .collect::<Result<Vec<_>>>()
            .ok()
    };
    let cand = candidates(basis, fast);
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
pub(super) const SLOW_POLE_SLACK: f64 = 1.1;

/// The statistic a changed basis may reach on the model experiment `reference` and still
/// describe it: [`SLOW_POLE_SLACK`] times the larger of the verdict's threshold and `basis`'s
/// own statistic.
pub(super) fn slack_bound(
    basis: &ModalBasis,
    h: f64,
    reference: &Level<'_>,
    alpha: f64,
) -> Result<f64> {
    let full = describes(basis, h, reference, alpha)?;
    Ok(SLOW_POLE_SLACK * full.threshold.max(full.value))
}

/// A friction-damped rigid body's basis without the slow real poles and overdamped pairs
/// ([`ModalBasis::slow_extras`]) the model experiment does not need: each, slowest first, is
/// dropped when the basis without it still describes the model experiment `reference`
/// within [`SLOW_POLE_SLACK`] times the larger of the verdict's threshold and the full
/// basis's statistic (a sensor filter's pole raises it several-fold and stays; a pole the
/// fit spent on the friction's distortion does not).
pub(super) fn without_unneeded_slow_poles(
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
#[derive(Clone)]
pub(super) struct Variant {
    pub(super) basis: ModalBasis,
    pub(super) cand: Vec<usize>,
    pub(super) fits: Vec<LevelFit>,
}

/// The other corners a friction-damped rigid body may have: where several real poles below
/// the modes could be the corner (a fit at the friction's strongest level may spend one on
/// the friction's distortion, slower or faster than the corner), the bases with the second,
/// third… as the corner ([`ModalBasis::with_damped_rigid_body_at`]), each without the slow
/// poles the model experiment does not need, with their level fits. Which one models the
/// levels is decided on the levels a model is fitted on ([`choose`]).
pub(super) fn other_corners(
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
        if let Some((cand, fits)) = level_fits(&trial, (data.h, &data.fast), levels) {
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
pub(super) fn without_slow_extras(
    damped: &ModalBasis,
    data: &Data<'_>,
    levels: &[Level<'_>],
) -> Option<Variant> {
    let extras = damped.slow_extras();
    if extras.is_empty() {
        return None;
    }
    let basis = damped.without_poles(&extras).ok()?;
    let (cand, fits) = level_fits(&basis, (data.h, &data.fast), levels)?;
    Some(Variant { basis, cand, fits })
}

/// Of `variants`, the one whose amplitude model, fitted on the levels `on` (indices into
/// `levels`), describes those same levels best (the pooled statistic of its predictions
/// over all their lines): a structural choice made on the training levels only. Every
/// variant fits each level about as well with free residues; the amplitude model shares the
/// model experiment's residues across levels, so only the basis whose moving pole carries
/// the amplitude dependence describes them all. The first variant where none can be fitted.
pub(super) fn choose(
    variants: &[Variant],
    levels: &[Level<'_>],
    on: &[usize],
    h: f64,
    alpha: f64,
) -> usize {
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
pub(super) fn damped_reading(
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
pub(super) fn repeat_drifts(data: &Data<'_>, ch: &mut Checks) -> Option<Outcome> {
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
pub(super) fn drift_check(data: &Data<'_>, alpha: f64) -> DriftCheck {
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
pub(super) fn nonlinearity(
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
    let (levels, at) = levels_of(data);
    let damped = damped_basis(data, j, &levels[0], alpha)?;
    progress("modal fit of every level; every physical mode tracked over the levels by local fits");
    // the bases in the order tried; the first whose level fits all succeed
    let bases = candidate_bases(&damped, &j.modal.basis, data.h, &levels[0], alpha)?;
    let rel = level_ratios(data, &at);
    let fast = (data.h, &data.fast);
    // the level fits and the tracks are independent: side by side
    let (tried, tracks) = rayon::join(
        || {
            bases
                .iter()
                .find_map(|b| level_fits(b, fast, &levels).map(|x| (b, x)))
        },
        || tracked(&levels, &rel, alpha),
    );
    let Some((basis, (cand, fits))) = tried else {
        // no amplitude model: the physical modes tracked over the levels still name the kind
        let tracks = tracks.modes;
        return Ok(per_level(
            data,
            found,
            (relative_levels, check, tracks),
            alpha,
        ));
    };
    // the two-level validation fits its earlier periods with the level fit: it keeps the
    // level fits of the model experiment too, not the tracks'
    let level_fitted = fits.clone();
    let mut variants = vec![Variant {
        basis: basis.clone(),
        cand,
        fits,
    }];
    if damped.is_damped() && levels.len() >= 3 {
        variants.extend(other_corners(j, data, &levels, alpha)?);
        variants.extend(without_slow_extras(&damped, data, &levels));
    }
    with_local_fits(&mut variants, &levels, &tracks.modes);
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
            later_periods(data, j, &levels, &level_fitted, (basis, cand), alpha)?,
            Vec::new(),
            BTreeMap::new(),
        )
    };
    let modes = model.report(&all, &fit_refs, &loo);
    let (kind, damping_trend, corner_trend, tracks) = trends(&modes, tracks, alpha);
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
            tracks,
            drift_check: check,
        }],
        extension: Extension::Amplitude(modes),
        ranking: Vec::new(),
        partial: None,
        gain,
        models,
        held,
        amplitude: Some(Box::new(model)),
        next: None,
    })
}

/// The bases the levels are fitted on, in the order tried: the damped rigid body without
/// the slow poles the model experiment `reference` does not need, then with them, then the
/// model's own basis `own`; a mode the model split into two close pairs as one pair.
fn candidate_bases(
    damped: &ModalBasis,
    own: &ModalBasis,
    h: f64,
    reference: &Level<'_>,
    alpha: f64,
) -> Result<Vec<ModalBasis>> {
    let mut bases = vec![without_unneeded_slow_poles(damped, h, reference, alpha)?];
    if damped.is_damped() {
        bases.push(damped.clone());
        bases.push(own.clone());
    }
    bases.extend(damped.without_close_pairs()?);
    bases.dedup_by(|a, b| a.poles() == b.poles() && a.is_damped() == b.is_damped());
    Ok(bases)
}

/// Each variant also with the pairs the tracks follow on their local fits
/// ([`crate::amplitude::on_tracks`]); [`choose`] takes the one that describes the training
/// levels best.
fn with_local_fits(
    variants: &mut Vec<Variant>,
    levels: &[Level<'_>],
    tracks: &[crate::tracks::ModeTrack],
) {
    let names: Vec<&str> = levels.iter().map(|l| l.name.as_str()).collect();
    let on_local: Vec<Variant> = variants
        .iter()
        .filter_map(|v| {
            let mut t = v.clone();
            (on_tracks(&t.basis, &t.cand, &mut t.fits, &names, tracks) > 0).then_some(t)
        })
        .collect();
    variants.extend(on_local);
}

/// The model experiment first, then every experiment at its rate, each with its index in
/// `data.vals` (`None` for the model experiment).
fn levels_of<'d>(data: &'d Data<'_>) -> (Vec<Level<'d>>, Vec<Option<usize>>) {
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
    (levels, at)
}

/// The model's basis with a rigid body damped at the model experiment's level (friction)
/// as one block whose damping moves (a pole below the first line is an integrator for the
/// data), or read from `reference` when the basis has none.
fn damped_basis(
    data: &Data<'_>,
    j: &Judged<'_>,
    reference: &Level<'_>,
    alpha: f64,
) -> Result<ModalBasis> {
    let near_zero = std::f64::consts::TAU * data.fast.frd.freq_hz().first().copied().unwrap_or(0.0);
    let damped = j.modal.basis.with_damped_rigid_body(near_zero)?;
    if damped.is_damped() {
        return Ok(damped);
    }
    Ok(damped_reading(&damped, near_zero, data.h, reference, alpha)?.unwrap_or(damped))
}

/// `kind`, `damping_trend` and `corner_trend` of the amplitude model's `modes`, the first
/// two from the tracked physical modes where they state them — unless a moving friction
/// corner outweighs every moving pair ([`crate::tracks::corner_dominates`]).
fn trends(
    modes: &[MovingMode],
    mut tracks: crate::tracks::Tracked,
    alpha: f64,
) -> (
    FreqTrend,
    DampingTrend,
    CornerTrend,
    Vec<crate::tracks::ModeTrack>,
) {
    let (kind, damping_trend, corner_trend) = kinds(modes, normal_quantile(1.0 - alpha / 2.0));
    let corner =
        crate::tracks::corner_dominates(&mut tracks.modes, corner_shift(modes), tracks.body_share);
    let (kind, damping_trend) =
        crate::tracks::decided(&tracks.modes, (kind, damping_trend), corner);
    (kind, damping_trend, corner_trend, tracks.modes)
}

/// The largest move of a moving real pole (a friction corner) of the amplitude model over the
/// levels, in its half-power bandwidth `2f_c` ([`crate::tracks::corner_dominates`]); 0 when
/// none moves.
fn corner_shift(modes: &[MovingMode]) -> f64 {
    modes
        .iter()
        .filter(|m| m.pole == PoleKind::Real && m.frequency_moves && m.linear_freq_hz > 0.0)
        .filter_map(|m| {
            let by = |a: &&ModePoint, b: &&ModePoint| {
                a.relative_amplitude.total_cmp(&b.relative_amplitude)
            };
            let lo = m.points.iter().min_by(by)?;
            let hi = m.points.iter().max_by(by)?;
            Some((hi.freq_hz - lo.freq_hz).abs() / (2.0 * m.linear_freq_hz))
        })
        .filter(|s| s.is_finite())
        .fold(0.0, f64::max)
}

/// Each level's excitation relative to the model experiment's (1 for the model experiment,
/// `at[k] = None`).
pub(super) fn level_ratios(data: &Data<'_>, at: &[Option<usize>]) -> Vec<f64> {
    at.iter()
        .map(|a| a.map_or(1.0, |i| data.vals[i].level))
        .collect()
}

/// The physical modes tracked over `levels` (excitation `rel` relative to the model
/// experiment's; [`crate::tracks`]), the model experiment's physical fit on its thinned lines;
/// empty when it fails.
fn tracked(levels: &[Level<'_>], rel: &[f64], alpha: f64) -> crate::tracks::Tracked {
    let Ok(first) = levels[0].est.thinned() else {
        return Default::default();
    };
    let tl: Vec<crate::tracks::TrackLevel<'_>> = levels
        .iter()
        .enumerate()
        .map(|(k, lv)| crate::tracks::TrackLevel {
            name: &lv.name,
            level: rel[k],
            frd: &lv.est.frd,
            correlation: &lv.est.correlation,
            spectra: lv.est.spectra.as_deref(),
        })
        .collect();
    crate::tracks::track_modes(&first.frd, &tl, alpha).unwrap_or_default()
}

/// Without an amplitude model (no in-band modes to move, or a level no modal fit describes):
/// one FRF per level (the level's own earlier periods predict its later ones); `kind` and
/// `damping_trend` from the physical modes tracked over the levels when they state them
/// ([`crate::tracks::decided`]), else `none`.
pub(super) fn per_level(
    data: &Data<'_>,
    found: &[(usize, Statistic)],
    (relative_levels, check, tracks): (
        BTreeMap<String, f64>,
        DriftCheck,
        Vec<crate::tracks::ModeTrack>,
    ),
    alpha: f64,
) -> Outcome {
    let (kind, damping_trend) =
        crate::tracks::decided(&tracks, (FreqTrend::None, DampingTrend::None), false);
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
            kind,
            damping_trend,
            corner_trend: CornerTrend::None,
            modes: Vec::new(),
            tracks,
            drift_check: check,
        }],
        extension: Extension::PerLevel,
        ranking: Vec::new(),
        partial: None,
        gain,
        models: BTreeMap::new(),
        held: BTreeMap::new(),
        amplitude: None,
        next: None,
    }
}
