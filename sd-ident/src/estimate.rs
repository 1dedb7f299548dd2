//! The FRF of one recorded experiment, the way `sdctl frf` and the Python package estimate it:
//! periodic records (the manifest gives `period`) by the period average of [`frf_periodic`]
//! (closed loop through the reference when there is one), non-periodic ones by the local
//! polynomial method ([`lpm_closed_loop_snr`] with a reference, [`lpm()`] without), with the
//! data-quality warnings of [`crate::quality`]. Lines whose input is at its own noise level are
//! dropped unless `keep_low_snr`; a record whose input is explained by its output alone (pure
//! feedback, no excitation) is refused unless `keep_low_snr`.

use crate::{
    feedback_only, frf_periodic, frf_periodic_mimo, lpm, lpm_closed_loop_snr, same_level,
    snr_warnings, trusted, Bla, Channels, DataWarning, Experiment, IdentError, LpmOptions,
    MimoFrfEstimate, PeriodicOptions, Result,
};
use sd_model::Frd;

/// What [`frf_of_experiment`] may change from its defaults.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrfRequest {
    /// Lines count as excited where the input's power is above this fraction of the strongest
    /// line's (periodic records; `None`: the default of [`PeriodicOptions::new`]).
    pub excited_fraction: Option<f64>,
    /// Keep lines (and records) whose input is at its noise level, with a warning.
    pub keep_low_snr: bool,
}

/// The FRF of one SISO experiment: the estimate (its variance the BLA's total where the
/// [`Bla`] could be formed), the data-quality warnings, and the BLA.
#[derive(Debug, Clone)]
pub struct ExperimentFrf {
    /// The estimate at the kept lines, with the total variance.
    pub frd: Frd,
    /// What was found in the data.
    pub warnings: Vec<DataWarning>,
    /// The best linear approximation with noise and distortion apart (`None` for an estimate
    /// without variance: one period without non-excited bins).
    pub bla: Option<Bla>,
}

/// The FRF of `exp` with its data-quality warnings (module documentation); its variance is
/// the BLA's total (noise + the distortion the data measure, [`crate::bla`]).
///
/// # Errors
/// As [`estimate_experiment`].
pub fn frf_of_experiment(exp: &Experiment, req: &FrfRequest) -> Result<(Frd, Vec<DataWarning>)> {
    let e = estimate_experiment(exp, req)?;
    Ok((e.frd, e.warnings))
}

/// `e` (no trusted line of a periodic estimate) with the period the excitation repeats with,
/// when it is not the manifest's `period_samples = p`: a wrong period spreads the excitation
/// over every bin.
fn with_likely_period(e: IdentError, exp: &Experiment, p: usize) -> IdentError {
    let x = exp.r.as_deref().unwrap_or(&exp.u);
    match (e, crate::likely_period(x)) {
        (IdentError::Data(m), Some(q)) if q != p => IdentError::Data(format!(
            "{m}; the excitation of `{}` repeats every {q} samples, not every {p}: set \
             period_samples = {q}",
            exp.spec.name
        )),
        (e, _) => e,
    }
}

