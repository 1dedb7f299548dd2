//! The FRF of one recorded experiment, the way `sdctl frf` and the Python package estimate it:
//! periodic records (the manifest gives `period`) by the period average of [`frf_periodic`]
//! (closed loop through the reference when there is one), non-periodic ones by the local
//! polynomial method ([`lpm_closed_loop_snr`] with a reference, [`lpm()`] without), with the
//! data-quality warnings of [`crate::quality`]. Lines whose input is at its own noise level are
//! dropped unless `keep_low_snr`; a record whose input is explained by its output alone (pure
//! feedback, no excitation) is refused unless `keep_low_snr`.

use crate::{
    feedback_only, frf_periodic, frf_periodic_mimo, lpm, lpm_closed_loop_snr, snr_warnings,
    trusted, Channels, DataWarning, Experiment, IdentError, LpmOptions, MimoFrfEstimate,
    PeriodicOptions, Result,
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

/// The FRF of `exp` with its data-quality warnings (module documentation).
///
/// # Errors
/// [`IdentError::InvalidArgument`] for an `excited_fraction` outside (0, 1), the estimators'
/// errors, [`IdentError::Data`] for a record without excitation (unless `keep_low_snr`).
pub fn frf_of_experiment(exp: &Experiment, req: &FrfRequest) -> Result<(Frd, Vec<DataWarning>)> {
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
    let (frd, mut warnings) = match exp.spec.period_samples {
        Some(p) => {
            let mut opt = PeriodicOptions::new(p, exp.spec.skip_periods);
            if let Some(f) = req.excited_fraction {
                if !(f.is_finite() && f > 0.0 && f < 1.0) {
                    return Err(IdentError::InvalidArgument(format!(
                        "excited fraction {f} must be in (0, 1)"
                    )));
                }
                opt.excited_fraction = f;
            }
            let est = frf_periodic(fs, exp.r.as_deref(), &exp.u, &exp.y, &opt)?;
            let warnings = est.warnings(!keep);
            let frd = if keep { est.frd } else { est.trusted_frd()? };
            (frd, warnings)
        }
        None => {
            let lo = LpmOptions::default();
            match &exp.r {
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
            }
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
    Ok((frd, warnings))
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
                if !(f.is_finite() && f > 0.0 && f < 1.0) {
                    return Err(IdentError::InvalidArgument(format!(
                        "excited fraction {f} must be in (0, 1)"
                    )));
                }
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
