//! The diagnosis as named stages (crate documentation): data → FRFs → model → consistency
//! checks → hypotheses → validation → findings.

mod checks;
mod decide;
mod held_out;
mod judged;
mod levels;
mod next;
mod rate_tied;
mod read;
mod reports;

use crate::{
    joined, merged_parameters, DiagnoseError, DiagnoseOptions, Diagnosis, Extension, Result,
};
use checks::*;
use decide::*;
use judged::*;
use read::*;
use reports::*;
use sd_ident::Experiment;
use sd_multirate::downsample;

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
    let (experiments, pieces, records) = match &cut {
        Some(c) => {
            for r in &c.records {
                progress(&format!(
                    "`{}`: {:.1} of {:.1} s excited in {} burst(s), used as {} piece(s)",
                    r.record, r.excited_s, r.length_s, r.bursts, r.pieces
                ));
            }
            (
                c.experiments.as_slice(),
                c.pieces.clone(),
                c.records.clone(),
            )
        }
        None => (experiments, Vec::new(), Vec::new()),
    };
    let mut data = Data::read(experiments, progress)?;
    let (model, origin, basis) = judged_model(&data, opt, progress)?;
    for v in &mut data.vals {
        v.model = if v.factor == 1 {
            model.clone()
        } else {
            downsample(&model, v.factor)?
        };
    }
    let mut judged = judge_model(&data, opt, model, origin, basis)?;
    let mut ch = checks(&data, &judged, opt.alpha)?;
    data.widen_levels(&level_tests(&data, &ch));
    own_fit(&data, &ch, &mut judged.info);
    let outcome = decide(&data, &judged, &mut ch, progress)?;
    progress("reports");
    // the residues with the poles' covariance: the reports and the continuous model use the
    // residues, the predictor keeps the covariance
    let tied = match &outcome.extension {
        Extension::RateTied(p) => Some((judged.modal.residues_full(p.nonideal())?, p)),
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
    let cause = joined(&outcome.causes);
    let uncertain = |residues: crate::modal::Residues| crate::ModelUncertainty {
        basis: judged.modal.basis.clone(),
        residues,
    };
    let tied_uncertainty = tied.as_ref().map(|(r, _)| uncertain(r.clone()));
    let predictor = crate::Predictor::of(
        (
            &judged.model,
            (!judged.given).then(|| uncertain(judged.plain.clone())),
        ),
        (&outcome.extension, &cause),
        (extended_model.as_ref(), tied_uncertainty),
        outcome.amplitude.as_deref(),
    );
    Ok(Diagnosis {
        verdict: outcome.verdict,
        cause,
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
        records,
        extended_model,
        predictor,
        next_experiment: outcome.next.clone().and_then(|n| n.ok()),
        no_next_experiment: outcome.next.and_then(|n| n.err()),
    })
}