/// The FRF, warnings and BLA of a SISO experiment (module documentation).
///
/// # Errors
/// [`IdentError::InvalidArgument`] for an `excited_fraction` outside (0, 1) or a MIMO
/// experiment, the estimators' errors, [`IdentError::Data`] for a record without excitation
/// (unless `keep_low_snr`).
pub fn estimate_experiment(exp: &Experiment, req: &FrfRequest) -> Result<ExperimentFrf> {
    if exp.spec.is_mimo() {
        return Err(IdentError::InvalidArgument(format!(
            "experiment `{}` has {} inputs and {} outputs: its FRF is a matrix \
             (frf_of_experiments with every experiment of the set; `sdctl frf` with an \
             --experiment for each)",
            exp.spec.name,
            exp.spec.inputs().len(),
            exp.spec.outputs().len()
        )));
    }
    let fs = exp.spec.sample_rate_hz;
    let keep = req.keep_low_snr;
    let (frd, mut warnings, bla) = match exp.spec.period_samples {
        Some(p) => {
            let mut opt = PeriodicOptions::new(p, exp.spec.skip_periods);
            if let Some(f) = req.excited_fraction {
                check_fraction(f)?;
                opt.excited_fraction = f;
            }
            let est = frf_periodic(fs, exp.r.as_deref(), &exp.u, &exp.y, &opt)?;
            let warnings = est.warnings(!keep);
            let bla = Bla::from_periodic(&est).ok();
            let ok = est.trusted_lines();
            let frd = bla
                .as_ref()
                .map_or_else(|| est.frd.clone(), |b| b.frd.clone());
            if keep {
                (frd, warnings, bla)
            } else {
                let bla = match bla {
                    Some(b) => Some(b.select(|i| ok[i])?),
                    None => None,
                };
                let frd =
                    trusted(&frd, &est.input_snr).map_err(|e| with_likely_period(e, exp, p))?;
                (frd, warnings, bla)
            }
        }
        None => {
            let lo = LpmOptions::default();
            let (frd, warnings) = match &exp.r {
                Some(r) => {
                    let (frd, snr) = lpm_closed_loop_snr(fs, r, &exp.u, &exp.y, &lo)?;
                    let warnings = snr_warnings(&frd, &snr, true, !keep);
                    let frd = if keep { frd } else { trusted(&frd, &snr)? };
                    (frd, warnings)
                }
                None => {
                    let n = exp.u.len();
                    let x = nalgebra::DMatrix::from_column_slice(n, 1, &exp.u);
                    let z = nalgebra::DMatrix::from_column_slice(n, 1, &exp.y);
                    (lpm(fs, &x, &z, &lo)?.frd, Vec::new())
                }
            };
            let bla = Bla::from_lpm(&frd).ok();
            (frd, warnings, bla)
        }
    };
    if let Some(w) = feedback_only(&exp.u, &exp.y)? {
        if !keep {
            return Err(IdentError::Data(format!(
                "{w} (to keep the estimate anyway: `--keep-low-snr` in sdctl, `keep_low_snr=True` \
                 in Python)"
            )));
        }
        warnings.insert(0, w);
    }
    Ok(ExperimentFrf { frd, warnings, bla })
}

/// [`estimate_experiment`] of `exps[target]`, its distortion carried from a sibling where its
/// own excitation cannot measure it ([`Bla::carried_from`]): a periodic experiment of the set
/// with the same input, output and reference columns, sample rate and period, an excitation
/// rms within [`crate::bla::CARRY_RMS_TOLERANCE`] ([`same_level`]) and a band covering at
/// least 80 % of the target's lines, whose measure may replace the target's
/// ([`crate::Distortion::replaced_by`]). Of several, the one nearest in rms.
///
/// # Errors
/// As [`estimate_experiment`]; a `target` out of range.
pub fn estimate_in_set(
    exps: &[Experiment],
    target: usize,
    req: &FrfRequest,
) -> Result<ExperimentFrf> {
    let exp = exps.get(target).ok_or_else(|| {
        IdentError::InvalidArgument(format!("experiment index {target} out of range"))
    })?;
    let mut own = estimate_experiment(exp, req)?;
    let Some(bla) = own.bla.as_ref().filter(|b| b.distortion.replaceable()) else {
        return Ok(own);
    };
    let level = excitation_rms(exp);
    let f = bla.frd.freq_hz();
    let mut best: Option<(f64, Bla, &str)> = None;
    for (i, other) in exps.iter().enumerate() {
        let s = &other.spec;
        let alike = i != target
            && s.period_samples.is_some()
            && s.sample_rate_hz == exp.spec.sample_rate_hz
            && s.inputs() == exp.spec.inputs()
            && s.outputs() == exp.spec.outputs()
            && s.references() == exp.spec.references()
            && same_level(level, excitation_rms(other));
        if !alike {
            continue;
        }
        let Ok(Some(src)) = estimate_experiment(other, req).map(|e| e.bla) else {
            continue;
        };
        let (lo, hi) = match (src.frd.freq_hz().first(), src.frd.freq_hz().last()) {
            (Some(&lo), Some(&hi)) => (lo, hi),
            _ => continue,
        };
        let covered = f.iter().filter(|x| (lo..=hi).contains(*x)).count();
        let gap = (excitation_rms(other) - level).abs();
        if 5 * covered >= 4 * f.len() && best.as_ref().is_none_or(|b| gap < b.0) {
            best = Some((gap, src, &s.name));
        }
    }
    if let Some((_, src, name)) = best {
        let carried = bla.carried_from(&src, name)?;
        if matches!(carried.distortion, crate::Distortion::Carried { .. }) {
            own.frd = carried.frd.clone();
            own.bla = Some(carried);
        }
    }
    Ok(own)
}

