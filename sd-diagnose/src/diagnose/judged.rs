//! Stage 2: the model judged — given or fitted, its modal form and prediction covariance,
//! and how far it is from its own experiment.

use super::checks::*;
use super::read::*;
use crate::data::{parts, Estimate};
use crate::findings::responses;
use crate::hypotheses::Modal;
use crate::lemma6::model_lines;
use crate::modal::{ModalBasis, Residues};
use crate::stats::{statistic, Line};
use crate::{DiagnoseOptions, ModelInfo, OwnFit, Result};
use sd_model::StateSpace;
use sd_multirate::NonIdeal;

/// Stage 2's model with its modal form (the prediction variance of a fitted model and the
/// base of every extension).
pub(super) struct Judged<'a> {
    pub(super) model: StateSpace,
    pub(super) info: ModelInfo,
    pub(super) given: bool,
    pub(super) modal: Modal<'a>,
    pub(super) plain: Residues,
}

impl Judged<'_> {
    /// Lines of `est` (slower by `factor`) against the model's simulation `sim`.
    pub(super) fn lines(
        &self,
        sim: &StateSpace,
        factor: usize,
        est: &Estimate,
    ) -> Result<Vec<Line>> {
        let f = est.frd.freq_hz();
        let resp = responses(sim, f)?;
        let ts = self.modal.h * factor as f64;
        let var = if self.given {
            None
        } else {
            Some(
                self.plain
                    .variances(&self.modal.basis, ts, NonIdeal::ideal(), f)?,
            )
        };
        Ok(model_lines(
            est,
            &resp,
            var.as_deref(),
            self.plain.n_params(),
        ))
    }
}

/// Mean score of a model on the model experiment's own lines (no prediction variance).
pub(super) fn own_statistic(m: &StateSpace, fast: &Estimate, alpha: f64) -> Result<f64> {
    Ok(crate::model::own_statistic(m, fast, alpha)?.value)
}

/// Where the model comes from: "given" or how it was fitted, and a fit's order choice.
pub(super) struct Origin {
    pub(super) source: String,
    pub(super) choice: Option<crate::OrderChoice>,
}

/// Stage 2: the model (given, or fitted and then its residues refitted on the continuous
/// modal basis of its poles, kept when it fits its data as well: the basis drops poles
/// without a continuous counterpart), its source, and that basis.
pub(super) fn judged_model(
    data: &Data<'_>,
    opt: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<(StateSpace, Origin, ModalBasis)> {
    let parts = if opt.model.is_none() {
        progress("FRFs of the model experiment's earlier and later periods");
        parts(data.model_exp, &data.fast)
    } else {
        None
    };
    let (fitted, mut source, choice) =
        crate::model::model_for(&data.fast, parts.as_ref(), data.h, opt, progress)?;
    let basis = ModalBasis::from_model(&fitted)?;
    if opt.model.is_some() {
        return Ok((fitted, Origin { source, choice }, basis));
    }
    let phi = basis.responses(data.h, NonIdeal::ideal(), data.fast.frd.freq_hz())?;
    let res = Residues::fit(&data.fast.frd, &phi)?;
    let refit = basis.model(&res.r, data.h, NonIdeal::ideal())?;
    let own = |m: &StateSpace| own_statistic(m, &data.fast, opt.alpha);
    if own(&refit)? <= own(&fitted)? * 1.02 {
        source.push_str("; residues refitted on the continuous modal basis");
        return Ok((refit, Origin { source, choice }, basis));
    }
    Ok((fitted, Origin { source, choice }, basis))
}

/// The model with its modal form and prediction covariance: residues and poles, for a fitted
/// model scaled by its misfit on its own data when above 1 (the residual-variance factor of
/// least squares: unmodelled detail widens its prediction).
pub(super) fn judge_model<'a>(
    data: &'a Data<'_>,
    opt: &DiagnoseOptions,
    model: StateSpace,
    origin: Origin,
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
            source: origin.source,
            order: model.n(),
            ts: model.ts(),
            own_data: None,
            own_fit: None,
            fitted: origin.choice,
        },
        given,
        model,
        modal,
        plain,
    })
}

/// How far the model is from its own experiment, and whether that excess is noise,
/// distortion (the non-excited lines), fit error, or not separable (the excitation cannot
/// measure the distortion).
pub(super) fn own_fit(data: &Data<'_>, ch: &Checks, info: &mut ModelInfo) {
    let own = statistic(
        [(ch.fast_model.as_slice(), data.fast.inflation)],
        ch.alpha_test,
    );
    let distorted = data.fast.distortion.as_ref().is_some_and(|d| {
        distortion_evidence(&data.model_exp.spec.name, d, ch.alpha_test)
            .iter()
            .any(|e| !e.passed)
    });
    // above the noise without distortion seen: a fit error only where the variance holds
    // the distortion (detection lines, realisations, a sibling, the LPM residual)
    let unmeasurable = data
        .fast
        .bla
        .as_ref()
        .is_some_and(|b| !b.distortion.measured());
    info.own_fit = Some(if own.passes() {
        OwnFit::Noise
    } else if distorted {
        OwnFit::Distortion
    } else if unmeasurable {
        OwnFit::NotSeparable
    } else {
        OwnFit::FitError
    });
    info.own_data = Some(own);
}
