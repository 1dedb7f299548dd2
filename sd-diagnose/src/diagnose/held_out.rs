//! Stage 5b: the amplitude model judged on data it was not fitted on — every validation level
//! left out in turn (three or more levels), or a second level's later periods (two levels).

use super::checks::*;
use super::judged::*;
use super::levels::{choose, level_ratios, Variant};
use super::read::*;
use crate::amplitude::{fit_level, level_floor, AmplitudeModel, Level, LevelFit};
use crate::data::held_out_label;
use crate::modal::ModalBasis;
use crate::stats::{in_bands, statistic, Line};
use crate::{Gain, HeldOut, Result};
use rayon::prelude::*;
use std::collections::BTreeMap;

/// Per level, the frequencies and dampings the model fitted without it predicted.
pub(super) type LeftOut = Vec<Option<Vec<(f64, f64)>>>;

/// Three or more levels: each validation level left out in turn, the amplitude model fitted
/// on the others (the model experiment always among them) and judged on it; before: the
/// linear model's simulation of it. The folds are independent: they run in parallel and are
/// gathered in level order.
pub(super) fn levels_left_out(
    data: &Data<'_>,
    ch: &Checks,
    levels: &[Level<'_>],
    at: &[Option<usize>],
    (variants, chosen, alpha): (&[Variant], usize, f64),
) -> Result<(Gain, LeftOut, BTreeMap<String, HeldOut>)> {
    let rel = level_ratios(data, at);
    // the linear model's lines at each level
    let linear: Vec<Option<&[Line]>> = at.iter().map(|a| a.map(|i| &ch.model[i][..])).collect();
    let h = data.h;
    let folds = (1..levels.len())
        .into_par_iter()
        .map(|k| {
            linear[k]
                .map(|lin| left_out((h, &rel), lin, levels, (k, variants, chosen, alpha)))
                .transpose()
        })
        .collect::<Result<Vec<_>>>()?;
    let (mut before, mut after, mut held) = (Vec::new(), Vec::new(), Vec::new());
    let mut per = BTreeMap::new();
    let mut loo: LeftOut = vec![None; levels.len()];
    for (k, f) in folds
        .into_iter()
        .enumerate()
        .filter_map(|(q, f)| Some((q + 1, f?)))
    {
        let lv = &levels[k];
        loo[k] = f.predicted;
        held.push(format!(
            "{} (whole experiment, left out{})",
            lv.name,
            if f.held.extrapolated {
                "; beyond the fitted amplitudes: extrapolated"
            } else {
                ""
            }
        ));
        per.insert(lv.name.clone(), f.held);
        after.push((f.after, lv.est.inflation));
        before.push((f.before, lv.est.inflation));
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

/// One fold of [`levels_left_out`]: the level's lines in the moving bands under the model
/// fitted without it (`after`) and under the linear model (`before`), and the summary.
struct Fold {
    after: Vec<Line>,
    before: Vec<Line>,
    held: HeldOut,
    /// The fold's per-candidate predictions, where its basis is the final one's.
    predicted: Option<Vec<(f64, f64)>>,
}

/// Level `k` left out: the basis chosen on the other levels ([`choose`]), the amplitude model
/// fitted on them, judged on level `k` against the linear model's lines `linear`; `h` is the
/// model experiment's sample period, `rel` each level's excitation relative to its.
fn left_out(
    (h, rel): (f64, &[f64]),
    linear: &[Line],
    levels: &[Level<'_>],
    (k, variants, chosen, alpha): (usize, &[Variant], usize, f64),
) -> Result<Fold> {
    let lv = &levels[k];
    let train: Vec<&Level<'_>> = levels
        .iter()
        .enumerate()
        .filter(|(m, _)| *m != k)
        .map(|(_, l)| l)
        .collect();
    let on: Vec<usize> = (0..levels.len()).filter(|m| *m != k).collect();
    let fold = choose(variants, levels, &on, h, alpha);
    let Variant { basis, cand, fits } = &variants[fold];
    let tf: Vec<&LevelFit> = on.iter().map(|&q| &fits[q]).collect();
    let m = AmplitudeModel::fit(basis, h, cand, &train, &tf, alpha)?;
    let c = lv.est.inflation;
    let bands = m.moving_bands(lv);
    let (a, b) = (
        in_bands(m.lines(lv)?, &bands),
        in_bands(linear.to_vec(), &bands),
    );
    let (sa, sb) = (
        statistic([(a.as_slice(), c)], alpha).value,
        statistic([(b.as_slice(), c)], alpha).value,
    );
    let own = level_floor((basis, cand), &fits[k], h, lv, &bands, alpha)?;
    // beyond the fitted amplitudes of a moving mode; or, where nothing moves on the training
    // levels, beyond their excitation levels
    let (lo, hi) = on
        .iter()
        .map(|&q| rel[q])
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), x| {
            (lo.min(x), hi.max(x))
        });
    let beyond = rel[k] < lo * 0.999 || rel[k] > hi * 1.001;
    let extrapolated = m.extrapolates(lv, &tf) || (!m.moves_any() && beyond);
    Ok(Fold {
        held: HeldOut {
            before: sb,
            after: sa,
            ratio: sb / sa,
            floor: own,
            lines: a.len(),
            extrapolated,
        },
        predicted: (fold == chosen).then(|| m.predicted(lv)),
        after: a,
        before: b,
    })
}

/// Two levels: the amplitude model fitted on the model experiment and the other level's
/// earlier periods, judged on its later ones (labelled so).
pub(super) fn later_periods(
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