/// Rms of the excitation (the reference, or the input without one) over the steady part.
pub fn excitation_rms(e: &Experiment) -> f64 {
    let x = e.r.as_ref().unwrap_or(&e.u);
    let start = e.spec.skip_periods * e.spec.period_samples.unwrap_or(0);
    sd_model::rms(&x[start.min(x.len())..])
}

/// An excited fraction must lie in (0, 1).
fn check_fraction(f: f64) -> Result<()> {
    if f.is_finite() && f > 0.0 && f < 1.0 {
        Ok(())
    } else {
        Err(IdentError::InvalidArgument(format!(
            "excited fraction {f} must be in (0, 1)"
        )))
    }
}

/// The ny×nu FRF of a set of experiments with the same columns' counts: periodic ones (same
/// rate, period and skipped periods) by [`frf_periodic_mimo`], one non-periodic record by the
/// MIMO local polynomial method ([`lpm()`] in open loop with independently excited inputs,
/// [`crate::lpm_closed_loop_mimo`] through one reference per input in closed loop); each with
/// the covariance of `vec(G)`.
///
/// # Errors
/// No experiment, experiments that differ in rate, period, skipped periods or channel counts,
/// several non-periodic records, an `excited_fraction`
/// outside (0, 1), the estimators' errors (too few experiments for the inputs among them).
pub fn frf_of_experiments(exps: &[&Experiment], req: &FrfRequest) -> Result<MimoFrfEstimate> {
    let first = exps
        .first()
        .ok_or_else(|| IdentError::InvalidArgument("no experiment to estimate from".into()))?;
    let spec = &first.spec;
    let shape = |e: &Experiment| {
        (
            e.spec.inputs().len(),
            e.spec.outputs().len(),
            e.spec.references().len(),
        )
    };
    if let Some(e) = exps.iter().find(|e| {
        e.spec.sample_rate_hz != spec.sample_rate_hz
            || e.spec.period_samples != spec.period_samples
            || e.spec.skip_periods != spec.skip_periods
            || shape(e) != shape(first)
    }) {
        return Err(IdentError::InvalidArgument(format!(
            "experiment `{}` differs from `{}` in rate, period, skipped periods or its numbers \
             of inputs, outputs and references: one FRF needs them equal",
            e.spec.name, spec.name
        )));
    }
    let fs = spec.sample_rate_hz;
    match spec.period_samples {
        Some(p) => {
            let mut opt = PeriodicOptions::new(p, spec.skip_periods);
            if let Some(f) = req.excited_fraction {
                check_fraction(f)?;
                opt.excited_fraction = f;
            }
            let sig: Vec<[Vec<&[f64]>; 3]> = exps
                .iter()
                .map(|e| [e.references(), e.inputs(), e.outputs()])
                .collect();
            let ch: Vec<Channels<'_>> = sig.iter().map(|[r, u, y]| Channels { r, u, y }).collect();
            frf_periodic_mimo(fs, &ch, &opt)
        }
        None => {
            if exps.len() > 1 {
                return Err(IdentError::InvalidArgument(
                    "a non-periodic MIMO FRF is estimated from one record (open loop with \
                     independently excited inputs, or closed loop with one reference per \
                     input); several records need periodic data"
                        .into(),
                ));
            }
            let n = first.u.len();
            let cols = |v: Vec<&[f64]>| nalgebra::DMatrix::from_fn(n, v.len(), |t, j| v[j][t]);
            let (u, y) = (cols(first.inputs()), cols(first.outputs()));
            let est = if first.references().is_empty() {
                lpm(fs, &u, &y, &LpmOptions::default())?
            } else {
                // closed loop: through the references
                crate::lpm::lpm_closed_loop_mimo(
                    fs,
                    &cols(first.references()),
                    &u,
                    &y,
                    &LpmOptions::default(),
                )?
            };
            Ok(MimoFrfEstimate {
                frd: est.frd,
                lines: Vec::new(),
                covariance: est.covariance,
                periods: 0,
            })
        }
    }
}
